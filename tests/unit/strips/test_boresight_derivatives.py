"""The boresight derivative matrices, kept per sensor angles (strips.centroids), are ∂R_bs/∂angle of each sensor asked."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calidar.sensor import Sensor
from calidar.strips.centroids import boresight_derivatives


def central_differences(sensor: Sensor, h: float = 1e-6) -> np.ndarray:
    """(9, 3): ∂vec(R_bs)/∂(roll, pitch, yaw) by central differences."""
    cols = []
    for name in ("boresight_roll", "boresight_pitch", "boresight_yaw"):
        up = replace(sensor, **{name: getattr(sensor, name) + h}).r_bs
        down = replace(sensor, **{name: getattr(sensor, name) - h}).r_bs
        cols.append(((up - down) / (2 * h)).ravel())
    return np.stack(cols, axis=1)


def test_each_sensor_gets_its_own_derivatives_and_they_cannot_be_changed():
    a = replace(Sensor(), boresight_roll=0.01, boresight_pitch=-0.02, boresight_yaw=0.3)
    b = replace(a, boresight_yaw=-1.2)
    for s in (a, b, a, b):  # asked alternately: a kept matrix must never answer for the other sensor
        np.testing.assert_allclose(boresight_derivatives(s), central_differences(s), rtol=0, atol=1e-9)
    assert not np.allclose(boresight_derivatives(a), boresight_derivatives(b))
    with pytest.raises(ValueError):
        boresight_derivatives(a)[0, 0] = 1.0
