"""The calibration's covariance from a calidar ``solution.json`` (``calidar boresight``): the
estimated sensor parameters, their σ and correlations, in SI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.validate import read_text

#: solution.json display unit → (SI unit of calidar.adjust.Parameter, factor display → SI)
_UNITS = {"deg": ("rad", np.pi / 180.0), "m": ("m", 1.0), "ppm": ("ppm", 1e-6), "1": ("1", 1.0)}


def read_calibration_covariance(path: str | Path,
                                names) -> tuple[tuple[str, ...], np.ndarray, tuple[str, ...]]:
    """(parameter names, covariance (k, k) SI, SI units) of the free parameters among ``names``
    (the sensor's) in a solution.json; a clear error naming the file and field otherwise."""
    path = Path(path)
    try:
        doc = json.loads(read_text(path, "solution.json"))
    except json.JSONDecodeError as e:
        raise InputError(path, None, f"not valid JSON ({e.msg} at line {e.lineno}); expected a "
                         "calidar solution.json")
    params = doc.get("parameters") if isinstance(doc, dict) else None
    corr = doc.get("correlation", {})
    has_matrix = isinstance(corr, dict) and "names" in corr and "matrix" in corr
    if not isinstance(params, dict) or not has_matrix:
        raise InputError(path, "parameters",
                         "expected a calidar solution.json (parameters and correlation)")

    def estimated(n: str) -> bool:
        return isinstance(params.get(n), dict) and params[n].get("free")

    chosen = [n for n in corr["names"] if n in names and estimated(n)]
    if not chosen:
        raise InputError(path, "parameters", "no estimated sensor parameter found; expected some "
                         f"of {sorted(names)}")
    index = [corr["names"].index(n) for n in chosen]
    try:
        rho = np.array(corr["matrix"], float)[np.ix_(index, index)]
        sigma, units = [], []
        for n in chosen:
            unit, factor = _UNITS[params[n]["unit"]]
            sigma.append(float(params[n]["sigma"]) * factor)
            units.append(unit)
    except (KeyError, TypeError, ValueError, IndexError):
        raise InputError(path, "parameters", "expected each estimated parameter's sigma and unit, "
                         "and a square correlation matrix") from None
    sigma = np.array(sigma)
    if not (np.all(np.isfinite(sigma)) and np.all(sigma >= 0) and np.all(np.isfinite(rho))):
        raise InputError(path, "parameters", "expected finite σ ≥ 0 and finite correlations")
    return tuple(chosen), rho * np.outer(sigma, sigma), tuple(units)
