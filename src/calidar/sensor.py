"""The sensor model: mounting (boresight, lever arm), scanner, range model, output CRS.

Range model: measured = (1 + range_scale) · true + range_offset, so georeferencing uses
true = (measured − range_offset) / (1 + range_scale).
Boresight R_bs = Rz(yaw) · Ry(pitch) · Rx(roll) rotates scanner-frame vectors into the body
frame; the lever arm a_b is the scanner origin in the body frame (m).

``sensor.toml``: every key, its unit, allowed range and default are in docs/sensor.md
(with the conversions from vendor conventions, :mod:`calidar.sensor_import`).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from calidar import frames
from calidar.errors import InputError
from calidar.outputs import write_text_atomic
from calidar.scanners import Scanner, scanner_from_toml
from calidar.scanners.linear import LinearScanner
from calidar.validate import read_text, table_number

MOUNTING_PARAMETERS = ("boresight_roll", "boresight_pitch", "boresight_yaw",
                       "lever_arm_x", "lever_arm_y", "lever_arm_z")
RANGE_PARAMETERS = ("range_offset", "range_scale")
MOUNTING_KEYS = ("boresight_roll_deg", "boresight_pitch_deg", "boresight_yaw_deg", "lever_arm_m")
#: the physical ranges sensor.toml values are checked against (docs/sensor.md)
BORESIGHT_MAX_DEG = 180.0
LEVER_ARM_MAX_M = 50.0
RANGE_OFFSET_MAX_M = 100.0
RANGE_SCALE_MAX_PPM = 1e5
CALIBRATION_KEYS = ("date", "calidar_version", "solution", "method", "sigma")


@dataclass(frozen=True)
class CalibrationRecord:
    """Where a calibrated ``sensor.toml`` came from: its ``[calibration]`` table (docs/sensor.md).

    ``sigma`` holds each estimated value's standard deviation keyed as the value is written
    (``boresight_roll_deg``, ``lever_arm_x_m``, ``range_offset_m``, ``range_scale_ppm``, a scanner
    key): information for the reader, never used to georeference.
    """

    date: str  #: UTC, ISO 8601
    calidar_version: str
    solution: str  #: the solution file it came from, as named in the output folder
    method: str = ""
    sigma: dict[str, float] = field(default_factory=dict)

    def to_toml(self) -> list[str]:
        lines = ["", "[calibration]", f"date = {_toml_value(self.date)}",
                 f"calidar_version = {_toml_value(self.calidar_version)}",
                 f"solution = {_toml_value(self.solution)}"]
        if self.method:
            lines.append(f"method = {_toml_value(self.method)}")
        if self.sigma:
            header = "[calibration.sigma]  # 1σ of each estimated value, in the unit its key names"
            lines += ["", header]
            lines += [f"{k} = {_toml_value(v)}" for k, v in self.sigma.items()]
        return lines

    @classmethod
    def from_dict(cls, table, source: str) -> "CalibrationRecord":
        _only(table, set(CALIBRATION_KEYS), source, "calibration.")
        text = {}
        for key in CALIBRATION_KEYS[:4]:
            value = table.get(key, "")
            if not isinstance(value, str):
                raise InputError(source, f"calibration.{key}", f"expected a string, got {value!r}")
            text[key] = value
        sigma = table.get("sigma", {})
        if not isinstance(sigma, dict):
            raise InputError(source, "calibration.sigma", "expected a table of σ values")
        values = {k: table_number(sigma, k, source, 0.0, None, "", "calibration.sigma.")
                  for k in sigma}
        return cls(**text, sigma=values)


@dataclass(frozen=True)
class Sensor:
    """A complete sensor model; all values SI (rad, m, ratio). ``sensor.toml`` holds it in
    degrees, metres and ppm (:meth:`read`, :meth:`write`; keys in docs/sensor.md).

    >>> import tempfile, numpy as np, calidar
    >>> roll = np.radians(0.05)
    >>> sensor = calidar.Sensor(boresight_roll=roll, lever_arm_z=0.12, range_offset=0.03)
    >>> path = sensor.write(Path(tempfile.mkdtemp()) / "sensor.toml")
    >>> print(path.read_text().split("[range]")[0].split("[mounting]")[1].strip())
    boresight_roll_deg = 0.05
    boresight_pitch_deg = 0.0
    boresight_yaw_deg = 0.0
    lever_arm_m = [0.0, 0.0, 0.12]
    >>> back = calidar.Sensor.read(path)
    >>> round(float(np.degrees(back.boresight_roll)), 12), back.range_offset
    (0.05, 0.03)
    >>> type(back.scanner).__name__
    'LinearScanner'
    """

    boresight_roll: float = 0.0
    boresight_pitch: float = 0.0
    boresight_yaw: float = 0.0
    lever_arm_x: float = 0.0
    lever_arm_y: float = 0.0
    lever_arm_z: float = 0.0
    range_offset: float = 0.0
    range_scale: float = 0.0
    scanner: Scanner = field(default_factory=LinearScanner)
    crs: str | None = None
    #: where a calibrated sensor came from (``[calibration]``); None for a nominal sensor
    calibration: CalibrationRecord | None = field(default=None, compare=False)

    @cached_property
    def r_bs(self) -> np.ndarray:
        """Boresight rotation scanner → body (3, 3), read-only (computed once per sensor: the
        strip adjustment asks for it per correspondence block and evaluation)."""
        r = frames.rpy_to_matrix(self.boresight_roll, self.boresight_pitch, self.boresight_yaw)
        r.setflags(write=False)
        return r

    @property
    def lever_arm(self) -> np.ndarray:
        """Lever arm a_b (3,), m."""
        return np.array([self.lever_arm_x, self.lever_arm_y, self.lever_arm_z])

    def true_range(self, measured_m) -> np.ndarray:
        """Corrected range from the measured one, m."""
        return (np.asarray(measured_m, float) - self.range_offset) / (1.0 + self.range_scale)

    def measured_range(self, true_m) -> np.ndarray:
        """What the instrument reports for a true range, m."""
        return (1.0 + self.range_scale) * np.asarray(true_m, float) + self.range_offset

    def parameters(self) -> dict[str, float]:
        """Every estimable parameter by name (SI), scanner parameters included."""
        out = {k: getattr(self, k) for k in MOUNTING_PARAMETERS + RANGE_PARAMETERS}
        out.update(self.scanner.parameters())
        return out

    def with_parameters(self, **values: float) -> "Sensor":
        """A copy with named parameters replaced (mounting, range or scanner ones)."""
        mine = MOUNTING_PARAMETERS + RANGE_PARAMETERS
        own = {k: float(v) for k, v in values.items() if k in mine}
        rest = {k: float(v) for k, v in values.items() if k not in own}
        scanner = self.scanner.with_parameters(**rest) if rest else self.scanner
        return replace(self, scanner=scanner, **own)

    def to_toml(self) -> str:
        """sensor.toml text (degrees, metres, ppm)."""
        lines = ["# calidar sensor model: angles in degrees, lengths in metres (docs/sensor.md)"]
        if self.crs:
            lines.append(f'crs = "{self.crs}"')
        lines += [
            "",
            "[mounting]",
            f"boresight_roll_deg = {_toml_value(np.degrees(self.boresight_roll))}",
            f"boresight_pitch_deg = {_toml_value(np.degrees(self.boresight_pitch))}",
            f"boresight_yaw_deg = {_toml_value(np.degrees(self.boresight_yaw))}",
            f"lever_arm_m = {_toml_value([self.lever_arm_x, self.lever_arm_y, self.lever_arm_z])}",
            "",
            "[range]",
            f"offset_m = {_toml_value(self.range_offset)}",
            f"scale_ppm = {_toml_value(self.range_scale * 1e6)}",
            "",
            "[scanner]",
        ]
        for k, v in self.scanner.to_toml().items():
            lines.append(f"{k} = {_toml_value(v)}")
        if self.calibration is not None:
            lines += self.calibration.to_toml()
        return "\n".join(lines) + "\n"

    def write(self, path: str | Path, force: bool = False) -> Path:
        """Write sensor.toml atomically."""
        return write_text_atomic(path, self.to_toml(), force=force)

    @classmethod
    def read(cls, path: str | Path) -> "Sensor":
        """Read sensor.toml (docs/sensor.md): unknown tables/keys, wrong types, missing keys without
        a documented default and values outside their range are clear errors naming the key."""
        text = read_text(path, "sensor.toml")
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise InputError(path, None, f"not valid TOML ({e})") from None
        return cls.from_dict(doc, str(path))

    @classmethod
    def from_dict(cls, doc: dict, source: str = "sensor.toml") -> "Sensor":
        """A Sensor from a parsed sensor.toml (see :meth:`read` and docs/sensor.md for keys, units,
        ranges)."""
        _only(doc, {"crs", "mounting", "range", "scanner", "calibration"}, source, "")
        scanner = scanner_from_toml(doc.get("scanner", {"model": "linear"}), source)
        if "mounting" not in doc:
            raise InputError(source, "mounting", "missing table; expected [mounting] with "
                             "boresight_roll_deg, boresight_pitch_deg, boresight_yaw_deg and "
                             "lever_arm_m (docs/sensor.md)")
        m = doc["mounting"]
        _only(m, set(MOUNTING_KEYS), source, "mounting.")
        r = doc.get("range", {})
        _only(r, {"offset_m", "scale_ppm"}, source, "range.")
        b = BORESIGHT_MAX_DEG
        angles = [np.radians(table_number(m, k, source, -b, b, "deg", "mounting."))
                  for k in MOUNTING_KEYS[:3]]
        lever_arm = _lever_arm(m.get("lever_arm_m"), source)
        offset = table_number(r, "offset_m", source, -RANGE_OFFSET_MAX_M, RANGE_OFFSET_MAX_M, "m",
                              "range.", 0.0)
        scale_ppm = table_number(r, "scale_ppm", source, -RANGE_SCALE_MAX_PPM, RANGE_SCALE_MAX_PPM,
                                 "ppm", "range.", 0.0)
        crs = validated_crs(doc.get("crs"), source)
        calibration = doc.get("calibration")
        if calibration is not None:
            calibration = CalibrationRecord.from_dict(calibration, source)
        return cls(*angles, *lever_arm, range_offset=offset, range_scale=scale_ppm * 1e-6,
                   scanner=scanner, crs=crs, calibration=calibration)


def _lever_arm(lever, source: str) -> tuple[float, float, float]:
    """mounting.lever_arm_m: three finite numbers within ±LEVER_ARM_MAX_M (m)."""
    field = "mounting.lever_arm_m"
    if lever is None:
        raise InputError(source, field, "missing; expected [x, y, z] in metres (body frame: "
                         "forward, right, down)")
    if not (isinstance(lever, list) and len(lever) == 3):
        raise InputError(source, field, f"expected 3 numbers [x, y, z] in metres, got {lever!r}")
    m = LEVER_ARM_MAX_M
    return tuple(table_number({k: v}, k, source, -m, m, "m", field + ".")
                 for k, v in zip("xyz", lever))


def validated_crs(crs, source: str | None, field: str = "crs") -> str | None:
    """``crs`` when pyproj knows it (None stays None), else a clear error naming ``source`` and
    ``field`` (an option: ``validated_crs(text, None, "--crs")``)."""
    if crs is None:
        return None
    import pyproj

    try:
        pyproj.CRS.from_user_input(crs)
    except (pyproj.exceptions.CRSError, TypeError):
        message = f"expected a CRS pyproj knows (e.g. 'EPSG:32611'), got {crs!r}"
        raise InputError(source, field, message) from None
    return crs


def _only(table: dict, known: set[str], source: str, prefix: str) -> None:
    if not isinstance(table, dict):
        raise InputError(source, prefix.rstrip(".") or None, "expected a table")
    unknown = set(table) - known
    if unknown:
        message = f"unknown key; expected one of {sorted(known)}"
        raise InputError(source, prefix + sorted(unknown)[0], message)


def _toml_value(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v))
