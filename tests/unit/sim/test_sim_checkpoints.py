"""Simulated checkpoints stand where a surveyor would put them (sim/checkpoints.py)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.sim import checkpoints as cp
from calidar.sim.scene import SceneSpec, build_scene


@pytest.fixture(scope="module")
def scene():
    return build_scene(SceneSpec(vegetation_fraction=0.2), 3, np.radians(47.0), np.radians(8.0), 450.0)


def test_placement_open_under_trees_apart_and_smooth(scene):
    xy, veg = cp.place_checkpoints(scene, 40, np.random.default_rng(1))
    assert xy.shape == (40, 2) and veg.sum() == 10  # a quarter under trees
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1)) + np.eye(40) * 1e9
    assert d.min() >= cp.MIN_SEPARATION_M
    ratio, beyond = cp._crown_distance(scene, xy[:, 0], xy[:, 1])
    assert (ratio[veg] <= cp.UNDER_CROWN).all() and (beyond[~veg] >= cp.CROWN_CLEARANCE_M).all()
    assert cp._smooth(scene, xy[:, 0], xy[:, 1]).all() and cp._clear_of_buildings(scene, xy[:, 0], xy[:, 1]).all()
    x0, x1, y0, y1 = scene.extent
    assert (xy[:, 0] > x0 + cp.MARGIN * (x1 - x0)).all() and (xy[:, 1] < y1 - cp.MARGIN * (y1 - y0)).all()


def test_no_room_and_bad_options_are_named(scene):
    with pytest.raises(InputError, match="--checkpoints: room for"):
        cp.place_checkpoints(scene, 900, np.random.default_rng(1))
    with pytest.raises(InputError, match="--checkpoint-sigma"):
        cp.check_checkpoint_options(10, -0.01)
    with pytest.raises(InputError, match="--checkpoints"):
        cp.check_checkpoint_options(-1, 0.01)
