"""Ground control for ``calidar boresight --control FILE`` (issue 28): the control file read and
checked, placed in the strips' frame.

The file is a checkpoint CSV (:mod:`calidar.io.checkpoints`: id, x, y, z, σ; the land-cover
column optional) in the strips' CRS unless ``--control-crs`` names another. Each point needs its
survey σ (the adjustment weighs it by it). Points marked vegetated are left out (under trees a
strip's surface is not the ground), with a note. The points go to the ingest as ECEF (so that
each flight line keeps its points around them) and to the calibration in the strips'
:class:`~calidar.strips.strip.LocalFrame` (:mod:`calidar.strips.control`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError


@dataclass(frozen=True, eq=False)
class ControlInput:
    """The control as read: the file's points (open ground only), ECEF (N, 3) m, notes."""

    checkpoints: object  #: calidar.io.checkpoints.Checkpoints, the points used
    ecef: np.ndarray
    notes: tuple[str, ...] = ()


def read_control(path, control_crs: str | None, strip_path, points, sensor) -> ControlInput:
    """Read the control file ``path``; its CRS: ``control_crs`` or the strips' (the first strip
    file's, ``points.crs`` or ``sensor.crs``)."""
    import pyproj

    from calidar.crs import from_crs
    from calidar.io.checkpoints import read_checkpoints
    from calidar.io.las import las_file_crs

    cp = read_checkpoints(path, cover=False)
    if cp.sigma_m is None:
        raise InputError(path, "sigma", "no sigma column; expected each control point's survey σ (m) in a column "
                         "named sigma: the adjustment weighs the control by it")
    notes = []
    if cp.vegetated.any():
        left = ", ".join(cp.ids[cp.vegetated][:5]) + (" …" if cp.vegetated.sum() > 5 else "")
        notes.append(f"{int(cp.vegetated.sum())} control points marked vegetated left out of the adjustment ({left}): "
                     "under trees a strip's surface is not the ground")
        keep = ~cp.vegetated
        if not keep.any():
            raise InputError(path, "class", "every control point is marked vegetated; expected control on open ground")
        cp = type(cp)(cp.path, cp.ids[keep], cp.xyz[keep], cp.vegetated[keep], cp.sigma_m[keep], cp.lines[keep])
    crs = las_file_crs(Path(strip_path), points.crs) or las_file_crs(Path(strip_path), sensor.crs)
    undulation = points.geoid_undulation_m
    if control_crs is not None:
        try:
            theirs = pyproj.CRS.from_user_input(control_crs)
        except pyproj.exceptions.CRSError as e:
            raise InputError(None, "--control-crs", f"expected a CRS (e.g. EPSG:32632), got {control_crs!r} ({e})")
        if crs is None or not theirs.equals(crs):
            crs, undulation = theirs, None
    if crs is None:
        raise InputError(path, "crs", "the strips have no CRS; expected --crs for them or --control-crs")
    return ControlInput(cp, from_crs(cp.xyz, crs, undulation, cp.path), tuple(notes))


def control_points(control: ControlInput, frame):
    """The control in the strips' local frame: a :class:`calidar.strips.control.ControlPoints`
    (two points at one place: an error naming them)."""
    from calidar.io.checkpoints import check_places
    from calidar.strips.control import ControlPoints

    cp = control.checkpoints
    local = frame.to_local(control.ecef)
    check_places(cp, local[:, :2])
    return ControlPoints(cp.ids, local, np.asarray(cp.sigma_m, float))
