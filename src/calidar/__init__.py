"""calidar — open geometric calibration of laser scanning systems.

Units are SI and radians inside the library; degrees appear only at the user's edge
(CLI, files, report). Times are GPS seconds. See docs/conventions.md.

The public API, one name per job (each documented with an example)::

    import calidar
    traj = calidar.read_trajectory("sbet.out")        # SBET, ASCII/CSV or Optech CSD
    sensor = calidar.Sensor.read("sensor.toml")
    points = calidar.read_las("line_001.laz")
    strips = ["line_001.laz", "line_002.laz"]
    run = calidar.calibrate_strips(strips, "sbet.out", "sensor.toml", calidar.StripConfig())
    run.write("out/")                      # solution.json, sensor.toml, config.toml, report.html

Names are imported on first use, so ``import calidar`` stays cheap.
"""



def _record_signals_when_the_cli_starts() -> None:
    """The ``calidar`` command (or ``python -m calidar``) starting: record SIGINT / SIGTERM from
    this first line of calidar on (:mod:`calidar.interrupts`), so that a Ctrl-C while the CLI's
    modules load ends the run cleanly, not in a KeyboardInterrupt traceback
    (``calidar.cli.signals`` takes over), and report a crash's stacks. A library import changes
    no signal handler."""
    import os
    import signal
    import sys
    import threading

    argv0 = os.path.basename(sys.argv[0]) if sys.argv else ""
    orig = list(getattr(sys, "orig_argv", []))
    run_as_module = any(a == "-m" and b == "calidar" for a, b in zip(orig, orig[1:]))
    starting = argv0 == "calidar" or run_as_module
    if starting and threading.current_thread() is threading.main_thread():
        from calidar import interrupts

        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, lambda signum, frame: interrupts.record(signum))
        _report_crashes()


def _report_crashes() -> None:
    """A crash of the command (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT in native code) prints
    Python's stack of every thread on stderr (:mod:`faulthandler`) instead of ending in silence:
    what a bug report needs. Only the command: a library import changes no signal handler."""
    import faulthandler
    import sys

    if sys.stderr is not None and not faulthandler.is_enabled():
        try:
            faulthandler.enable()
        except (RuntimeError, ValueError, OSError):  # no usable stderr file descriptor
            pass


_record_signals_when_the_cli_starts()

__version__ = "0.1.0"

#: public name → (module, attribute in it)
_API = {
    "Trajectory": ("calidar.trajectory", "Trajectory"),
    "read_trajectory": ("calidar.io.trajectory", "read_trajectory"),
    "read_sbet": ("calidar.io.sbet", "read_sbet"),
    "write_sbet": ("calidar.io.sbet", "write_sbet"),
    "read_trajectory_text": ("calidar.io.trajectory_text", "read_trajectory_text"),
    "write_trajectory_text": ("calidar.io.trajectory_text", "write_trajectory_text"),
    "read_las": ("calidar.io.las", "read_las"),
    "write_las": ("calidar.io.las_write", "write_las"),
    "Sensor": ("calidar.sensor", "Sensor"),
    "georeference": ("calidar.georef", "forward"),
    "inverse_georeference": ("calidar.georef", "inverse"),
    "calibrate_strips": ("calidar.pipelines.boresight", "calibrate_strips"),
    "StripConfig": ("calidar.pipelines.strip_config", "StripConfig"),
    "calibrate_range": ("calidar.pipelines.rangecal", "run_range_cal"),
    "RangeCalConfig": ("calidar.pipelines.rangecal_config", "RangeCalConfig"),
    "calibrate_ccr": ("calidar.pipelines.ccr", "run_ccr"),
    "CCRConfig": ("calidar.pipelines.ccr_config", "CCRConfig"),
    "TpuConfig": ("calidar.pipelines.tpu_config", "TpuConfig"),
    "survey_config": ("calidar.sim.survey", "survey_config"),
    "simulate_survey": ("calidar.sim.survey", "simulate_survey"),
}

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    """Import a public name on first use (PEP 562)."""
    if name not in _API:
        raise AttributeError(f"module 'calidar' has no attribute {name!r}")
    from importlib import import_module

    module, attr = _API[name]
    value = getattr(import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
