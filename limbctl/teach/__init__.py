"""Teaching: record hand-guided poses (torque off), dataset files, coverage, and training a model.

May import only the layers below it (envelope, region, servo, geometry, errors, calib); never
teleop, view or the app.
"""
