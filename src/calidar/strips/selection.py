"""Which points the swath-overlap difference uses.

The USGS interswath measure is defined on non-vegetated surfaces with single returns. So, per
source (a file, or a flight line held in memory):

- ``classes``: the LAS classes asked for (``--classes 2,6``); each must be present;
- ``ground``: class 2 when the source has ground points;
- ``last returns``: otherwise, last-of-many and single returns (return_number ==
  number_of_returns), without vegetation, noise or water classes; the smoothness test of the
  cells then keeps the non-vegetated surfaces.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from calidar.errors import InputError

GROUND = 2  #: LAS class of ground points
#: LAS classes never used by the last-returns rule nor the calibration's points, by what they hold
#: (ASPRS LAS 1.4 R15 table 17: low/medium/high vegetation, low point (noise), high noise, water)
EXCLUDED_GROUPS = (("vegetation", (3, 4, 5)), ("noise", (7, 18)), ("water", (9,)))
EXCLUDED_CLASSES = tuple(sorted(c for _, classes in EXCLUDED_GROUPS for c in classes))


def _classes_text(classes: tuple[int, ...]) -> str:
    """(3, 4, 5) → '3–5' (a run of consecutive classes), (7, 18) → '7, 18'."""
    run = len(classes) > 2 and classes == tuple(range(classes[0], classes[-1] + 1))
    return f"{classes[0]}–{classes[-1]}" if run else ", ".join(map(str, classes))


def excluded_words(numbers: bool = True) -> str:
    """The excluded classes in words, from :data:`EXCLUDED_GROUPS`: 'vegetation (3–5), noise
    (7, 18) and water (9)' (``numbers`` False: 'vegetation, noise and water')."""
    words = [f"{name} ({_classes_text(c)})" if numbers else name for name, c in EXCLUDED_GROUPS]
    return ", ".join(words[:-1]) + " and " + words[-1]
#: the attributes of a point chunk a selection reads
FIELDS = ("classification", "return_number", "number_of_returns")


def excluded(classification: np.ndarray) -> np.ndarray:
    """Mask of the points of :data:`EXCLUDED_CLASSES` (vegetation, noise, water): what neither
    the overlap-quality rule nor the strip calibration's points use (issue 26)."""
    return among(classification, EXCLUDED_CLASSES)


def among(classification: np.ndarray, classes: tuple[int, ...]) -> np.ndarray:
    """``np.isin(classification, classes)``: for 8-bit classes (LAS) a lookup in a table of the
    256 (one pass, no comparison per class), the same mask."""
    c = np.asarray(classification)
    if c.dtype == np.uint8 and c.ndim == 1:
        return _looked_up(c, _table(tuple(classes)))
    return np.isin(c, classes)


@njit(cache=True, nogil=True)
def _looked_up(c, table):  # pragma: no cover - numba
    out = np.empty(c.size, np.bool_)
    for k in range(c.size):
        out[k] = table[c[k]]
    return out


@lru_cache(maxsize=64)
def _table(classes: tuple[int, ...]) -> np.ndarray:
    """Whether each of the 256 8-bit classes is among ``classes``."""
    return np.isin(np.arange(256), classes)


@dataclass(frozen=True)
class PointSelection:
    """A rule ("classes", "ground" or "last returns") and the classes it keeps (None: any but
    EXCLUDED_CLASSES)."""

    rule: str
    classes: tuple[int, ...] | None = None

    def mask(self, points) -> np.ndarray:
        """Mask of the points (anything with the attributes of FIELDS, None when absent) kept."""
        n = len(points.classification if points.classification is not None else points.xyz)
        keep = np.ones(n, bool)
        if self.classes is not None:
            return among(points.classification, self.classes)
        if points.classification is not None:
            keep &= ~excluded(points.classification)
        if points.return_number is not None and points.number_of_returns is not None:
            keep &= points.return_number == points.number_of_returns
        return keep

    def describe(self) -> str:
        if self.classes is None:
            return ("last and single returns (return_number = number_of_returns), no "
                    f"{'/'.join(name for name, _ in EXCLUDED_GROUPS)} classes")
        plural = "es" if len(self.classes) > 1 else ""
        return f"{self.rule}: class{plural} {', '.join(map(str, self.classes))}"

    def to_dict(self) -> dict:
        return {"rule": self.rule, "classes": None if self.classes is None else list(self.classes),
                "description": self.describe()}


def candidate_mask(points) -> np.ndarray:
    """Mask of the points that the default rules could keep (ground, or last returns): what a caller
    must hold before it knows the classes a source has (:func:`choose_selection`)."""
    ground = PointSelection("ground", (GROUND,)).mask(points)
    return ground | PointSelection("last returns").mask(points)


def choose_selection(source, present: np.ndarray | None,
                     classes: tuple[int, ...] | None = None) -> PointSelection:
    """The selection for one source from the classes ``present`` in it (None: no classification):
    the ``classes`` asked for (each must be present, else an error naming ``source``), else ground
    when present, else last returns."""
    found = set() if present is None else {int(c) for c in present}
    if classes is not None:
        missing = [c for c in classes if c not in found]
        if missing:
            raise InputError(source, "classification",
                             f"has no points of class {', '.join(map(str, missing))} "
                             f"(classes present: {', '.join(map(str, sorted(found))) or 'none'}); "
                             "expected every class given to --classes")
        return PointSelection("classes", classes)
    if GROUND in found:
        return PointSelection("ground", (GROUND,))
    return PointSelection("last returns")
