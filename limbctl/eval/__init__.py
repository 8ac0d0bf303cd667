"""The papers' experiments: task grids, metrics and figures, run by ``limbctl eval``.

Used only by the app.
"""
