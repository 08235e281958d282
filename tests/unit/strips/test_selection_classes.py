"""The selections' class test by a 256-entry table equals np.isin, for LAS's uint8 classes and others."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.strips.selection import EXCLUDED_CLASSES, in_classes


@pytest.mark.parametrize("dtype", [np.uint8, np.int64, np.uint16])
@pytest.mark.parametrize("classes", [(2,), (2, 6), EXCLUDED_CLASSES, (0, 255), (300,)])
def test_equals_isin(dtype, classes):
    rng = np.random.default_rng(3)
    c = rng.integers(0, 256 if dtype == np.uint8 else 400, 10_000).astype(dtype)
    record = np.zeros(c.size, [("x", "i4"), ("classification", dtype)])  # strided, as laspy's fields
    record["classification"] = c
    for view in (c, record["classification"]):
        got = in_classes(view, classes)
        assert got.dtype == bool and np.array_equal(got, np.isin(view, classes))
