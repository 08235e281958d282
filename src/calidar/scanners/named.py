"""``parameters()`` / ``with_parameters()`` shared by the scanner models (frozen dataclasses whose
class attribute ``units`` names their calibratable parameters, SI)."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar


class NamedParameters:
    """Mixin: the parameters listed in ``units`` read and replaced by name."""

    units: ClassVar[dict[str, str]]

    def parameters(self) -> dict[str, float]:
        """Named parameters in SI units (rad, m, ratio)."""
        return {k: float(getattr(self, k)) for k in self.units}

    def with_parameters(self, **values: float):
        """A copy with some parameters replaced (SI); unknown names are a KeyError."""
        unknown = set(values) - set(self.units)
        if unknown:
            raise KeyError(f"{self.model} scanner has no parameter(s) {sorted(unknown)}")
        return replace(self, **{k: float(v) for k, v in values.items()})
