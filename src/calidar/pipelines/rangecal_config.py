"""The configuration of a range calibration (``calidar range-cal``) as one typed value, and its
TOML file: written beside the results (``config.toml``) and given again with ``--config`` to repeat
the run::

    tolerance_m = 0.05     # acceptance tolerance of the raw range error
                           # (absent: no acceptance check)
    fix_scale = false      # true: estimate the offset only

A key left out takes its default; an unknown key or a value of the wrong type is an error naming
the file and the key.

>>> import tempfile
>>> config = RangeCalConfig(tolerance_m=0.05)
>>> RangeCalConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
>>> try:
...     RangeCalConfig(tolerance_m=-1.0)
... except InputError as e:
...     print(e)
tolerance_m (--tolerance): expected a finite number in (0, 10] m, got -1.0
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from calidar.errors import InputError
from calidar.pipelines.config_file import FileConfig, Key
from calidar.validate import number

MAX_TOLERANCE_M = 10.0  #: largest --tolerance (m)


@dataclass(frozen=True)
class RangeCalConfig(FileConfig):
    """What ``calidar range-cal`` takes besides its files: the acceptance tolerance of the raw range
    error (m, None: no acceptance check) and whether the scale is held at 0 (the offset only).

    >>> RangeCalConfig(tolerance_m=0.05).to_dict()
    {'tolerance_m': 0.05, 'fix_scale': False}
    """

    KEYS = (Key("tolerance_m", "tolerance_m", "--tolerance"),
            Key("fix_scale", "fix_scale", "--fix-scale"))
    COMMAND = "range-cal"

    tolerance_m: float | None = None
    fix_scale: bool = False

    def __post_init__(self):
        if self.tolerance_m is not None:
            number(self.tolerance_m, None, 0.0, MAX_TOLERANCE_M, "m",
                   field="tolerance_m (--tolerance)", open_lo=True)
            object.__setattr__(self, "tolerance_m", float(self.tolerance_m))
        if not isinstance(self.fix_scale, bool):
            raise InputError(None, "fix_scale (--fix-scale)",
                             f"expected true or false, got {self.fix_scale!r}")
