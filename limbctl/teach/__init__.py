"""Teaching: record hand-guided poses (torque off), dataset files, coverage, and training a model.

Imports the layers below (envelope, region, servo, geometry); never teleop or the app.
"""
