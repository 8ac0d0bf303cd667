"""The envelope base class: a model must say how it answers when its class is defined."""

import numpy as np
import pytest

from limbctl.envelope.base import Envelope
from limbctl.envelope.cone import Cone


def test_a_model_answering_through_neither_form_is_refused_and_the_hooks_answer():
    with pytest.raises(TypeError, match="_inside and _to_boundary, or contains and correct"):

        class Silent(Envelope):
            kind = "silent-test"

    assert "silent-test" not in Envelope._registry
    # a model answering through the hooks gets contains and correct
    cone = Cone(np.radians(30.0))
    inside, outside = np.array([1.0, 0, 0, 0]), np.array([0.0, 0, 0, 1.0])
    assert cone.contains(inside) is True and cone.contains(outside) is False
    np.testing.assert_array_equal(cone.correct(inside), inside)
    assert cone.contains(cone.correct(outside)[None])[0]
