"""The strip calibrator's parameter set: the groups an estimate is made of, the engine's parameters
(every sensor parameter, the estimated ones free, plus the trajectory corrections), and a
simulation's truth in the same terms."""

from __future__ import annotations

from collections.abc import Mapping

from calidar.adjust import Parameter, ParameterSet
from calidar.sensor import Sensor
from calidar.strips.trajectory_errors import TrajectoryModel

#: What ``--estimate`` accepts → sensor parameters (name, unit of the engine).
ESTIMATE_GROUPS: dict[str, tuple[tuple[str, str], ...]] = {
    "boresight": (("boresight_roll", "rad"), ("boresight_pitch", "rad"), ("boresight_yaw", "rad")),
    "lever_arm": (("lever_arm_x", "m"), ("lever_arm_y", "m"), ("lever_arm_z", "m")),
    "range_offset": (("range_offset", "m"),),
    "range_scale": (("range_scale", "ppm"),),
    "scan_angle_scale": (("scan_angle_scale", "1"),),
    "scan_angle_offset": (("scan_angle_offset", "rad"),),
    "palmer": (("eccentricity_ratio", "1"), ("eccentricity_phase", "rad"), ("delta_l", "rad"),
               ("delta_r", "rad")),
    #: a height shift common to every strip (a vertical trajectory bias): only ground control
    #: sees it
    "height_bias": (("height_bias", "m"),),
}
#: Single parameters ``--estimate`` also accepts (e.g. lever_arm_x,lever_arm_y without z).
SINGLE_PARAMETERS = {name: ((name, unit),) for g in ESTIMATE_GROUPS.values() for name, unit in g}


def build_parameters(nominal: Sensor, estimate, spans: Mapping[int, tuple[float, float]],
                     trajectory: TrajectoryModel | None = None,
                     headings: Mapping[int, float] | None = None) -> ParameterSet:
    """The engine's parameters: every sensor parameter (those of ``estimate``, a
    :class:`calidar.strips.config.Estimate`, free) plus, with a ``trajectory`` model, the trajectory
    corrections of strips with time spans {id: (t0, t1)} s (``headings`` {id: rad from north}:
    which attitude σ the horizontal tilts get)."""
    free = set(estimate.parameters)
    units = {name: unit for g in ESTIMATE_GROUPS.values() for name, unit in g}
    params = [Parameter(name, value, units.get(name, "1"), free=name in free)
              for name, value in nominal.parameters().items() if name in units]
    # not a sensor parameter: a shift of every strip (calidar.strips.problem)
    if "height_bias" in free:
        params.append(Parameter("height_bias", 0.0, "m"))
    if trajectory is not None:
        params += trajectory.parameters(spans, headings)
    return ParameterSet(params)


def sensor_of(nominal: Sensor, values: Mapping[str, float]) -> Sensor:
    """``nominal`` with the sensor parameters among ``values`` (SI; other names ignored)."""
    own = set(nominal.parameters())
    return nominal.with_parameters(**{k: v for k, v in values.items() if k in own})


def truth_to_si(doc: dict, params: ParameterSet) -> dict[str, float]:
    """A truth.json document (display units: deg, m, ppm, as solution.json) → SI values by name.

    Values are read from ``doc["parameters"]`` (or ``doc`` itself), each a number or
    {"value": ...}; names the parameters do not know are ignored.
    """
    doc = doc.get("parameters", doc) if isinstance(doc.get("parameters"), dict) else doc
    out = {}
    for p in params:
        v = doc.get(p.name)
        if isinstance(v, dict):
            v = v.get("value")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            out[p.name] = float(v) / p.to_display(1.0)
    return out
