"""Scanner models: encoder/scan angles → unit beam directions in the scanner frame s.

Every model implements :class:`Scanner`. ``SCANNERS`` maps the ``model`` name used in
``sensor.toml`` to the class. Parameters are flat, uniquely named floats in SI units
(rad, m, ratios) so that the adjustment engine can estimate any of them.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from calidar.scanners.linear import LinearScanner
from calidar.scanners.palmer import PalmerScanner
from calidar.scanners.wedge import WedgeScanner


@runtime_checkable
class Scanner(Protocol):
    """A scanner model (frozen dataclass)."""

    model: str  #: name in sensor.toml

    def directions(self, angles: np.ndarray) -> np.ndarray:
        """Scanner observations (N,) or (N, k) in rad → unit beam vectors (N, 3) in frame s."""

    def angles(self, directions: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`directions`: unit vectors (N, 3) → observations (N, k), rad
        (rotating scanners — Palmer, wedge — return their encoder angle β as (N,)).

        ``directions(angles(u)) == u`` must hold for every u this model can produce.
        """

    def parameters(self) -> dict[str, float]:
        """Named parameters in SI units (rad, m, ratio)."""

    def with_parameters(self, **values: float) -> "Scanner":
        """A copy with some parameters replaced (unknown names raise KeyError)."""

    def to_toml(self) -> dict:
        """The ``[scanner]`` table for sensor.toml (user units, key names say them)."""


SCANNERS: dict[str, type] = {
    "linear": LinearScanner,
    "palmer": PalmerScanner,
    "wedge": WedgeScanner,
}


def scanner_from_toml(table: dict, source: str = "sensor.toml") -> Scanner:
    """Build a scanner from a ``[scanner]`` table; unknown models are a clear error."""
    from calidar.errors import InputError

    model = table.get("model", "linear")
    if model not in SCANNERS:
        raise InputError(source, "scanner.model",
                         f"expected one of {sorted(SCANNERS)}, got {model!r}")
    return SCANNERS[model].from_toml(table, source)
