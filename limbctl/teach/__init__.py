"""Teaching: record hand-guided poses (torque off), dataset files, coverage, and training a model.
Imports only the layers below it (envelope, region, servo, geometry, errors, calib)."""
