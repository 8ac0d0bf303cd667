"""The teleop tests' shared fixture: a 40 deg cone saved as a model for ``sim``."""

import pytest


@pytest.fixture
def cone_model(cone_file):
    return cone_file(40.0)
