"""The configuration of a strip calibration run (``calidar boresight``), as one typed value, and
its TOML file: the file a user keeps and gives again with ``--config`` to repeat a run; the run
writes it beside its results (``config.toml``).

:class:`StripConfig` holds the calibration's own configuration
(:class:`calidar.strips.config.CalibrationConfig`: what to estimate, the matchers, the
trajectory model, the adjustment) and how the files are read (:class:`IngestSettings`, the
point and text-trajectory options, the control points' CRS). The file, in the units a user
reads (degrees for the trajectory's attitude σ)::

    method = ["planes"]
    estimate = ["boresight", "lever_arm_z"]
    model_check = true           # free each structural parameter not estimated in turn
                                 # (calidar.strips.model_check)

    [trajectory_model]
    on = true
    block_s = 1.0
    correlation_s = [20.0, 3.5]  # s, the integral time of each Gauss–Markov process
    shape = ["gm1", "gm1"]       # position, attitude: Gauss–Markov of first or second order
    sigma = [0.03, 0.002]        # position m, attitude deg (absent: the trajectory's accuracy)

    [solver]                     # calidar.strips.config.StripSettings, with robust, robust_k,
                                 # robust_scale, max_iter, tol, covariance ("irls" or
                                 # "sandwich") of its calidar.adjust.SolverOptions
    [planes]                     # the tie planes' settings and threshold_m
                                 # (calidar.strips.planes.PlaneSettings)
    [vgicp]                      # VGICP's (calidar.strips.vgicp.VgicpSettings)
    [ingest]                     # strip_points (0: every overlapping point), block_cells, gap_s,
                                 # chunk_points, all_classes (false: no vegetation, noise or
                                 # water classes in the calibration's points)
    [inputs]                     # crs, time_system, geoid_undulation_m, trajectory_crs,
                                 # trajectory_angles, trajectory_heading, trajectory_columns,
                                 # control_crs, checkpoints_crs

A key left out takes its default; an unknown key or a value of the wrong type is an error naming
the file and the key.

>>> import tempfile
>>> from calidar.strips.config import CalibrationConfig, Estimate
>>> config = StripConfig(CalibrationConfig(Estimate.of("boresight", "lever_arm_z")))
>>> path = config.write(Path(tempfile.mkdtemp()) / "config.toml")
>>> StripConfig.read(path) == config
True
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field, replace
from pathlib import Path

from calidar.adjust import SolverOptions
from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines.config_toml import (
    build as _build, inputs_table, known as _known, plain as _plain, read_document,
    section as _section, table as _table, typed as _typed, write_document,
)
from calidar.pipelines.inputs import TrajectoryOptions
from calidar.ingest.settings import IngestSettings
from calidar.strips.config import (
    MATCHERS, CalibrationConfig, Estimate, StripSettings, TrajectorySettings,
)

#: [ingest] keys → IngestSettings fields (strip_points as --strip-points: 0 keeps every
#: overlapping point)
INGEST_KEYS = {"strip_points": "budget_points", "block_cells": "block_cells", "gap_s": "gap_s",
               "chunk_points": "chunk_points", "all_classes": "all_classes"}
#: [solver] keys of the engine's SolverOptions (StripSettings.adjustment); step_in_sigma is each
#: outer iteration's
ADJUSTMENT_KEYS = ("robust", "robust_k", "robust_scale", "max_iter", "tol", "covariance")
#: [inputs] keys → (PointOptions | TrajectoryOptions | StripConfig, field)
INPUT_KEYS = {"crs": ("points", "crs"), "time_system": ("points", "time_system"),
              "geoid_undulation_m": ("points", "geoid_undulation_m"),
              "trajectory_crs": ("trajectory", "crs"),
              "trajectory_angles": ("trajectory", "angles"),
              "trajectory_heading": ("trajectory", "heading"),
              "trajectory_columns": ("trajectory", "columns"),
              "control_crs": ("config", "control_crs"),
              "checkpoints_crs": ("config", "checkpoints_crs"),
              "control_sigma_m": ("config", "control_sigma_m")}
#: the top-level keys of the file besides the matchers' tables
TOP_KEYS = {"method", "estimate", "model_check", "checkpoint_class_cm", "trajectory_model",
            "solver", "ingest", "inputs"}


@dataclass(frozen=True)
class StripConfig:
    """Everything a strip calibration run takes besides its files: the calibration's
    configuration, how the strips are read (``ingest``, the streaming engine's settings with the
    point options; its overlap grid set to the solver's), how a text trajectory is read, the
    control points' CRS.

    >>> from calidar.strips.config import CalibrationConfig, Estimate, TrajectorySettings, Vgicp
    >>> estimate = Estimate.of("boresight", "range_offset")
    >>> config = StripConfig(CalibrationConfig(estimate, matchers=(Vgicp(),),
    ...                                        trajectory=TrajectorySettings(block_s=2.0)))
    >>> config.to_dict()["estimate"]
    ['boresight', 'range_offset']
    >>> config.to_dict()["trajectory_model"]
    {'on': True, 'block_s': 2.0, 'correlation_s': [20.0, 3.5], 'shape': ['gm1', 'gm1']}
    """

    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    ingest: IngestSettings = field(default_factory=IngestSettings)
    trajectory_input: TrajectoryOptions = field(default_factory=TrajectoryOptions)
    control_crs: str | None = None  #: the control points' CRS when it is not the strips'
    #: a reference cloud's stated vertical accuracy (--control-sigma), m
    control_sigma_m: float | None = None
    checkpoints_crs: str | None = None  #: the checkpoints' CRS when it is not the strips'
    #: the ASPRS vertical accuracy class (cm) the calibrated strips must meet at the checkpoints
    #: (--class)
    checkpoint_class_cm: float | None = None

    def __post_init__(self):
        # one overlap grid: the ingest reads on the calibration's (its solver settings), so that the
        # engine takes ``ingest`` as it stands
        s = self.calibration.solver
        if (self.ingest.cell_m, self.ingest.min_cells) != (s.overlap_cell_m, s.min_overlap_cells):
            ingest = replace(self.ingest, cell_m=s.overlap_cell_m, min_cells=s.min_overlap_cells)
            object.__setattr__(self, "ingest", ingest)

    @property
    def points(self) -> PointOptions:
        """How the strips' points are read (--crs, --time-system, --geoid-undulation)."""
        return self.ingest.points

    def to_dict(self) -> dict:
        """The TOML file's document (user units; None values left out)."""
        c = self.calibration
        doc = {"method": [m.name for m in c.matchers], "estimate": c.estimate.names(),
               "model_check": c.model_check}
        if self.checkpoint_class_cm is not None:
            doc["checkpoint_class_cm"] = self.checkpoint_class_cm
        traj = {"on": c.trajectory is not None}
        if c.trajectory is not None:
            t = c.trajectory
            traj.update(block_s=t.block_s, correlation_s=list(t.correlation_s),
                        shape=list(t.shape))
            if t.sigma is not None:
                traj["sigma"] = [t.sigma[0], math.degrees(t.sigma[1])]
        doc["trajectory_model"] = traj
        # no TOML null: no robust loss is "none", no clusters 0
        a = c.solver.adjustment
        engine = {k: v for k in ADJUSTMENT_KEYS[1:] if (v := getattr(a, k)) is not None}
        doc["solver"] = {**_plain(c.solver), "cluster_s": c.solver.cluster_s or 0,
                         "robust": a.robust or "none", **engine}
        for m in c.matchers:
            doc[m.name] = {"threshold_m": m.threshold_m, **_plain(m.settings)}
        ingest = {k: getattr(self.ingest, f) for k, f in INGEST_KEYS.items()}
        ingest["strip_points"] = ingest["strip_points"] or 0
        doc["ingest"] = {k: v for k, v in ingest.items() if v is not None}
        owners = {"points": self.points, "trajectory": self.trajectory_input, "config": self}
        doc["inputs"] = inputs_table(owners, INPUT_KEYS)
        return doc

    def write(self, path: Path) -> Path:
        """Write the TOML file (atomically); returns its path."""
        return write_document(path, self.to_dict(), "calidar boresight configuration: give it "
                              "again with --config to repeat the run")

    @classmethod
    def read(cls, path: Path) -> StripConfig:
        """The configuration of a TOML file (keys left out: their defaults)."""
        return from_document(read_document(path), Path(path))


def from_document(doc: dict, path: Path | None = None) -> StripConfig:
    """:class:`StripConfig` from a TOML document (:meth:`StripConfig.to_dict`'s layout)."""
    _known(doc, {*TOP_KEYS, *MATCHERS}, path, "")
    target = _typed(doc.get("checkpoint_class_cm"), float | None, path, "checkpoint_class_cm")
    estimate = _typed(doc.get("estimate", ["boresight"]), tuple[str, ...], path, "estimate")
    methods = _typed(doc.get("method", ["planes"]), tuple[str, ...], path, "method")
    for m in methods:
        if m not in MATCHERS:
            raise InputError(path, "method",
                             f"expected one or more of {', '.join(MATCHERS)}, got {m!r}")
    matchers = tuple(_matcher(MATCHERS[m], _table(doc, m, path), path) for m in methods)
    for m in set(MATCHERS) - set(methods):
        _matcher(MATCHERS[m], _table(doc, m, path), path)  # checked, though not used
    trajectory = _trajectory(_table(doc, "trajectory_model", path), path)
    solver = _solver(_table(doc, "solver", path), path)
    chosen = _build(path, "estimate", lambda: Estimate.of(*estimate))
    check = _typed(doc.get("model_check", True), bool, path, "model_check")
    calibration = _build(path, "method",
                         lambda: CalibrationConfig(chosen, matchers, trajectory, solver, check))
    kw = _ingest_fields(_table(doc, "ingest", path), path)
    parts = _input_fields(_table(doc, "inputs", path), path)
    points = _build(path, "inputs", lambda: PointOptions(**parts["points"]))
    ingest_options = _build(path, "ingest", lambda: IngestSettings(points=points, **kw))
    trajectory = _build(path, "inputs", lambda: TrajectoryOptions(**parts["trajectory"]))
    return StripConfig(calibration, ingest_options, trajectory, **parts["config"],
                       checkpoint_class_cm=target)


def _ingest_fields(ingest: dict, path) -> dict:
    """[ingest]: the IngestSettings fields it sets (strip_points 0: every overlapping point)."""
    _known(ingest, set(INGEST_KEYS), path, "ingest.")
    hints = typing.get_type_hints(IngestSettings)
    kw = {INGEST_KEYS[k]: _typed(v, hints[INGEST_KEYS[k]], path, f"ingest.{k}")
          for k, v in ingest.items()}
    if kw.get("budget_points") == 0:
        kw["budget_points"] = None
    return kw


def _input_fields(inputs: dict, path) -> dict[str, dict]:
    """[inputs]: the fields it sets of each owner of :data:`INPUT_KEYS` (points, trajectory,
    config), each CRS checked."""
    from calidar.sensor import validated_crs

    _known(inputs, set(INPUT_KEYS), path, "inputs.")
    parts: dict[str, dict] = {"points": {}, "trajectory": {}, "config": {}}
    hints = {"points": typing.get_type_hints(PointOptions),
             "trajectory": typing.get_type_hints(TrajectoryOptions)}
    for k, v in inputs.items():
        owner, name = INPUT_KEYS[k]
        if owner == "config" or name == "crs":
            kind = float | None if name == "control_sigma_m" else str | None
        else:
            kind = hints[owner][name]
        parts[owner][name] = _typed(v, kind, path, f"inputs.{k}")
        if k.endswith("crs"):
            validated_crs(v, str(path), f"inputs.{k}")
    return parts


def _solver(table: dict, path) -> StripSettings:
    """[solver]: StripSettings with the engine's SolverOptions (its :data:`ADJUSTMENT_KEYS`);
    "none" for no robust loss and 0 for no clusters (TOML has no null)."""
    table = {**table, **({"robust": None} if table.get("robust") == "none" else {}),
             **({"cluster_s": None} if table.get("cluster_s") == 0 else {})}
    if table.get("robust", "cauchy") not in (None, "cauchy", "huber"):
        raise InputError(path, "solver.robust",
                         f"expected cauchy, huber or none, got {table['robust']!r}")
    engine = {k: table.pop(k) for k in ADJUSTMENT_KEYS if k in table}
    adjustment = _section(SolverOptions, engine, path, "solver")
    return _section(StripSettings, table, path, "solver", adjustment=adjustment)


def _trajectory(table: dict, path) -> TrajectorySettings | None:
    _known(table, {"on", "block_s", "correlation_s", "shape", "sigma"}, path,
           "trajectory_model.")
    if not _typed(table.get("on", True), bool, path, "trajectory_model.on"):
        extra = sorted(set(table) - {"on"})
        if extra:
            raise InputError(path, f"trajectory_model.{extra[0]}", "given with on = false; "
                             "expected the model on or no trajectory-model settings")
        return None
    fields = {k: v for k, v in table.items() if k not in ("on", "sigma")}
    settings = _section(TrajectorySettings, fields, path, "trajectory_model")
    if "sigma" not in table:
        return settings
    pos, att_deg = _typed(table["sigma"], tuple[float, float], path, "trajectory_model.sigma")
    return _build(path, "trajectory_model.sigma",
                  lambda: replace(settings, sigma=(pos, math.radians(att_deg))))


def _matcher(cls: type, table: dict, path):
    settings_type = typing.get_type_hints(cls)["settings"]
    threshold = {k: v for k, v in table.items() if k == "threshold_m"}
    fields = {k: v for k, v in table.items() if k != "threshold_m"}
    settings = _section(settings_type, fields, path, cls.name)
    typed_threshold = {k: _typed(v, float, path, f"{cls.name}.{k}") for k, v in threshold.items()}
    return cls(settings, **typed_threshold)
