"""The taught region the gate enforces: its shape, its edge and the mesh that answers queries.

Built from taught samples (positions of real poses), not from any network's weights. Imports
:mod:`limbctl.geometry` and :mod:`limbctl.errors` only.
"""
