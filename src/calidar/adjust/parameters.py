"""Named calibration parameters with units, priors and free/fixed flags."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

#: How each SI unit is shown to users: (display unit, factor SI → display).
DISPLAY_UNITS = {"rad": ("deg", 180.0 / math.pi), "m": ("m", 1.0), "1": ("1", 1.0),
                 "ppm": ("ppm", 1e6)}
#: Default central-difference steps per SI unit for numerical Jacobians.
DEFAULT_STEPS = {"rad": 1e-6, "m": 1e-4, "1": 1e-7, "ppm": 1e-7}


@dataclass(frozen=True)
class Parameter:
    """One parameter. ``value`` and ``prior_sigma`` are SI; ``unit`` is "rad", "m", "1"
    (plain ratio) or "ppm" (a ratio shown in parts per million)."""

    name: str
    value: float
    unit: str
    prior_sigma: float | None = None  #: a-priori σ (SI) about ``prior_value``; None = no prior
    free: bool = True
    prior_value: float | None = None  #: defaults to the initial value
    step: float | None = None  #: central-difference step (SI); default by unit

    def __post_init__(self):
        if self.unit not in DISPLAY_UNITS:
            raise ValueError(f"parameter {self.name}: unit must be one of "
                             f"{sorted(DISPLAY_UNITS)}, got {self.unit!r}")
        if self.prior_sigma is not None and not self.prior_sigma > 0:
            raise ValueError(f"parameter {self.name}: prior_sigma must be > 0, "
                             f"got {self.prior_sigma}")

    @property
    def display_unit(self) -> str:
        return DISPLAY_UNITS[self.unit][0]

    def to_display(self, value_si: float) -> float:
        """SI value → the user's unit (deg for angles, ppm for ppm ratios)."""
        return float(value_si) * DISPLAY_UNITS[self.unit][1]

    @property
    def diff_step(self) -> float:
        return self.step if self.step is not None else DEFAULT_STEPS[self.unit]

    @property
    def prior_center(self) -> float:
        return self.value if self.prior_value is None else self.prior_value


class ParameterSet:
    """An ordered set of parameters; the free ones form the solver's vector x."""

    def __init__(self, parameters: Iterable[Parameter]):
        self._params = list(parameters)
        names = [p.name for p in self._params]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in {names}")
        self._layout = None

    def __iter__(self):
        return iter(self._params)

    def __len__(self) -> int:
        return len(self._params)

    def __getitem__(self, name: str) -> Parameter:
        for p in self._params:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self._params]

    @property
    def free(self) -> list[Parameter]:
        return [p for p in self._params if p.free]

    @property
    def free_names(self) -> list[str]:
        return [p.name for p in self.free]

    def layout(self) -> tuple[tuple[str, ...], dict[str, int], np.ndarray, np.ndarray]:
        """(names, name → position, positions of the free parameters, all values SI), built once:
        the vector layout :class:`calidar.adjust.residuals.Values` reads (never to be changed)."""
        if self._layout is None:
            names = tuple(p.name for p in self._params)
            free = [i for i, p in enumerate(self._params) if p.free]
            self._layout = (names, {n: i for i, n in enumerate(names)},
                            np.array(free, dtype=np.intp),
                            np.array([p.value for p in self._params], dtype=float))
        return self._layout

    def values(self) -> dict[str, float]:
        """All values (SI) by name."""
        return {p.name: p.value for p in self._params}

    def x(self) -> np.ndarray:
        """The free values (SI) as a vector."""
        return np.array([p.value for p in self.free], dtype=float)

    def values_with(self, x: np.ndarray) -> dict[str, float]:
        """All values with the free ones taken from x."""
        out = self.values()
        out.update(zip(self.free_names, map(float, x)))
        return out

    def updated(self, x: np.ndarray) -> "ParameterSet":
        """A copy with the free values replaced by x (priors stay centred where they were)."""
        it = iter(map(float, x))
        return ParameterSet(replace(p, value=next(it), prior_value=p.prior_center) if p.free else p
                            for p in self._params)
