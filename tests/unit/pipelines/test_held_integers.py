"""The held points' integers (:func:`calidar.ingest.held.stored_integers`): the numpy round trip
they replace, bit for bit, and the same refusals."""

import numpy as np

from calidar.ingest.held import stored_integers


def _numpy(xyz, scales, offsets):
    # the round trip HeldFiles.add made in numpy before (issue 32, seventh session)
    raw = np.round((xyz - offsets) / scales)
    if not np.all(np.abs(raw) < 2**31):
        return None
    stored = raw.astype(np.int32)
    back = np.empty_like(xyz)
    for k in range(3):
        back[:, k] = stored[:, k] * scales[k] + offsets[k]
    return stored if np.array_equal(back, xyz) else None


def _scaled(stored, scales, offsets):
    xyz = np.empty(stored.shape)
    for k in range(3):  # as laspy scales them
        xyz[:, k] = stored[:, k] * scales[k] + offsets[k]
    return xyz


def test_laspy_scaled_coordinates_give_their_integers():
    rng = np.random.default_rng(1)
    for scales, offsets in (([0.01, 0.01, 0.001], [500000.0, 5000000.0, 0.0]),
                            ([0.001, 0.001, 0.0001], [-3.0, 17.25, -100.0]),
                            ([1e-7, 1e-7, 0.001], [7.5, 45.0, 0.0])):  # degrees
        scales, offsets = np.array(scales), np.array(offsets)
        stored = rng.integers(-2**31 + 1, 2**31 - 1, (20000, 3)).astype(np.int32)
        stored[:10] = [[-2**31 + 1, 2**31 - 1, 0]] * 10  # the ends of the range
        xyz = _scaled(stored, scales, offsets)
        got, want = stored_integers(xyz, scales, offsets), _numpy(xyz, scales, offsets)
        assert want is not None and got is not None
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(got, stored)
        assert got.dtype == np.int32


def test_the_same_refusals():
    scales, offsets = np.array([0.01, 0.01, 0.01]), np.array([0.0, 0.0, 0.0])
    good = _scaled(np.arange(30, dtype=np.int32).reshape(10, 3), scales, offsets)
    cases = {"between two integers": (0, 1, 0.004), "NaN": (3, 2, np.nan),
             "infinite": (5, 0, np.inf), "beyond 2³¹": (9, 1, 2.2e7),
             "at −2³¹": (2, 0, -2**31 * 0.01)}
    for name, (i, k, v) in cases.items():
        xyz = good.copy()
        xyz[i, k] = v
        assert _numpy(xyz, scales, offsets) is None, name
        assert stored_integers(xyz, scales, offsets) is None, name
    np.testing.assert_array_equal(stored_integers(good, scales, offsets),
                                  np.arange(30).reshape(10, 3))
    empty = stored_integers(np.zeros((0, 3)), scales, offsets)
    assert empty.shape == (0, 3) and empty.dtype == np.int32
    half = np.array([[0.025, 0.035, -0.025]])  # (x − o) / s at .5 (in binary near it): as numpy
    np.testing.assert_array_equal(stored_integers(half, scales, offsets) is None,
                                  _numpy(half, scales, offsets) is None)


def test_scaled_integers_equal_the_axis_by_axis_numpy_scaling():
    from calidar.ingest.held import scaled_integers

    rng = np.random.default_rng(4)
    for scales, offsets in (([0.01, 0.01, 0.001], [500000.0, 5000000.0, 0.0]),
                            ([1e-7, 1e-7, 0.001], [7.5, 45.0, -17.3]),
                            ([0.0025, 3.0, 1e-9], [-1e6, 0.1, 1e9])):
        scales, offsets = np.array(scales), np.array(offsets)
        stored = rng.integers(-2**31, 2**31 - 1, (20000, 3), dtype=np.int64).astype(np.int32)
        stored[:3] = [[-2**31, 2**31 - 1, 0]] * 3  # the ends of the range
        x, y, z = (np.ascontiguousarray(stored[:, k]) for k in range(3))
        got = scaled_integers(x, y, z, scales, offsets)
        assert got.shape == (20000, 3) and got.dtype == np.float64
        assert got.tobytes() == _scaled(stored, scales, offsets).tobytes()  # every bit
    empty = np.zeros(0, np.int32)
    assert scaled_integers(empty, empty, empty, scales, offsets).shape == (0, 3)
    floats = [np.array([1.0, 2.0])] * 3  # not integers: the numpy way, the same values
    np.testing.assert_array_equal(scaled_integers(*floats, scales, offsets),
                                  _scaled(np.stack(floats, axis=1), scales, offsets))



def test_spill_folder_removed_beside_what_follows_or_at_once_on_failure(monkeypatch):
    """calidar quality's folder of held points and spilled moments: a registered temporary while
    the block runs (an interruption removes it); when the block ends, removed by a thread
    (finish_removals waits for it); when it fails, removed before the error goes on."""
    import threading

    import pytest

    from calidar import outputs
    from calidar.ingest.held import HeldPoints, spill_folder

    outputs.finish_removals()  # an earlier test's (a library call leaves them to run)
    go, real = threading.Event(), outputs._remove
    monkeypatch.setattr(outputs, "_remove", lambda tmp: go.wait(30) and real(tmp))
    with spill_folder("calidar-test-") as folder:
        HeldPoints(folder).add("a", x=np.arange(5))
        assert str(folder) in outputs._TEMPORARIES
    assert folder.exists() and [t.name for t in outputs._REMOVALS] == ["calidar-remove"]
    go.set()
    outputs.finish_removals()
    assert not folder.exists() and str(folder) not in outputs._TEMPORARIES
    with pytest.raises(KeyError), spill_folder("calidar-test-") as failed:
        raise KeyError("x")
    assert not failed.exists() and str(failed) not in outputs._TEMPORARIES
    assert outputs._REMOVALS == []
