"""Per-point total propagated uncertainty (TPU) of airborne/UAV lidar points.

The lidar equation (docs/conventions.md) p = r + R_eb·(R_bs·ρ·u_s(θ) + a_b) is linearised about
each point and every input's covariance carried through it (first-order propagation, Glennie
2007, "Rigorous 3D error analysis of kinematic scanning LIDAR systems", J. Appl. Geodesy 1:147):

- GNSS/INS position σ north/east/down (per epoch, e.g. POSPac's smrmsg): ∂p/∂r = I;
- attitude σ roll, pitch, heading (Euler angles, R_nb = Rz(heading)·Ry(pitch)·Rx(roll)): small
  rotations of the lever vector w = p − r about the body's x axis (roll), the horizontal axis
  square to the heading (pitch: ∂R_nb/∂pitch = [Rz·ŷ]×·R_nb) and the local down axis (heading):
  ∂p/∂α = axis × w;
- range noise σ_ρ along the beam b: ∂p/∂ρ = b;
- encoder (scan-angle) noise σ_θ: ∂p/∂θ = ρ·R_eb·R_bs·∂u_s/∂θ (central differences of the
  scanner model, so every scanner calidar models is covered);
- the beam's footprint (divergence γ, full angle): the return comes from anywhere in a footprint
  of radius ρ·γ/2, taken as 2σ of a Gaussian beam: an angular offset of σ = γ/4 on each axis square
  to the beam, so σ = ρ·γ/4 across the beam against the spot the return came from (Baltsavias 1999,
  ISPRS J. 54:199; Glennie 2007, Sect. 3.4). The incidence α on an inclined surface is in this term
  already: projected on the surface's normal it gives (ρ·γ/4)·sin α, which is Baltsavias' range
  spread (ρ·γ/4)·tan α seen along the normal (× cos α). No separate along-beam term: that spread is
  the same offset measured from where the nominal beam meets the surface instead of the actual
  spot, and adding both counted the footprint twice (√2 too much normal to the surface; see
  :func:`_footprint`);
- the calibration's own covariance (boresight, lever arm, range offset and scale from
  ``solution.json``, with their correlations): J_cal·Σ_cal·J_calᵀ, J_cal by central differences
  of the lidar equation in each parameter. No other tool propagates this term.

The terms are independent of each other; within one term the σ are taken as the source states
them (smrmsg: independent axes). Output: the covariance (N, 3, 3) in local east/north/up at each
point; :func:`thu_tvu` gives the horizontal (radial, √(σ_e² + σ_n²)) and vertical 1σ as cBLUE
names them (total_thu, total_tvu).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar import frames, georef
from calidar.cells import grid_indices
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory
from calidar.trajectory_accuracy import TrajectoryAccuracy

#: central-difference steps: encoder angle (rad) and calibration parameters by SI unit
ANGLE_STEP_RAD = 1e-6
CALIBRATION_STEPS = {"rad": 1e-6, "m": 1e-4, "1": 1e-7, "ppm": 1e-7}


@dataclass(frozen=True)
class TpuSettings:
    """The sensor's own noise, in SI: range σ (m), encoder angle σ (rad), beam divergence (rad, full
    angle; 0 leaves the footprint out) and the cell (m) of local surfaces (:func:`surface_normals`;
    the footprint term needs no normal since it is across the beam only: :func:`_footprint`)."""

    range_sigma_m: float = 0.01
    angle_sigma_rad: float = float(np.radians(0.002))
    beam_divergence_rad: float = 0.25e-3
    normal_cell_m: float = 2.0


@dataclass(frozen=True)
class CalibrationCovariance:
    """The estimated sensor parameters (names as :meth:`Sensor.parameters`), their covariance (SI)
    and the unit of each (for the differentiation step)."""

    names: tuple[str, ...]
    covariance: np.ndarray  #: (k, k) SI
    units: tuple[str, ...]

    def __post_init__(self):
        c = np.asarray(self.covariance, float)
        k = len(self.names)
        if c.shape != (k, k):
            raise ValueError(f"covariance must be {k}×{k}, got {c.shape}")
        object.__setattr__(self, "covariance", c)


def enu_rotation(points_ecef: np.ndarray) -> np.ndarray:
    """ECEF → local east/north/up (3, 3) at the points' mean (a chunk spans a few km at most:
    the verticals differ by < 0.05°)."""
    lat, lon, _ = frames.ecef_to_geodetic(np.mean(points_ecef, axis=0))
    r_ned = frames.r_en(lat, lon)  # NED → ECEF: columns north, east, down
    return np.stack([r_ned[:, 1], r_ned[:, 0], -r_ned[:, 2]])


def surface_normals(points_enu: np.ndarray, cell_m: float, min_points: int = 6) -> np.ndarray:
    """Unit normals (N, 3) of the local surface at each point: the plane of its cell's points
    (least-squares, smallest eigenvector of the cell's scatter), up where a cell has too few."""
    key = grid_indices(points_enu, cell_m)
    _, cell, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    cell = cell.ravel()
    centred = points_enu - points_enu.mean(axis=0)
    mean = np.stack([np.bincount(cell, centred[:, k]) for k in range(3)], 1) / count[:, None]
    d = centred - mean[cell]
    scatter = np.empty((count.size, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            scatter[:, i, j] = scatter[:, j, i] = np.bincount(cell, d[:, i] * d[:, j])
    normal = np.linalg.eigh(scatter)[1][:, :, 0]
    normal[count < min_points] = (0.0, 0.0, 1.0)
    normal *= np.where(normal[:, 2:] < 0, -1.0, 1.0)
    return normal[cell]


def _outer_sum(cov: np.ndarray, d: np.ndarray, sigma) -> None:
    """cov += σ²·d·dᵀ for derivative vectors d (N, 3) and σ (N,) or scalar."""
    cov += (np.asarray(sigma, float) ** 2)[..., None, None] * d[:, :, None] * d[:, None, :]


def point_covariance(traj: Trajectory, sensor: Sensor, accuracy: TrajectoryAccuracy, time,
                     points_ecef, settings: TpuSettings = TpuSettings(),
                     calibration: CalibrationCovariance | None = None) -> np.ndarray:
    """The covariance (N, 3, 3) m² in local east/north/up of points (N, 3) ECEF at GPS times (N,) s,
    georeferenced from ``traj`` with ``sensor`` (see the module docstring for every term)."""
    points_ecef = np.asarray(points_ecef, float)
    time = np.asarray(time, float)
    obs = georef.inverse(traj, sensor, time, points_ecef)
    position, r_eb = georef.poses(traj, time)
    rho = sensor.true_range(obs.range_m)
    enu = enu_rotation(points_ecef)
    # every derivative vector in ENU: rotate the poses once
    r_nb = enu @ r_eb
    w = (points_ecef - position) @ enu.T  # lever vector IMU → point
    beam = sensor.scanner.directions(obs.angles) @ sensor.r_bs.T
    b = np.einsum("nij,nj->ni", r_nb, beam)
    cov = np.zeros((time.size, 3, 3))
    sig_pos, sig_att = accuracy.at(time)  # north, east, down; roll, pitch, heading
    north, east, down = sig_pos.T
    cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2] = east ** 2, north ** 2, down ** 2
    _attitude_terms(cov, r_nb, w, sig_att)
    _outer_sum(cov, b, settings.range_sigma_m / (1.0 + sensor.range_scale))
    if settings.angle_sigma_rad:
        d_angle = rho[:, None] * _direction_derivative(sensor, obs.angles, r_nb)
        _outer_sum(cov, d_angle, settings.angle_sigma_rad)
    if settings.beam_divergence_rad:
        _footprint(cov, b, rho, settings)
    if calibration is not None:
        jac = calibration_jacobian(sensor, calibration, position, r_eb, obs.range_m, obs.angles)
        jac = jac @ enu.T
        cov += np.einsum("nki,kl,nlj->nij", jac, calibration.covariance, jac)
    return cov


def _attitude_terms(cov: np.ndarray, r_nb: np.ndarray, w: np.ndarray, sig_att: np.ndarray) -> None:
    """cov += the roll, pitch and heading σ (N, 3) rad as rotations of the lever vector ``w`` (N, 3)
    about the forward axis, the horizontal axis right of the heading and down (ENU)."""
    forward = r_nb[:, :, 0]
    right = np.stack([forward[:, 1], -forward[:, 0], np.zeros(len(w))], 1)
    right /= np.linalg.norm(right, axis=1)[:, None]
    for k, axis in enumerate((forward, right, np.broadcast_to([0.0, 0.0, -1.0], w.shape))):
        _outer_sum(cov, np.cross(axis, w), sig_att[:, k])


def _direction_derivative(sensor: Sensor, angles, r_nb: np.ndarray) -> np.ndarray:
    """∂(R_nb·R_bs·u_s)/∂θ (N, 3) for the first (encoder) angle, by central differences."""
    angles = np.array(angles, float)
    hi, lo = angles.copy(), angles.copy()
    if angles.ndim == 1:
        hi += ANGLE_STEP_RAD
        lo -= ANGLE_STEP_RAD
    else:
        hi[:, 0] += ANGLE_STEP_RAD
        lo[:, 0] -= ANGLE_STEP_RAD
    du = (sensor.scanner.directions(hi) - sensor.scanner.directions(lo)) / (2 * ANGLE_STEP_RAD)
    return np.einsum("nij,nj->ni", r_nb, du @ sensor.r_bs.T)


def _footprint(cov: np.ndarray, b: np.ndarray, rho: np.ndarray, settings: TpuSettings) -> None:
    """The footprint's share: (ρ·γ/4)² on each axis square to the beam b, nothing along it.

    The error judged is the point's against the spot its return came from (the simulator's
    ``Strip.true_enu``, the reference of every other term here). The point lies along the nominal
    beam at the range of that spot, so it is off it by ρ·δ across the beam (δ the spot's angular
    offset, σ = γ/4 per axis) and by ~ρ·δ²/2 along it. Baltsavias' along-beam spread (ρ·γ/4)·tan α
    (α the incidence) is that same ρ·δ seen from where the nominal beam meets the surface: both give
    (ρ·γ/4)·sin α normal to a plane, so it is not added again (docs/validation.md, "Lines of at
    most 100 characters … fifth session", has the measurement that showed it).
    """
    radius = rho * settings.beam_divergence_rad / 4.0
    across = np.eye(3)[None] - b[:, :, None] * b[:, None, :]
    cov += (radius ** 2)[:, None, None] * across


def calibration_jacobian(sensor: Sensor, calibration: CalibrationCovariance, position, r_eb,
                         range_m, angles) -> np.ndarray:
    """∂p/∂θ_cal (N, k, 3) in the poses' frame: central differences of the lidar equation in each
    calibrated parameter (boresight, lever arm, range, scanner), at the sensor's values."""
    values = sensor.parameters()
    out = np.empty((len(range_m), len(calibration.names), 3))
    for k, (name, unit) in enumerate(zip(calibration.names, calibration.units)):
        h = CALIBRATION_STEPS[unit]
        hi, lo = (sensor.with_parameters(**{name: values[name] + step}) for step in (h, -h))
        p_hi = georef.lidar_points(position, r_eb, hi, range_m, angles)
        p_lo = georef.lidar_points(position, r_eb, lo, range_m, angles)
        out[:, k] = (p_hi - p_lo) / (2 * h)
    return out


def thu_tvu(cov_enu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total horizontal (radial, √(σ_e² + σ_n²)) and vertical 1σ (m) from covariances (N, 3, 3)."""
    return np.sqrt(cov_enu[:, 0, 0] + cov_enu[:, 1, 1]), np.sqrt(cov_enu[:, 2, 2])
