"""Simulated single-photon lidar pass over corner-cube retroreflectors (CCRs), ICESat-2 style.

Model (all SI): shots every ``shot_spacing`` m along a geodesic ground track (10 kHz) from (lat0,
lon0) at ``azimuth_deg`` (WGS84, pyproj's Geod; x is the distance along it, so passes of thousands
of km keep ATL03's along-track distance exact). The reported footprint centre of shot i is (x_i, 0)
in track coordinates (x along, y cross-track, left positive); the true one is (x_i + along_bias +
jitter, cross_bias + jitter). Footprint energy is Gaussian with 1/e² radius w. Ground photons:
Poisson(``ground_photons``) per shot, each from a point drawn from the footprint energy, height =
terrain there (slopes, undulation, roughness) + range noise c·σ_t/2. Solar background:
Poisson(rate·window) per shot, uniform over the telemetry window (``window`` m from 10 m below the
ground). Vegetation: along-track stands of 40 m, each wooded with probability ``canopy_cover``;
under trees a fraction ``canopy_interception`` of the signal photons comes from the crowns (class 3)
at ground + H·√U (U uniform, H the stand's height, 0.6–1 × ``canopy_height``), the rest from the
ground. A CCR at distance r from the true centre returns Poisson(λ0·exp(-2r²/w²)) photons at its
pole height. Detector: ``channels`` channels with dead time t_d (a photon is lost if the previous
photon of the same shot and channel came less than t_d before it).

Truth ``footprint_diameter`` D is the diameter within which a CCR is detected (≥ 1 photon) with
probability ≥ 50 %: λ0·exp(-2(D/2)²/w²) = ln 2
(:func:`calidar.photon.parameters.footprint_radius_1e2`). That is what CCR chords measure. A weak
beam (``strength="weak"``) has 4 detector channels instead of 16; its signal strength is
``ground_photons`` (ICESat-2's weak beams carry a quarter of a strong beam's energy: give a
quarter). Each photon's truth is in ``SimulatedPass.photon_class`` and, in the written file, the
extra dataset ``<beam>/heights/sim_class_ph`` (0 background, 1 ground, 2 CCR, 3 canopy).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from calidar.io.atl03 import CHANNELS, SURFACE_TYPES, PhotonBeam, segment_photons, write_atl03
from calidar.outputs import atomic_path, write_text_atomic
from calidar.photon.parameters import C_LIGHT, GEOLOCATION, footprint_radius_1e2
ATLAS_EPOCH_OFFSET = 2.5e7  #: s, delta_time of the first shot (about Oct 2018)


@dataclass(frozen=True)
class PhotonSimConfig:
    """Settings of a simulated pass. Distances m, times s, angles rad, rates Hz."""

    seed: int = 0
    beam: str = "gt1l"
    length: float = 1200.0  #: m of track simulated
    shot_spacing: float = 0.7  #: m between footprints (7 km/s ground speed / 10 kHz)
    prf: float = 10_000.0  #: Hz
    footprint_diameter: float = 11.0  #: m, 50 % CCR-detection diameter (truth)
    along_bias: float | None = None  #: m; None = drawn in ±3 m
    cross_bias: float | None = None  #: m; None = drawn in ±3 m
    jitter: float = 0.3  #: m, per-shot pointing jitter σ (each axis)
    ground_photons: float = 3.0  #: mean signal photons per shot from the ground
    background_rate: float = 3.0e6  #: Hz, solar background photon rate
    window: float = 30.0  #: m, telemetry height window (from 10 m below ground)
    dead_time: float = 3.2e-9  #: s
    pulse_width: float = 1.0e-9  #: s, RMS
    strength: str = "strong"  #: "strong" (16 detector channels) or "weak" (4)
    spot: int | None = None  #: ATLAS laser spot written to the file (None: not written)
    slope_along: float = 0.02  #: terrain slope along track (m/m)
    slope_cross: float = 0.01  #: terrain slope across track (m/m)
    undulation: float = 2.0  #: m, amplitude of a terrain undulation (hills)
    undulation_wavelength: float = 300.0  #: m
    canopy_cover: float = 0.0  #: fraction of the track's 40 m stands that are wooded
    canopy_height: float = 15.0  #: m, the tallest stands' height
    canopy_interception: float = 0.5  #: fraction of the signal photons from the crowns under trees
    roughness: float = 0.05  #: m, RMS surface roughness
    n_ccr: int = 5  #: CCRs inside the footprints' reach
    n_unlit: int = 0  #: extra CCRs placed out of the footprints' reach (no returns)
    ccr_photons: float = 20.0  #: mean photons from a CCR at the footprint centre
    ccr_dropout: float = 0.0  #: fraction of shots whose CCR photons are all lost
    ccr_spacing: float = 60.0  #: m along track between CCRs
    lat0_deg: float = 32.4  #: start of the track (a desert CCR site)
    lon0_deg: float = -106.4
    azimuth_deg: float = -13.0  #: track direction at the start (clockwise from north)

    @property
    def w(self) -> float:
        """1/e² radius of the footprint energy (m) for the 50 %-detection diameter."""
        return float(footprint_radius_1e2(self.footprint_diameter, self.ccr_photons))

    @property
    def channels(self) -> int:
        return CHANNELS[self.strength]


@dataclass
class SimulatedPass:
    """A simulated pass: the ATL03 beam, the CCR survey (track and geodetic) and the truth."""

    beam: PhotonBeam
    ccr_id: list[str]
    ccr_x: np.ndarray  #: m along track
    ccr_y: np.ndarray  #: m cross track (left positive)
    ccr_lat: np.ndarray  #: rad
    ccr_lon: np.ndarray  #: rad
    ccr_height: np.ndarray  #: m above ground
    truth: dict
    photon_class: np.ndarray  #: 0 background, 1 ground, 2 CCR, 3 canopy

    @property
    def signal(self) -> np.ndarray:
        """True where the photon is signal (ground, CCR or canopy), False for the solar
        background."""
        return self.photon_class > 0


def _terrain(cfg: PhotonSimConfig, x, y):
    """Terrain height (m) at track coordinates x, y (m): the along-track slope at the start bends
    over 5 km (±100 m at the default slope, so long passes stay on Earth), a cross slope and an
    undulation (``undulation`` m, ``undulation_wavelength`` m)."""
    return (1200.0 + cfg.slope_along * 5000.0 * np.sin(np.asarray(x) / 5000.0) + cfg.slope_cross * y
            + cfg.undulation * np.sin(2 * np.pi * x / cfg.undulation_wavelength))


CANOPY_STAND = 40.0  #: m, along-track length of a stand of trees (wooded or open)


def _canopy(cfg: PhotonSimConfig, x: np.ndarray, h: np.ndarray, cls: np.ndarray) -> None:
    """Turn ground photons under trees into crown returns in place (class 3, height raised).

    Drawn from a generator of its own, so a pass without trees is the same as before they
    existed."""
    if cfg.canopy_cover <= 0.0:
        return
    rng = np.random.default_rng([cfg.seed, 3])
    n_stand = int(np.ceil((np.max(x, initial=0.0) + 50.0) / CANOPY_STAND)) + 1
    wooded = rng.random(n_stand) < cfg.canopy_cover
    height = cfg.canopy_height * rng.uniform(0.6, 1.0, n_stand)
    stand = np.clip(((x + 25.0) // CANOPY_STAND).astype(np.int64), 0, n_stand - 1)
    crown = (cls == 1) & wooded[stand] & (rng.random(x.size) < cfg.canopy_interception)
    h[crown] += height[stand[crown]] * np.sqrt(rng.random(int(crown.sum())))
    cls[crown] = 3


def _geodesic(cfg: PhotonSimConfig, x: np.ndarray,
              y: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Geodetic lat, lon (rad) of track coordinates x (m along the geodesic from the start) and y
    (m to its left). With y (CCRs): exact (pyproj Geod), the point on the track then the
    perpendicular offset. Without (shots on the track): exact at knots every 100 m, linear
    between them (≤ 0.2 mm off), so millions of shots cost little."""
    from pyproj import Geod

    geod = Geod(ellps="WGS84")
    x = np.asarray(x, float)

    def start(n: int):
        return np.full(n, cfg.lon0_deg), np.full(n, cfg.lat0_deg), np.full(n, cfg.azimuth_deg)

    if y is not None:
        lon, lat, back = geod.fwd(*start(x.size), x)
        left = np.asarray(back) + 90.0  # back azimuth + 180° − 90°: to the left of the track
        lon, lat, _ = geod.fwd(lon, lat, left, np.asarray(y, float))
        return np.radians(lat), np.radians(lon)
    knots = np.arange(np.floor(x.min() / 100.0) - 1, np.ceil(x.max() / 100.0) + 2) * 100.0
    lon, lat, _ = geod.fwd(*start(knots.size), knots)
    return np.radians(np.interp(x, knots, lat)), np.interp(x, knots, np.unwrap(np.radians(lon)))


def _ccr_layout(cfg: PhotonSimConfig, rng, along_bias, cross_bias):
    """CCRs spread across the true footprint track (distinct pole heights, cross-track offsets)."""
    r = 0.5 * cfg.footprint_diameter
    n = cfg.n_ccr + cfg.n_unlit
    x = 0.5 * cfg.length - 0.5 * cfg.ccr_spacing * (n - 1) + cfg.ccr_spacing * np.arange(n)
    x = x + rng.uniform(-0.3, 0.3, n) * cfg.shot_spacing
    # lit CCRs: evenly spread offsets within ±0.7 R of the true track, shuffled
    u = np.linspace(-0.7, 0.7, cfg.n_ccr) if cfg.n_ccr > 1 else np.array([0.3])
    y = cross_bias + r * rng.permutation(u + rng.uniform(-0.05, 0.05, cfg.n_ccr))
    # unlit CCRs: beyond the footprint on either side
    side = rng.choice([-1, 1], cfg.n_unlit)
    y_unlit = cross_bias + side * (2.0 * r + rng.uniform(1, 4, cfg.n_unlit))
    y = np.concatenate([y, y_unlit])
    heights = 1.5 + 0.5 * rng.permutation(n)
    return x, y, heights


def simulate_pass(cfg: PhotonSimConfig) -> SimulatedPass:
    """Simulate one pass (see the module docstring for the model)."""
    rng = np.random.default_rng(cfg.seed)
    along_bias = rng.uniform(-3, 3) if cfg.along_bias is None else cfg.along_bias
    cross_bias = rng.uniform(-3, 3) if cfg.cross_bias is None else cfg.cross_bias
    n_shots = int(cfg.length / cfg.shot_spacing)
    xs = cfg.shot_spacing * np.arange(n_shots)
    tx = xs + along_bias + rng.normal(0, cfg.jitter, n_shots)  # true footprint centres
    ty = cross_bias + rng.normal(0, cfg.jitter, n_shots)
    range_sigma = 0.5 * C_LIGHT * cfg.pulse_width
    sg, hg, cls_g = _ground_photons(cfg, rng, tx, ty, range_sigma)
    # solar background, uniform over the telemetry window around the reported ground
    nb = rng.poisson(cfg.background_rate * 2 * cfg.window / C_LIGHT, n_shots)
    sb = np.repeat(np.arange(n_shots), nb)
    hb = _terrain(cfg, xs[sb], 0.0) - 10.0 + rng.uniform(0, cfg.window, sb.size)
    cx, cy, ch = _ccr_layout(cfg, rng, along_bias, cross_bias)
    sc, hc = _ccr_photons(cfg, rng, xs, tx, ty, (cx, cy, ch), along_bias, range_sigma)

    shot = np.concatenate([sg, sb, sc])
    h = np.concatenate([hg, hb, hc])
    cls = np.concatenate([cls_g, np.zeros(sb.size, np.int8), np.full(sc.size, 2, np.int8)])
    shot, h, cls = _detect(cfg, rng, shot, h, cls)

    beam = _atl03_beam(cfg, xs, shot, h, cls)
    clat, clon = _geodesic(cfg, cx, cy)
    geolocation = map(float, (along_bias, cross_bias, cfg.footprint_diameter))
    truth = {
        **dict(zip(GEOLOCATION, geolocation)),
        "units": "m",
        "conventions": CONVENTIONS,
        "ccr_lit": [bool(i < cfg.n_ccr) for i in range(cx.size)],
        "ccr_x": cx.tolist(), "ccr_y": cy.tolist(),
        "config": asdict(cfg),
    }
    ids = [f"CCR{k + 1:02d}" for k in range(cx.size)]
    return SimulatedPass(beam, ids, cx, cy, clat, clon, ch, truth, cls)


CONVENTIONS = ("true footprint = reported + bias; along-track positive in the direction of travel, "
               "cross-track positive to the left of it; footprint_diameter = 50 % CCR-detection "
               "diameter")


def _ground_photons(cfg: PhotonSimConfig, rng, tx: np.ndarray, ty: np.ndarray,
                    range_sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ground (and canopy) photons of every shot at true footprint centres (tx, ty): their shots,
    heights (m) and classes."""
    n_shots = tx.size
    sig_fp = 0.5 * cfg.w  # Gaussian σ of the energy (1/e² radius = 2σ)
    ng = rng.poisson(cfg.ground_photons, n_shots)
    sg = np.repeat(np.arange(n_shots), ng)
    px = tx[sg] + rng.normal(0, sig_fp, sg.size)
    py = ty[sg] + rng.normal(0, sig_fp, sg.size)
    hg = _terrain(cfg, px, py) + rng.normal(0, cfg.roughness, sg.size)
    hg = hg + rng.normal(0, range_sigma, sg.size)
    cls_g = np.ones(sg.size, np.int8)
    _canopy(cfg, px, hg, cls_g)
    return sg, hg, cls_g


def _ccr_photons(cfg: PhotonSimConfig, rng, xs: np.ndarray, tx: np.ndarray, ty: np.ndarray,
                 ccrs: tuple, along_bias: float,
                 range_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """The CCRs' photons: the shots whose Gaussian footprint reaches each CCR (x, y, height) and
    the photons' heights (m)."""
    cx, cy, ch = ccrs
    sc_list, hc_list = [], []
    for k in range(cx.size):
        lo_x = cx[k] - along_bias - 3 * cfg.w - 5 * cfg.jitter
        hi_x = cx[k] - along_bias + 3 * cfg.w + 5 * cfg.jitter
        lo, hi = np.searchsorted(xs, [lo_x, hi_x])
        near = np.arange(lo, hi)
        r2 = (tx[near] - cx[k]) ** 2 + (ty[near] - cy[k]) ** 2
        nk = rng.poisson(cfg.ccr_photons * np.exp(-2 * r2 / cfg.w**2))
        nk[rng.random(near.size) < cfg.ccr_dropout] = 0  # lost shots take all their CCR photons
        sk = np.repeat(near, nk)
        sc_list.append(sk)
        hc_list.append(_terrain(cfg, cx[k], cy[k]) + ch[k] + rng.normal(0, range_sigma, sk.size))
    return np.concatenate(sc_list), np.concatenate(hc_list)


def _detect(cfg: PhotonSimConfig, rng, shot: np.ndarray, h: np.ndarray, cls: np.ndarray):
    """The detector: a random channel per photon, dead time within (shot, channel); the photons
    left, a shot's in arrival order (descending height)."""
    chan = rng.integers(0, cfg.channels, shot.size)
    order = np.lexsort((-h, chan, shot))
    shot, h, cls, chan = shot[order], h[order], cls[order], chan[order]
    t_arr = -2.0 * h / C_LIGHT
    same = (shot[1:] == shot[:-1]) & (chan[1:] == chan[:-1])
    dead = np.concatenate([[False], same & (t_arr[1:] - t_arr[:-1] < cfg.dead_time)])
    shot, h, cls = shot[~dead], h[~dead], cls[~dead]
    order = np.lexsort((-h, shot))  # photons of a shot in arrival order
    return shot[order], h[order], cls[order]


def _atl03_beam(cfg: PhotonSimConfig, xs: np.ndarray, shot: np.ndarray, h: np.ndarray,
                cls: np.ndarray) -> PhotonBeam:
    """The photons as an ATL03 beam: positions at their shot's reported footprint, 20 m segments
    with their reference (centre) times, ATL03-style confidence (4 for ground/CCR, 0 background)."""
    x = xs[shot]
    slat, slon = _geodesic(cfg, xs)
    seg_id, beg, cnt, dist_x, along = segment_photons(x, 20.0, first_id=100_000)
    conf = np.full((x.size, len(SURFACE_TYPES)), -1, np.int8)
    conf[:, 0] = np.where(cls > 0, 4, 0)
    segment_time = ATLAS_EPOCH_OFFSET + (dist_x + 10.0) / cfg.shot_spacing / cfg.prf
    return PhotonBeam(
        beam=cfg.beam, delta_time=ATLAS_EPOCH_OFFSET + shot / cfg.prf, lat=slat[shot],
        lon=slon[shot], h=h, dist_along=along, dist_across=np.zeros_like(x), signal_conf=conf,
        quality=np.zeros(x.size, np.int8), segment_id=seg_id, ph_index_beg=beg,
        segment_ph_cnt=cnt, segment_dist_x=dist_x, segment_time=segment_time,
        strength=cfg.strength, spot=cfg.spot, along_track=x, along_track_source="segments",
    )


def write_ccr_csv(path: str | Path, ids, lat_rad, lon_rad, height_m, force: bool = True) -> Path:
    """CCR survey file: ``id,lat,lon,height`` (degrees, degrees, metres above ground)."""
    lines = ["id,lat,lon,height"] + [
        f"{i},{np.degrees(a):.9f},{np.degrees(o):.9f},{hh:.3f}"
        for i, a, o, hh in zip(ids, lat_rad, lon_rad, height_m)
    ]
    return write_text_atomic(path, "\n".join(lines) + "\n", force)


def write_pass(sim: SimulatedPass, out_dir: Path, stem: str = "ATL03_sim") -> dict[str, Path]:
    """Write ``<stem>.h5``, ``ccr.csv`` and ``truth.json`` into ``out_dir`` (already prepared)."""
    out_dir = Path(out_dir)
    h5 = out_dir / f"{stem}.h5"
    with atomic_path(h5) as tmp:
        write_atl03(tmp, [sim.beam])
        import h5py

        with h5py.File(tmp, "a") as f:  # the truth of each photon, beside ATL03's own fields
            heights = f[sim.beam.beam]["heights"]
            classes = heights.create_dataset("sim_class_ph", data=sim.photon_class.astype(np.int8))
            meaning = "simulation truth: 0 solar background, 1 ground, 2 CCR, 3 canopy"
            classes.attrs["description"] = meaning
    ccr = write_ccr_csv(out_dir / "ccr.csv", sim.ccr_id, sim.ccr_lat, sim.ccr_lon, sim.ccr_height)
    truth = write_text_atomic(out_dir / "truth.json", json.dumps(sim.truth, indent=2) + "\n")
    return {"atl03": h5, "ccr": ccr, "truth": truth}
