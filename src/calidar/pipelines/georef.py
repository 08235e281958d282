"""The georeferencing pipelines: ``calidar inverse`` (points → scanner observations, CSV),
``calidar regeoref`` (strips re-georeferenced with a new sensor model) and ``calidar georef``
(an Optech CSD's raw pulses → points with calidar's own lidar equation). LAS/LAZ inputs are
streamed in chunks; every whole-file check runs before anything is written."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar import georef
from calidar.errors import InputError
from calidar.io.las import PointOptions, las_header, write_las
from calidar.io.optech_csd import csd_trajectory, read_csd, returns
from calidar.outputs import atomic_path, guard_inputs
from calidar.pipelines import Progress, no_progress
from calidar.pipelines import inputs
from calidar.pipelines.config_file import FileConfig, Key, crs_decoder
from calidar.pipelines.inputs import TrajectoryOptions, load_trajectory, trajectory_for
from calidar.ingest.plausibility import GeometryCheck, heights_notes
from calidar.ingest.rewrite import VECTOR_COLUMNS, inverse_rows, regeoreference_file
from calidar.sensor import Sensor
from calidar.sensor_import import from_optech_header
from calidar.validate import values

def inverse_points(points: Path, trajectory: Path, out: Path, *, sensor: Path | None = None,
                   point_options: PointOptions = PointOptions(),
                   trajectory_options: TrajectoryOptions = TrajectoryOptions(), force: bool = False,
                   progress: Progress = no_progress, notes: list[str] | None = None) -> int:
    """Inverse georeferencing of a LAS/LAZ file into a CSV of :data:`VECTOR_COLUMNS` (``out``,
    atomic): gps_time (s, as in the LAS), range_m (measured), x_s, y_s, z_s (m, scanner frame),
    across_track_angle_deg = atan2(y_s, z_s), along_track_angle_deg = atan2(x_s, hypot(y_s, z_s)).
    Returns the number of points; ``notes`` (when given) receives the vertical reference used and
    the plausibility warnings (:mod:`calidar.ingest.plausibility`, whose errors stop the run)."""
    guard_inputs([out], [points, trajectory, sensor])
    model = Sensor.read(sensor) if sensor else Sensor()
    loaded = load_trajectory(trajectory, trajectory_options)
    traj, week = trajectory_for(points, loaded, point_options, inputs.CHUNK_POINTS)
    check = GeometryCheck(points)
    with atomic_path(out, force) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(",".join(VECTOR_COLUMNS) + "\n")
        n, crs = inverse_rows(f, points, traj, week, model, point_options, check, progress,
                              las_header(points).point_count, inputs.CHUNK_POINTS)
    if notes is not None:
        notes += heights_notes(crs, point_options.geoid_undulation_m, check)
    return n


def regeoreference_strips(strips: list[Path], trajectory: Path, old: Path, new: Path,
                          out_dir: Path, *,
                          point_options: PointOptions = PointOptions(),
                          trajectory_options: TrajectoryOptions = TrajectoryOptions(),
                          progress: Progress = no_progress, to_trajectory: Path | None = None,
                          notes: list[str] | None = None) -> dict[Path, int]:
    """Re-georeference delivered strips: inverse with ``trajectory`` and the ``old`` sensor.toml,
    forward with ``to_trajectory`` (default: ``trajectory``; e.g. calidar boresight's
    sbet_corrected.out) and ``new``, written into ``out_dir`` under the strips' names (formats, CRS
    and every other attribute kept). Every strip is checked (CRS, whole-file trajectory coverage)
    before any is written, and its geometry while it is streamed
    (:mod:`calidar.ingest.plausibility`). Returns {output path: points}; ``notes`` (when given)
    receives the vertical reference and warnings."""
    old_s, new_s = Sensor.read(old), Sensor.read(new)
    traj0 = load_trajectory(trajectory, trajectory_options)
    new0 = None if to_trajectory is None else load_trajectory(to_trajectory, trajectory_options)
    names = [s.name for s in strips]
    if len(set(names)) != len(names):
        raise InputError(None, "STRIPS",
                         f"expected distinct file names (outputs share the folder), got {names}")
    guard_inputs([out_dir / s.name for s in strips], [*strips, trajectory, old, new, to_trajectory])
    chunk = inputs.CHUNK_POINTS
    plans = []
    for s in strips:
        traj, week = trajectory_for(s, traj0, point_options, chunk)
        new_traj = None if new0 is None else trajectory_for(s, new0, point_options, chunk)[0]
        plans.append((s, traj, week, new_traj))
    written, checks, crs = {}, [], None
    for k, (s, traj, week, new_traj) in enumerate(plans):
        checks.append(GeometryCheck(s))
        target = out_dir / s.name
        written[target] = regeoreference_file(s, target, traj, week, old_s, new_s, new_traj,
                                              point_options, checks[-1], chunk)
        progress("re-georeferencing strips", k + 1, len(plans))
    if notes is not None and strips:
        crs = inputs.las_file_crs(strips[0], point_options.crs)
        for check in checks:
            found = heights_notes(crs, point_options.geoid_undulation_m, check)
            notes += [n for n in found if n not in notes]
    return written


@dataclass(frozen=True)
class CsdResult:
    """What ``calidar georef`` made of a CSD file."""

    points: Path  #: the LAS/LAZ written
    sensor: Path  #: the sensor.toml written beside it
    n_points: int
    crs: str
    first_xyz: tuple[float, float, float]  #: the first point, in ``crs``
    first_gps_time: float


@dataclass(frozen=True)
class GeorefConfig(FileConfig):
    """What ``calidar georef`` takes besides its files: the output's CRS (None: the WGS 84 UTM zone
    of the first pulse) and a geoid undulation N (m) for a CRS with geoid heights; written beside
    the points as <name>.config.toml.

    >>> GeorefConfig(crs="EPSG:32611").to_dict()
    {'crs': 'EPSG:32611'}
    """

    KEYS = (Key("crs", "crs", "--crs", decode=crs_decoder("--crs")),
            Key("geoid_undulation_m", "geoid_undulation_m", "--geoid-undulation"))
    COMMAND = "georef"

    crs: str | None = None
    geoid_undulation_m: float | None = None

    def check(self) -> None:
        """N within its range (the CRS is checked when given)."""
        PointOptions(geoid_undulation_m=self.geoid_undulation_m)


def sensor_path(out: Path) -> Path:
    """Where ``calidar georef`` writes the sensor model beside its output: <stem>.sensor.toml."""
    return out.with_name(out.stem + ".sensor.toml")


def georeference_csd(csd: Path, out: Path, *, crs: str | None = None,
                     geoid_undulation_m: float | None = None, force: bool = False,
                     progress: Progress = no_progress) -> CsdResult:
    """Georeference an Optech CSD file's returns with calidar's lidar equation: the trajectory of
    its pulses (:func:`calidar.io.optech_csd.csd_trajectory`), the header's boresight as a calidar
    Sensor (:func:`calidar.sensor_import.from_optech_header`), the linear scanner at the pulses'
    scan angles. Writes ``out`` (LAS/LAZ, GPS week seconds as in the file) in ``crs`` (default:
    the WGS 84 UTM zone of the first pulse, ellipsoidal heights) and the sensor.toml beside it."""
    from calidar.sim.survey import utm_crs

    sensor_out = sensor_path(out)
    guard_inputs([out, sensor_out], [csd])
    pulses = read_csd(csd)
    pulse, slot, number, count = returns(pulses)
    if pulse.size == 0:
        raise InputError(csd, "return_count",
                         f"expected pulses with returns; none of the {len(pulses)} has one")
    crs = crs or utm_crs(np.degrees(pulses.lat[0]), np.degrees(pulses.lon[0]))
    sensor = from_optech_header(pulses.header, crs=str(crs))
    range_m = values(pulses.range_m[pulse, slot], csd, "range", 0.01, 1e4, "m", what="return")
    t = pulses.time[pulse]
    ecef = georef.forward(csd_trajectory(pulses), sensor, t, range_m, pulses.scan_angle[pulse])
    progress("georeferencing", pulse.size, pulse.size)
    xyz = georef.to_crs(ecef, crs, geoid_undulation_m, source="--crs")
    scan_angle_deg = np.degrees(pulses.scan_angle[pulse])
    # both files or neither
    with atomic_path(out, force) as tmp_points, atomic_path(sensor_out, force) as tmp_sensor:
        write_las(tmp_points, xyz, crs, gps_time=t, scan_angle_deg=scan_angle_deg,
                  point_source_id=1, return_number=number, number_of_returns=count,
                  intensity=pulses.intensity[pulse, slot], force=True)
        sensor.write(tmp_sensor, force=True)
    first_xyz = tuple(float(v) for v in xyz[0])
    return CsdResult(out, sensor_out, int(pulse.size), str(crs), first_xyz, float(t[0]))
