"""Ground control for ``calidar boresight --control FILE`` (issue 28): the control file read and
checked, placed in the strips' frame; and the same for ``--checkpoints FILE``, points tested after
the calibration (not in it; their σ optional, :mod:`calidar.strips.checkpoint_verdict`).

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
from typing import Protocol

import numpy as np

from calidar.errors import InputError


class SurveyFile(Protocol):
    """What a ground-control file read gives the pipeline whatever its kind (a checkpoint CSV's
    :class:`calidar.io.checkpoints.Checkpoints`,
    :class:`calidar.io.control_planes.ControlPlaneFile`, a
    :class:`calidar.io.control_cloud.ReferenceCloud`, …): its path and surveyed points."""

    path: Path
    xyz: np.ndarray  #: (N, 3) in the CRS they were surveyed in


@dataclass(frozen=True, eq=False)
class ControlInput:
    """The control as read: the file's points (open ground only), ECEF (N, 3) m, notes; for
    another kind (control planes, a reference cloud: ``kind``) the file read, the places over its
    targets whose points the ingest keeps (``ecef``) and the surveyed points (``survey_ecef``)."""

    checkpoints: SurveyFile  #: the file read (the kind's own type: its from_file takes it)
    ecef: np.ndarray
    notes: tuple[str, ...] = ()
    #: a name of calidar.strips.config.CONTROL_KINDS (None: control points, the first)
    kind: str | None = None
    survey_ecef: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Ground:
    """The run's ground points as read (each None when not given): ``control`` (in the adjustment)
    and ``checkpoints`` (tested after it)."""

    control: ControlInput | None = None
    checkpoints: ControlInput | None = None

    @property
    def near(self) -> np.ndarray | None:
        """Every ground point, ECEF (N, 3) m: each flight line keeps its cells around them (None:
        none)."""
        parts = [g.ecef for g in (self.control, self.checkpoints) if g is not None]
        return np.vstack(parts) if parts else None


def read_ground(control, checkpoints, config, strip_paths, sensor) -> Ground:
    """``calidar boresight --control FILE`` and ``--checkpoints FILE`` read (either may be None) in
    the CRS ``config`` (the run's :class:`calidar.pipelines.strip_config.StripConfig`) names for
    each, else the strips' (the first strip file's, ``config.points.crs`` or ``sensor.crs``);
    their options given without the file are an error."""
    given = {"--control-crs": (control, config.control_crs),
             "--checkpoints-crs": (checkpoints, config.checkpoints_crs),
             "--class": (checkpoints, config.checkpoint_class_cm),
             "--control-sigma": (control, config.control_sigma_m)}
    for option, (path, value) in given.items():
        if path is None and value is not None:
            flag = "--control" if option.startswith("--control") else "--checkpoints"
            raise InputError(None, option, f"given without {flag}; expected {flag} FILE with it")
    if control is None and checkpoints is None:
        return Ground()
    if not strip_paths:
        raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
    strips_crs = _strips_crs(Path(strip_paths[0]), config.points, sensor)
    control_input = checkpoint_input = None
    if control is not None:
        control_input = read_control(control, config.control_crs, strips_crs,
                                     sigma_m=config.control_sigma_m)
    if checkpoints is not None:
        checkpoint_input = read_control(checkpoints, config.checkpoints_crs, strips_crs,
                                        checkpoints=True, crs_option="--checkpoints-crs")
    return Ground(control_input, checkpoint_input)


def _strips_crs(strip_path: Path, points, sensor) -> tuple:
    """The strips' CRS (the first file's, ``points.crs`` or ``sensor.crs``; None: none) and geoid
    undulation."""
    from calidar.io.las import las_file_crs

    crs = las_file_crs(strip_path, points.crs) or las_file_crs(strip_path, sensor.crs)
    return crs, points.geoid_undulation_m


def control_kind_of(path) -> type:
    """The kind of ground control (:data:`calidar.strips.config.CONTROL_KINDS`) a ``--control``
    file is: the last registered whose ``accepts(path)`` holds (a reference cloud: LAS/LAZ; control
    planes: a CSV naming a plane column), else the one that accepts any file (control points)."""
    from calidar.strips.config import CONTROL_KINDS

    kinds = list(CONTROL_KINDS.values())[::-1]
    return next((k for k in kinds if k.accepts is not None and k.accepts(path)),
                next(k for k in kinds if k.accepts is None))


def read_control(path, control_crs: str | None, strips_crs: tuple, checkpoints: bool = False,
                 crs_option: str = "--control-crs", sigma_m: float | None = None) -> ControlInput:
    """Read the control file ``path``; its CRS: ``control_crs`` or the strips' (``strips_crs``:
    their CRS and geoid undulation). ``checkpoints``: a checkpoint file (``--checkpoints``, tested
    after the calibration, not in it): its σ optional. ``sigma_m``: a reference cloud's stated σ
    (``--control-sigma``; only with a kind that takes it)."""
    kind = None if checkpoints else control_kind_of(path)
    if sigma_m is not None and not (kind is not None and kind.takes_sigma):
        raise InputError(path, "--control-sigma", "given with a control CSV (its σ are in its "
                         "sigma column); expected it only with a reference cloud (LAS/LAZ) as "
                         "--control")
    if kind is not None and kind.reader is not None:
        return _read_targets(kind, path, control_crs, crs_option, strips_crs, sigma_m)
    return _read_points(path, control_crs, strips_crs, checkpoints, crs_option)


def _read_points(path, control_crs: str | None, strips_crs: tuple, checkpoints: bool,
                 crs_option: str) -> ControlInput:
    """Control points or checkpoints: a checkpoint CSV (:mod:`calidar.io.checkpoints`), the
    vegetated ones left out with a note; control points need their σ."""
    from calidar.io.checkpoints import read_checkpoints

    cp = read_checkpoints(path, cover=False)
    if cp.sigma_m is None and not checkpoints:
        raise InputError(path, "sigma", "no sigma column; expected each control point's survey σ "
                         "(m) in a column named sigma: the adjustment weighs the control by it")
    notes = []
    if cp.vegetated.any():
        cp, note = _open_ground(cp, path, checkpoints)
        notes.append(note)
    crs, undulation = _crs(path, control_crs, crs_option, strips_crs)
    return ControlInput(cp, from_crs_of(cp, crs, undulation), tuple(notes))


def _open_ground(cp, path, checkpoints: bool):
    """The points of a checkpoint CSV ``cp`` on open ground (an error when none is) and the note
    naming those marked vegetated, left out."""
    role = "checkpoints" if checkpoints else "control points"
    left = ", ".join(cp.ids[cp.vegetated][:5]) + (" …" if cp.vegetated.sum() > 5 else "")
    where = "of the check against the ground" if checkpoints else "of the adjustment"
    tested = " (calidar accuracy tests them: VVA)" if checkpoints else ""
    note = (f"{int(cp.vegetated.sum())} {role} marked vegetated left out {where} ({left}): under "
            "trees a strip's surface is not the ground" + tested)
    keep = ~cp.vegetated
    if not keep.any():
        raise InputError(path, "class",
                         f"every {role[:-1]} is marked vegetated; expected {role} on open ground")
    sigma = None if cp.sigma_m is None else cp.sigma_m[keep]
    kept = type(cp)(cp.path, cp.ids[keep], cp.xyz[keep], cp.vegetated[keep], sigma, cp.lines[keep])
    return kept, note


def _read_targets(kind: type, path, control_crs, crs_option, strips_crs: tuple,
                  sigma_m) -> ControlInput:
    """A kind's file read by its io reader (CRS: the option's, else the file's own when it names
    one, else the strips'), its targets made in a local metric frame at it (checked there), and the
    places over them whose points the ingest keeps."""
    from calidar.strips.strip import LocalFrame

    f = kind.reader(path, sigma_m) if kind.takes_sigma else kind.reader(path)
    own = getattr(f, "crs", None)
    given = control_crs if control_crs is not None else own
    crs, undulation = _crs(path, given, crs_option, strips_crs)
    survey = from_crs_of(f, crs, undulation)
    frame = LocalFrame.at(survey)
    targets = kind.from_file(f, frame.to_local(survey))
    keep = targets.keep_xy()
    height = float(np.mean(targets.local[:, 2]))
    places = frame.to_ecef(np.c_[keep, np.full(len(keep), height)])
    return ControlInput(f, places, kind.notes(f, targets), kind.kind, survey)


def _crs(path, given: str | None, option: str, strips_crs: tuple):
    """The file's CRS and geoid undulation: ``given`` (a CRS, the option ``option``) or the
    strips'."""
    import pyproj

    crs, undulation = strips_crs
    if given is not None:
        try:
            theirs = pyproj.CRS.from_user_input(given)
        except pyproj.exceptions.CRSError as e:
            raise InputError(None, option, f"expected a CRS (e.g. EPSG:32632), got {given!r} ({e})")
        if crs is None or not theirs.equals(crs):
            crs, undulation = theirs, None
    if crs is None:
        raise InputError(path, "crs",
                         f"the strips have no CRS; expected --crs for them or {option}")
    return crs, undulation


def from_crs_of(cp, crs, undulation) -> np.ndarray:
    from calidar.crs import from_crs

    return from_crs(cp.xyz, crs, undulation, cp.path)


def control_points(control: ControlInput, frame):
    """The control in the strips' local frame: a :class:`calidar.strips.control.ControlPoints`
    (two points at one place: an error naming them)."""
    from calidar.io.checkpoints import check_places
    from calidar.strips.config import control_kind

    kind = control_kind(control.kind)
    if kind.reader is not None:
        return kind.from_file(control.checkpoints, frame.to_local(control.survey_ecef))
    cp = control.checkpoints
    local = frame.to_local(control.ecef)
    check_places(cp, local[:, :2])
    sigma = np.zeros(len(cp.ids)) if cp.sigma_m is None else np.asarray(cp.sigma_m, float)
    return kind(cp.ids, local, sigma)


def checked_checkpoints(checkpoints: ControlInput | None, frame, notes: list[str]):
    """The checkpoints of :func:`read_ground` in the strips' local frame (None: none) and the run's
    notes with theirs."""
    if checkpoints is None:
        return None, notes
    return control_points(checkpoints, frame), [*notes, *checkpoints.notes]
