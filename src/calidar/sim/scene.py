"""A synthetic scene in a local ENU frame: terrain, buildings, trees — reproducible from a seed.

Coordinates are metres in the east-north-up frame tangent to the ellipsoid at the origin
(lat0, lon0, h0), so ray casting is exact Cartesian geometry; :meth:`Scene.enu_to_ecef`
takes hits to ECEF.

- Terrain: a height grid with spacing ``cell_m``; each cell is split into two triangles along
  its (0,0)–(1,1) diagonal, which *defines* the surface (so ray hits are exact on it). The
  heights are smooth hills plus a rough band (random node noise) in part of the area.
- Buildings: rectangular footprints with vertical walls and flat, shed, gable or hip roofs
  of random slope and orientation; every roof face and wall is a planar polygon with an id
  (``plane_normal``, ``plane_d``: n·p = d), triangulated for ray casting.
- Trees: spherical crowns on trunks, which return points at random depths following
  Beer–Lambert attenuation (clutter, with a second return from what lies below).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar import frames

CLASS_GROUND, CLASS_VEGETATION, CLASS_BUILDING = 2, 5, 6
ROOF_TYPES = ("flat", "shed", "gable", "hip")


@dataclass(frozen=True)
class SceneSpec:
    """What to build; lengths in m, angles in rad."""

    width_m: float = 300.0  #: east extent
    length_m: float = 300.0  #: north extent
    cell_m: float = 1.0  #: terrain grid spacing (also the ray-casting bin size)
    relief_m: float = 6.0  #: amplitude of the smooth hills
    rough_sigma_m: float = 0.15  #: node noise in the rough band
    building_density_per_km2: float = 400.0
    building_size_m: tuple[float, float] = (8.0, 24.0)  #: footprint side range
    building_height_m: tuple[float, float] = (3.0, 12.0)  #: eave height above ground range
    roof_slope_rad: tuple[float, float] = (np.radians(10.0), np.radians(45.0))
    vegetation_fraction: float = 0.1  #: fraction of the area under tree crowns
    crown_radius_m: tuple[float, float] = (1.5, 4.0)
    extinction_per_m: float = 0.35  #: Beer–Lambert coefficient of a crown


@dataclass(eq=False)
class Scene:
    """Scene geometry in ENU metres; see the module docstring."""

    lat0: float  #: origin latitude, rad
    lon0: float  #: origin longitude, rad
    h0: float  #: origin ellipsoidal height, m
    x0: float  #: east of terrain node (0, 0), m
    y0: float  #: north of terrain node (0, 0), m
    cell_m: float
    heights: np.ndarray  #: terrain node heights (ny + 1, nx + 1), m (up)
    tri: np.ndarray  #: building triangles (M, 3, 3) vertices, m
    tri_plane: np.ndarray  #: plane id of each triangle (M,)
    plane_normal: np.ndarray  #: unit normals (P, 3)
    plane_d: np.ndarray  #: n·p = d, m (P,)
    plane_is_roof: np.ndarray  #: (P,) bool
    plane_building: np.ndarray  #: building index of each plane (P,)
    roof_type: list  #: per building
    tree_center: np.ndarray  #: (K, 3) m
    tree_radius: np.ndarray  #: (K,) m
    extinction_per_m: float
    #: ray-casting acceleration structure (raycast.build_bins)
    bins: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        """Number of terrain cells (ny, nx)."""
        return self.heights.shape[0] - 1, self.heights.shape[1] - 1

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the terrain, m."""
        ny, nx = self.shape
        return self.x0, self.x0 + nx * self.cell_m, self.y0, self.y0 + ny * self.cell_m

    @property
    def origin_ecef(self) -> np.ndarray:
        return frames.geodetic_to_ecef(self.lat0, self.lon0, self.h0)

    @property
    def r_e_enu(self) -> np.ndarray:
        """Rotation ENU (at the origin) → ECEF (3, 3)."""
        return frames.r_en(self.lat0, self.lon0) @ frames.R_ENU_NED

    def enu_to_ecef(self, p_enu) -> np.ndarray:
        """ENU (N, 3) m → ECEF (N, 3) m (exact rigid transform)."""
        return np.asarray(p_enu, float) @ self.r_e_enu.T + self.origin_ecef

    def ecef_to_enu(self, p_ecef) -> np.ndarray:
        """ECEF (N, 3) m → ENU (N, 3) m."""
        return (np.asarray(p_ecef, float) - self.origin_ecef) @ self.r_e_enu

    def terrain_height(self, x, y) -> np.ndarray:
        """Height (m, up) of the triangulated terrain at ENU x, y (m); NaN outside."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        ny, nx = self.shape
        u, v = (x - self.x0) / self.cell_m, (y - self.y0) / self.cell_m
        inside = (u >= 0) & (u <= nx) & (v >= 0) & (v <= ny)
        i = np.clip(np.floor(v).astype(int), 0, ny - 1)
        j = np.clip(np.floor(u).astype(int), 0, nx - 1)
        fx, fy = u - j, v - i
        h = self.heights
        h00, h10, h01, h11 = h[i, j], h[i, j + 1], h[i + 1, j], h[i + 1, j + 1]
        lower = h00 + fx * (h10 - h00) + fy * (h11 - h10)  # triangle (00, 10, 11) where fx >= fy
        upper = h00 + fy * (h01 - h00) + fx * (h11 - h01)  # triangle (00, 11, 01)
        return np.where(inside, np.where(fx >= fy, lower, upper), np.nan)

    def plane_distance(self, p_enu, plane_id) -> np.ndarray:
        """Signed distance (m) of points (N, 3) to the planes with the given ids (N,)."""
        n = self.plane_normal[plane_id]
        return np.einsum("ij,ij->i", np.asarray(p_enu, float), n) - self.plane_d[plane_id]


def _smooth_terrain(rng, x, y, spec: SceneSpec) -> np.ndarray:
    """Smooth hills (sum of random long-wavelength waves) plus a rough band, m."""
    size = max(spec.width_m, spec.length_m)
    z = np.zeros_like(x)
    for k in range(6):
        wavelength = size * rng.uniform(0.4, 1.5) / (1 + k)
        ang = rng.uniform(0, np.pi)
        amp = spec.relief_m * rng.uniform(0.3, 1.0) / (1 + k)
        along = x * np.cos(ang) + y * np.sin(ang)  # m along the wave's direction
        z += amp * np.sin(2 * np.pi * along / wavelength + rng.uniform(0, 2 * np.pi))
    # rough band: the northern third, blended in smoothly
    frac = np.clip((y - y.min()) / max(np.ptp(y), 1e-9), 0, 1)
    weight = np.clip((frac - 0.6) / 0.1, 0, 1)
    return z + weight * rng.normal(0.0, spec.rough_sigma_m, x.shape)


def _roof_faces(kind: str, length: float, width: float, eave: float,
                slope: float) -> list[np.ndarray]:
    """Roof polygons in the building frame (u along length, v along width, z up), m."""
    a, b = length / 2, width / 2
    rise = np.tan(slope)
    if kind == "flat":
        return [np.array([[-a, -b, eave], [a, -b, eave], [a, b, eave], [-a, b, eave]])]
    if kind == "shed":
        hi = eave + width * rise
        return [np.array([[-a, -b, eave], [a, -b, eave], [a, b, hi], [-a, b, hi]])]
    ridge = eave + b * rise
    if kind == "gable":
        return [np.array([[-a, -b, eave], [a, -b, eave], [a, 0, ridge], [-a, 0, ridge]]),
                np.array([[-a, 0, ridge], [a, 0, ridge], [a, b, eave], [-a, b, eave]])]
    r = a - b  # hip (length >= width): ridge of length 2(a - b)
    return [np.array([[-a, -b, eave], [a, -b, eave], [r, 0, ridge], [-r, 0, ridge]]),
            np.array([[a, b, eave], [-a, b, eave], [-r, 0, ridge], [r, 0, ridge]]),
            np.array([[a, -b, eave], [a, b, eave], [r, 0, ridge]]),
            np.array([[-a, b, eave], [-a, -b, eave], [-r, 0, ridge]])]


def _wall_faces(kind: str, length: float, width: float, eave: float, slope: float,
                base: float) -> list[np.ndarray]:
    """Vertical wall polygons (convex) from ``base`` up to the roof edge, building frame, m."""
    a, b = length / 2, width / 2
    rise = np.tan(slope)
    hi = eave + width * rise if kind == "shed" else eave
    walls = [np.array([[-a, -b, base], [a, -b, base], [a, -b, eave], [-a, -b, eave]]),
             np.array([[a, b, base], [-a, b, base], [-a, b, hi], [a, b, hi]])]
    def edge_z(v: float) -> float:
        return eave + (v + b) * rise if kind == "shed" else eave

    for u in (a, -a):
        s = 1.0 if u > 0 else -1.0
        top = [[u, s * b, edge_z(s * b)], [u, -s * b, edge_z(-s * b)]]
        if kind == "gable":
            top.insert(1, [u, 0.0, eave + b * rise])
        walls.append(np.array([[u, -s * b, base], [u, s * b, base]] + top))
    return walls


def scene_seed(seed: int, own: int | None = None) -> int:
    """The seed of a survey's scene: its own (``SurveyConfig.scene_seed``), else drawn from the
    survey seed's scene stream (the first of the six :func:`calidar.sim.survey.simulate_survey`
    spawns)."""
    if own is not None:
        return int(own)
    return int(np.random.default_rng(np.random.SeedSequence(seed).spawn(6)[0]).integers(2**63))


def build_scene(spec: SceneSpec, seed: int, lat0: float, lon0: float, h0: float) -> Scene:
    """Generate a scene from ``spec`` and ``seed`` around the origin (lat0, lon0 rad; h0 m)."""
    from calidar.sim.raycast import build_bins

    rng = np.random.default_rng(seed)
    nx, ny = int(np.ceil(spec.width_m / spec.cell_m)), int(np.ceil(spec.length_m / spec.cell_m))
    x0, y0 = -nx * spec.cell_m / 2, -ny * spec.cell_m / 2
    gx, gy = np.meshgrid(x0 + spec.cell_m * np.arange(nx + 1),
                         y0 + spec.cell_m * np.arange(ny + 1))
    heights = _smooth_terrain(rng, gx, gy, spec)
    scene = Scene(lat0, lon0, h0, x0, y0, spec.cell_m, heights, np.zeros((0, 3, 3)),
                  np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0), np.zeros(0, bool),
                  np.zeros(0, np.int64), [], np.zeros((0, 3)), np.zeros(0), spec.extinction_per_m)
    footprints = _add_buildings(scene, spec, rng)
    _add_trees(scene, spec, rng, footprints)
    scene.bins = build_bins(scene)
    return scene


def _add_buildings(scene: Scene, spec: SceneSpec, rng) -> list[tuple[float, float, float]]:
    """Buildings on a jittered grid, kept inside the terrain and apart from each other: their
    roof and wall triangles into ``scene``; their footprints (x, y, radius, m) returned."""
    x0, y0 = scene.x0, scene.y0
    area_km2 = spec.width_m * spec.length_m / 1e6
    n_build = int(round(spec.building_density_per_km2 * area_km2))
    tris, tri_plane, normals, ds, is_roof, owner, footprints = [], [], [], [], [], [], []
    margin = spec.building_size_m[1]
    for _ in range(n_build * 20):
        if len(footprints) >= n_build:
            break
        length, width = np.sort(rng.uniform(*spec.building_size_m, 2))[::-1]
        cx = rng.uniform(x0 + margin, -x0 - margin)
        cy = rng.uniform(y0 + margin, -y0 - margin)
        radius = np.hypot(length, width) / 2
        if any(np.hypot(cx - fx, cy - fy) < radius + fr + 4.0 for fx, fy, fr in footprints):
            continue
        footprints.append((cx, cy, radius))
        kind = ROOF_TYPES[rng.integers(len(ROOF_TYPES))]
        slope = 0.0 if kind == "flat" else rng.uniform(*spec.roof_slope_rad)
        alpha = rng.uniform(0, 2 * np.pi)
        ca, sa = np.cos(alpha), np.sin(alpha)
        corners = np.array([[u, v] for u in (-length / 2, length / 2)
                            for v in (-width / 2, width / 2)])
        cxy = corners @ np.array([[ca, sa], [-sa, ca]]) + [cx, cy]
        ground = scene.terrain_height(cxy[:, 0], cxy[:, 1])
        base, eave = ground.min() - 0.5, ground.max() + rng.uniform(*spec.building_height_m)
        faces = [(f, True) for f in _roof_faces(kind, length, width, eave, slope)]
        faces += [(f, False) for f in _wall_faces(kind, length, width, eave, slope, base)]
        rot = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
        for poly, roof in faces:
            p = poly @ rot.T + [cx, cy, 0.0]
            n = np.cross(p[1] - p[0], p[2] - p[0])
            n /= np.linalg.norm(n)
            if roof and n[2] < 0:
                n = -n
            pid = len(normals)
            normals.append(n)
            ds.append(float(n @ p[0]))
            is_roof.append(roof)
            owner.append(len(footprints) - 1)
            for k in range(1, len(p) - 1):  # fan triangulation of a convex polygon
                tris.append(np.stack([p[0], p[k], p[k + 1]]))
                tri_plane.append(pid)
        scene.roof_type.append(kind)
    if tris:
        scene.tri = np.array(tris)
        scene.tri_plane = np.array(tri_plane, np.int64)
        scene.plane_normal = np.array(normals)
        scene.plane_d = np.array(ds)
        scene.plane_is_roof = np.array(is_roof)
        scene.plane_building = np.array(owner, np.int64)
    return footprints


def _add_trees(scene: Scene, spec: SceneSpec, rng, footprints: list) -> None:
    """Tree crowns (spheres on trunks) covering about ``vegetation_fraction`` of the area, away
    from the buildings' ``footprints``, into ``scene``."""
    x0, y0 = scene.x0, scene.y0
    r_mean = np.mean(spec.crown_radius_m)
    crown_area = np.pi * r_mean**2
    n_tree = int(round(spec.vegetation_fraction * spec.width_m * spec.length_m / crown_area))
    if not n_tree:
        return
    r = rng.uniform(*spec.crown_radius_m, n_tree)
    tx = rng.uniform(x0 + r, -x0 - r)
    ty = rng.uniform(y0 + r, -y0 - r)
    keep = np.ones(n_tree, bool)
    for fx, fy, fr in footprints:
        keep &= np.hypot(tx - fx, ty - fy) > fr + r + 1.0
    r, tx, ty = r[keep], tx[keep], ty[keep]
    trunk = rng.uniform(1.5, 5.0, r.size)
    # the ground under a crown: the highest of its centre and the corners of its bounding square
    under = [scene.terrain_height(tx + dx, ty + dy) for dx in (-r, r) for dy in (-r, r)]
    ground = np.nanmax(np.stack(under + [scene.terrain_height(tx, ty)]), axis=0)
    scene.tree_center = np.stack([tx, ty, ground + trunk + r], -1)
    scene.tree_radius = r
