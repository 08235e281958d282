"""The configuration of a CCR calibration (``calidar ccr``) as one typed value, and its TOML
file: written beside the results (``config.toml``) and given again with ``--config`` to repeat the
run. In the units a user reads (ns for the detector's times)::

    beams = "all"              # or a list: ["gt1l", "gt2l"]

    [search]                   # calidar.photon.search.SearchSettings (m)
    diameter_min = 8.0
    diameter_max = 15.0
    diameter_step = 0.1
    length_step = 0.1
    bias_step = 0.05
    max_bias = 10.0
    bootstrap = 100
    seed = 0
    shared_bias = false
    surface_points = 9

    [system]                   # calidar.photon.passes.SystemParameters
    dead_time_s = 3.2e-09
    pulse_width_s = 1e-09
    shot_spacing_m = 0.7
    pointing_jitter_m = 0.3
    # channels = 16            # absent: from each beam's strength (16 strong, 4 weak)

A key left out takes its default; an unknown key or a value of the wrong type or range is an error
naming the file and the key.

>>> import tempfile
>>> from calidar.photon.search import SearchSettings
>>> config = CCRConfig(beams=("gt1l",), search=SearchSettings(bootstrap=20))
>>> CCRConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
>>> CCRConfig(search=SearchSettings(diameter_step=5.0))
Traceback (most recent call last):
calidar.errors.InputError: --diameter-step: expected a finite number in [0.01, 2] m, got 5.0
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

from calidar.errors import InputError
from calidar.io.atl03 import BEAMS
from calidar.photon.passes import SystemParameters
from calidar.photon.search import SearchSettings
from calidar.pipelines.config_file import FileConfig, Key
from calidar.validate import SEED_MAX, integer, number

SHOT_SPACING_RANGE = (0.05, 10.0)  #: m, along-track shot spacing accepted (ATLAS: 0.7 m)
#: [search] keys with a command-line option: (low, high, unit) of a number, or an integer's
#: (low, high, None)
SEARCH_RANGES = {"diameter_min": ("--diameter-range", 0.5, 500.0, "m"),
                 "diameter_max": ("--diameter-range", 0.5, 500.0, "m"),
                 "diameter_step": ("--diameter-step", 0.01, 2.0, "m"),
                 "length_step": ("--length-step", 0.01, 2.0, "m"),
                 "bias_step": (None, 0.001, 1.0, "m"), "max_bias": ("--max-bias", 0.5, 200.0, "m"),
                 "bootstrap": ("--bootstrap", 0, 10_000, None),
                 "seed": ("--seed", 0, SEED_MAX, None),
                 "surface_points": (None, 0, 101, None)}
#: the [search] keys' options ("shared_bias" has an option but no range)
SEARCH_OPTIONS = {**{k: v[0] for k, v in SEARCH_RANGES.items()}, "shared_bias": "--shared-bias"}
#: [system] keys (SI) → (SystemParameters field, the option's unit and its factor to SI, option,
#: low, high in the option's unit)
SYSTEM_KEYS = {"dead_time_s": ("dead_time", "ns", 1e-9, "--dead-time-ns", 0.1, 100.0),
               "pulse_width_s": ("pulse_width", "ns", 1e-9, "--pulse-width-ns", 0.01, 50.0),
               "shot_spacing_m": ("shot_spacing", "m", 1.0, "--shot-spacing-m",
                                  *SHOT_SPACING_RANGE),
               "pointing_jitter_m": ("pointing_jitter", "m", 1.0, "--pointing-jitter-m", 0.0, 5.0)}


def _label(key: str, option: str | None, keyed: bool) -> str:
    """Where a value is named: its option (as the command line gives it) or, ``keyed`` (read from a
    file), its key with the option."""
    if option is None:
        return key
    return f"{key} ({option})" if keyed else option


def check_search(s: SearchSettings, keyed: bool = False) -> None:
    """The search settings in their ranges (an error naming the option, or ``keyed`` the file's
    key)."""
    for key, (option, lo, hi, unit) in SEARCH_RANGES.items():
        where = _label(f"search.{key}", option, keyed)
        if unit is None:
            integer(getattr(s, key), None, lo, hi, field=where)
        else:
            number(getattr(s, key), None, lo, hi, unit, field=where)
    if not s.diameter_min < s.diameter_max:
        where = _label("search.diameter_min, diameter_max", "--diameter-range", keyed)
        raise InputError(None, where,
                         f"expected MIN < MAX, got {s.diameter_min:g}, {s.diameter_max:g}")
    if not isinstance(s.shared_bias, bool):
        raise InputError(None, _label("search.shared_bias", "--shared-bias", keyed),
                         f"expected true or false, got {s.shared_bias!r}")


def check_system(s: SystemParameters, keyed: bool = False) -> None:
    """The instrument's constants in their ranges (an error naming the option, or ``keyed`` the
    file's key)."""
    for key, (name, unit, factor, option, lo, hi) in SYSTEM_KEYS.items():
        where = _label(f"system.{key}", option, keyed)
        number(getattr(s, name) / factor, None, lo, hi, unit, field=where)
    if s.channels is not None:
        integer(s.channels, None, 1, 64, field=_label("system.channels", "--channels", keyed))


def check_beams(beams: tuple[str, ...] | None, keyed: bool = False) -> None:
    """The beams: None (all) or names of ATL03 beams, each once."""
    if beams is not None:
        bad = [b for b in beams if b not in BEAMS]
        if bad or not beams or len(set(beams)) != len(beams):
            raise InputError(None, _label("beams", "--beam", keyed), "expected all, or one or "
                             f"more of {', '.join(BEAMS)} (each once), got "
                             f"{', '.join(beams) or 'none'}")


def _beams(value: str | tuple[str, ...]) -> tuple[str, ...] | None:
    """The file's beams: "all" (None) or a list of names."""
    if isinstance(value, str):
        if value != "all":
            raise InputError(None, "--beam",
                             f"expected all or a list of beam names, got {value!r}")
        return None
    return value


@dataclass(frozen=True)
class CCRConfig(FileConfig):
    """What ``calidar ccr`` takes besides its files: the beams (None: every beam of each file), the
    grid search's and the fit's settings, and the instrument's constants; every value checked when
    made.

    >>> from calidar.photon.search import SearchSettings
    >>> config = CCRConfig(beams=("gt1l", "gt2l"), search=SearchSettings(bootstrap=0))
    >>> config.beam_text, config.to_dict()["search"]["bootstrap"]
    ('gt1l,gt2l', 0)
    """

    KEYS = (Key("beams", "beams", "--beam", str | tuple[str, ...],
                encode=lambda b: "all" if b is None else b, decode=_beams),
            *(Key(f"search.{f.name}", f"search.{f.name}", SEARCH_OPTIONS.get(f.name))
              for f in fields(SearchSettings)),
            *(Key(f"system.{k}", f"system.{name}", option, float)
              for k, (name, _, _, option, *_) in SYSTEM_KEYS.items()),
            Key("system.channels", "system.channels", "--channels"))
    COMMAND = "ccr"

    beams: tuple[str, ...] | None = None
    search: SearchSettings = field(default_factory=SearchSettings)
    system: SystemParameters = field(default_factory=SystemParameters)

    def __post_init__(self):
        if not (isinstance(self.search, SearchSettings)
                and isinstance(self.system, SystemParameters)):
            raise InputError(None, "search, system", "expected SearchSettings and SystemParameters")
        check_beams(self.beams)
        check_search(self.search)
        check_system(self.system)

    @property
    def beam_text(self) -> str:
        """The beams as ``--beam`` names them ("all" or "gt1l,gt2l")."""
        return "all" if self.beams is None else ",".join(self.beams)
