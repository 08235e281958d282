"""``calidar boresight``'s options and ``--config`` file made into one
:class:`calidar.pipelines.strip_config.StripConfig`, checked here, at the edge: the library below
takes typed values only (no option string is parsed under the CLI)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from calidar.cli.options import crs_option, parse_sigma, point_options, trajectory_options
from calidar.errors import InputError
from calidar.validate import parse_floats

#: the text trajectory's input options
TRAJECTORY_KEYS = ("trajectory_crs", "trajectory_angles", "trajectory_heading",
                   "trajectory_columns")


def parse_methods(text: str) -> tuple[str, ...]:
    """'planes', 'vgicp' or 'planes,vgicp' → the matchers' names, in order."""
    from calidar.strips.config import MATCHERS

    names = tuple(m.strip() for m in text.split(",") if m.strip())
    if not names or any(m not in MATCHERS for m in names) or len(set(names)) != len(names):
        raise InputError(None, "--method", f"expected one or more of {', '.join(MATCHERS)} "
                         f"separated by commas, got {text!r}")
    return names


def parse_estimate(text: str, trajectory_model: bool = True):
    """'boresight,lever_arm_x' → an :class:`calidar.strips.config.Estimate` (``trajectory_bias``,
    the trajectory model's own, is accepted while the model is on)."""
    from calidar.strips.config import Estimate

    names = [n.strip() for n in text.split(",") if n.strip()]
    if "trajectory_bias" in names and not trajectory_model:
        raise InputError(None, "--estimate", "trajectory_bias: the trajectory's errors are "
                         "estimated by the trajectory model; expected --trajectory-model on (the "
                         "default)")
    try:
        return Estimate.of(*[n for n in names if n != "trajectory_bias"])
    except InputError as e:
        problem = f"{e.problem} (comma-separated), got {text!r}"
        raise InputError(None, "--estimate", problem) from None


def _trajectory(base, given: dict):
    """The trajectory model's settings: ``base``'s (a TrajectorySettings or None: off) with the
    options given."""
    from calidar.strips.config import TrajectorySettings

    if given.get("trajectory_model") not in (None, "on", "off"):
        raise InputError(None, "--trajectory-model",
                         f"expected on or off, got {given['trajectory_model']!r}")
    on = base is not None if "trajectory_model" not in given else given["trajectory_model"] == "on"
    settings = base or TrajectorySettings()
    if "trajectory_block" in given:
        settings = replace(settings, block_s=given["trajectory_block"])
    if "trajectory_correlation" in given:
        correlation_s = parse_floats(given["trajectory_correlation"], 2,
                                     "--trajectory-correlation (POS_S,ATT_S)")
        settings = replace(settings, correlation_s=correlation_s)
    if given.get("trajectory_sigma") is not None:
        if not on:
            from calidar.pipelines.boresight import OFF_WITH_ACCURACY

            raise InputError(None, "--trajectory-model", OFF_WITH_ACCURACY)
        settings = replace(settings, sigma=parse_sigma(given["trajectory_sigma"]))
    return settings if on else None


def _ingest(base, given: dict):
    """The ingest options: ``base``'s with --strip-points, --all-classes and the point options
    given."""
    from calidar.ingest.settings import MIN_BUDGET_POINTS

    ingest = base
    if "strip_points" in given:
        n = given["strip_points"]
        if n != 0 and n < MIN_BUDGET_POINTS:
            raise InputError(None, "--strip-points", "expected 0 (every overlapping point) or at "
                             f"least {MIN_BUDGET_POINTS}, got {n}")
        ingest = replace(ingest, budget_points=n or None)
    if "all_classes" in given:
        ingest = replace(ingest, all_classes=bool(given["all_classes"]))
    keys = ("crs", "time_system", "geoid_undulation")
    if any(k in given for k in keys):
        p = ingest.points
        mine = dict(zip(keys, (p.crs, p.time_system, p.geoid_undulation_m)))
        ingest = replace(ingest, points=point_options(**_merged(mine, given)))
    return ingest


def strip_config(path: Path | None, given: dict):
    """The configuration: the ``--config`` file's (else the defaults), with the options ``given`` on
    the command line ({parameter name: value}) replacing its settings; every value checked."""
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import MATCHERS

    config = StripConfig.read(path) if path is not None else StripConfig()
    cal = config.calibration
    trajectory = _trajectory(cal.trajectory, given)
    changes = {"trajectory": trajectory}
    if "method" in given:
        own = {m.name: m for m in cal.matchers}
        names = parse_methods(given["method"])
        changes["matchers"] = tuple(own.get(n) or MATCHERS[n]() for n in names)
    if "estimate" in given:
        changes["estimate"] = parse_estimate(given["estimate"], trajectory is not None)
    if "model_check" in given:
        if given["model_check"] not in ("on", "off"):
            raise InputError(None, "--model-check",
                             f"expected on or off, got {given['model_check']!r}")
        changes["model_check"] = given["model_check"] == "on"
    config = replace(config, calibration=replace(cal, **changes),
                     ingest=_ingest(config.ingest, given))
    if any(k in given for k in TRAJECTORY_KEYS):
        trajectory_input = _trajectory_input(config.trajectory_input, given)
        config = replace(config, trajectory_input=trajectory_input)
    if "control_crs" in given:
        config = replace(config, control_crs=crs_option(given["control_crs"], "--control-crs"))
    if given.get("control_sigma") is not None:
        config = replace(config, control_sigma_m=float(given["control_sigma"]))
    if "checkpoints_crs" in given:
        crs = crs_option(given["checkpoints_crs"], "--checkpoints-crs")
        config = replace(config, checkpoints_crs=crs)
    if given.get("target_class") is not None:
        target_cm = checked_class(given["target_class"], given.get("checkpoints"))
        config = replace(config, checkpoint_class_cm=target_cm)
    return config


def _merged(mine: dict, given: dict) -> dict:
    """``mine`` ({option: value}) with the values of those of its options that were ``given``."""
    return {**mine, **{k: given[k] for k in mine if k in given}}


def _trajectory_input(base, given: dict):
    """The trajectory's input options: ``base``'s (TrajectoryOptions) with the options given."""
    columns = None if base.columns is None else ",".join(base.columns)
    mine = dict(zip(TRAJECTORY_KEYS, (base.crs, base.angles, base.heading, columns)))
    return trajectory_options(*_merged(mine, given).values())


def checked_class(target_cm: float, checkpoints: Path | None) -> float:
    """--class: a class in cm, with --checkpoints."""
    from calidar.validate import number

    if checkpoints is None:
        raise InputError(None, "--class",
                         "given without --checkpoints; expected --checkpoints FILE with it")
    number(target_cm, "--class", 0.1, 10000.0, "cm")
    return float(target_cm)
