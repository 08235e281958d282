"""Strip quality: how well two overlapping strips agree.

Vertical: the swath-overlap difference of the USGS Lidar Base Specification (interswath
relative accuracy): on a grid of ``cell_m`` cells, wherever both strips are smooth (a plane
fits their points within ``max_rms_m``) and gently sloped (< ``max_slope_deg``), the
difference dz = z_a − z_b of the two fitted planes at the cell centre; summarised as
median, RMSDz and max |dz|. Vegetation and edges fail the smoothness test; which points
enter at all is the caller's choice (:mod:`calidar.strips.selection`).

Planimetric: on planar cells of all slopes up to 45°, dz jointly with the difference's offset
and tilt and a horizontal shift (dx, dy) of strip a relative to b, with a cluster-robust σ;
dx, dy only where the slopes constrain both directions, else "not determined"
(:mod:`calidar.strips.planimetric`).

Streamed: :class:`SwathAccumulator` takes each flight line's points chunk by chunk and keeps
only per-cell moments (:mod:`calidar.strips.cell_moments`), on 1 m cells that coarsen exactly
into the whole-metre cell chosen per pair (or on the ``cell_m`` asked for), and occupancy on
the overlap grid; memory grows with the cells, not the points. The planes are the
least-squares (PCA) planes of the cells' points, as if all points were held at once.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calidar.strips.cell_moments import CellMoments, key_indices
from calidar.strips.overlap import common_cells, unpaired_notes
from calidar.strips.planes import PlaneSettings, planar_cells
from calidar.strips.planimetric import (Planimetric, PlanimetricSettings, gradient_noise, gradients,
                                        planimetric_offsets)

#: accumulation grid when the cell is chosen per pair (whole metres coarsen from it)
BASE_CELL_M = 1.0
#: which lines overlap: cells of this size occupied by both (as the strip calibration)
OVERLAP_CELL_M = 5.0
OVERLAP_MIN_POINTS = 3  #: points of a line that make an overlap cell occupied
MERGE_PARTS = 16  #: chunk moments a line holds before they are combined into one
#: cell moments an accumulator with a spill folder holds in memory before they go to disk (per
#: stage) (88 B a cell: a 10⁹-point survey's 2 m cells of three stages would be ≈ 4 GB)
HOLD_BYTES = 64 * 2**20


@dataclass(frozen=True)
class QualitySettings:
    """Swath-difference settings (metres, degrees where named)."""

    cell_m: float | None = None  #: None → 2 m, larger where too sparse for ≈ min_points per cell
    min_points: int = 6
    max_rms_m: float = 0.08  #: smooth surface: point scatter about the cell's plane
    max_slope_deg: float = 10.0  #: vertical statistics on gentler cells only
    min_slope_deg: float = 15.0  #: a cell counts as sloped (planimetric) above this
    planimetric: PlanimetricSettings = PlanimetricSettings()


@dataclass
class PairQuality:
    """Agreement of strips a and b (dz = a − b), metres."""

    a: int
    b: int
    n_cells: int
    median_dz_m: float | None
    rmsdz_m: float | None
    max_abs_dz_m: float | None
    mean_dz_m: float | None
    dx_m: float | None = None  #: planimetric offset of a relative to b (east), when determined
    dy_m: float | None = None
    sigma_dx_m: float | None = None  #: cluster-robust σ (calidar.strips.planimetric)
    sigma_dy_m: float | None = None
    n_sloped: int = 0  #: planar cells sloped more than min_slope_deg
    #: the joint fit (offset, tilt, dx, dy) or why not determined
    planimetric: Planimetric | None = None
    cell_m: float = 2.0
    n_points_a: int = 0  #: points of a in the n_cells compared cells
    n_points_b: int = 0
    #: which points of a were used (PointSelection.to_dict)
    points_a: list[dict] = field(default_factory=list)
    points_b: list[dict] = field(default_factory=list)
    #: (ny, nx) dz, NaN outside, row 0 north
    grid: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    origin: tuple[float, float] = (0.0, 0.0)  #: (west x, north y) of the grid, m

    def to_dict(self) -> dict:
        keys = ("a", "b", "median_dz_m", "rmsdz_m", "max_abs_dz_m", "mean_dz_m", "n_cells",
                "n_points_a", "n_points_b",
                "dx_m", "dy_m", "sigma_dx_m", "sigma_dy_m", "n_sloped", "cell_m", "points_a",
                "points_b")
        out = {k: getattr(self, k) for k in keys}
        out["planimetric"] = None if self.planimetric is None else self.planimetric.to_dict()
        return out


@dataclass(frozen=True)
class OverlapPlan:
    """Which flight lines overlap and the cell (m) each pair's difference uses, with notes about
    lines that overlap no other: decided from point counts on the overlap grid."""

    cells: dict[tuple[int, int], float]
    notes: list[str]

    def sizes(self, line: int) -> set[float]:
        """The cells (m) of the pairs the line is in."""
        return {c for ab, c in self.cells.items() if line in ab}


def overlap_plan(counts: Mapping[int, tuple[np.ndarray, np.ndarray]], overlap_m: float,
                 settings: QualitySettings, names: Mapping[int, str] | None = None) -> OverlapPlan:
    """The plan from each line's (keys, counts) of its selected points on cells of ``overlap_m``:
    pairs sharing cells occupied by both, each with ``settings.cell_m`` or a cell of 2 m, larger
    (whole metres) where the sparser line has under ≈ 1.5 · min_points per cell over the overlap."""
    occupied = {i: k[n >= OVERLAP_MIN_POINTS] for i, (k, n) in counts.items()}
    common = {(a, b): shared for a, b, shared in common_cells(occupied, 4)}
    notes = unpaired_notes(occupied, list(common), overlap_m, 4, names)
    cells = {}
    for ab, shared in common.items():
        area = shared.size * overlap_m**2
        # shared ⊂ each line's sorted keys
        dens = [counts[i][1][np.searchsorted(counts[i][0], shared)].sum() / area for i in ab]
        cells[ab] = float(settings.cell_m) if settings.cell_m else _cell_size(dens, settings)
    return OverlapPlan(cells, notes)


def overlap_cell(cell_m: float | None) -> float:
    """The overlap grid (m): 5 m, or the multiple of ``cell_m`` just above when 5 m is not one."""
    base = float(cell_m) if cell_m else BASE_CELL_M
    ratio = OVERLAP_CELL_M / base
    return OVERLAP_CELL_M if ratio.is_integer() else base * np.ceil(ratio)


class SwathAccumulator:
    """Flight lines' points, chunk by chunk, reduced to what the swath differences need: cell
    moments per line. With a ``plan`` (from counts of a first pass), on the cells of its pairs
    only; without one, on ``cell_m`` (or on 1 m, which coarsens into any whole-metre cell),
    coarsened into the overlap grid to make the plan. Also which selections (PointSelection) the
    points came through."""

    def __init__(self, cell_m: float | None = None, plan: OverlapPlan | None = None,
                 spill_dir: Path | None = None):
        self.cell_m, self.plan = cell_m, plan
        self.spill_dir = None
        if spill_dir is not None:  # its own folder in spill_dir
            self.spill_dir = Path(tempfile.mkdtemp(prefix="lines-", dir=spill_dir))
        self._written = 0  #: files written to spill_dir (their names)
        self.base_m = float(cell_m) if cell_m else BASE_CELL_M
        #: (line, cell m) → moments not yet combined
        self.parts: dict[tuple[int, float], list[CellMoments]] = {}
        #: (line, cell m) → moments written to spill_dir
        self.spilled: dict[tuple[int, float], list[Path]] = {}
        self.selections: dict[int, list[dict]] = {}

    def add(self, line: int, xyz: np.ndarray, selection=None) -> None:
        """Points (N, 3) metric, z up, of flight line ``line`` (after ``selection``, if any)."""
        self._chose(line, [] if selection is None else [selection.to_dict()])
        for cell in (self.plan.sizes(line) if self.plan else {self.base_m}):
            self._put((line, cell), [CellMoments.of_points(xyz, cell)])

    def merge(self, other: "SwathAccumulator") -> "SwathAccumulator":
        """This accumulator with the lines' points of ``other`` (same plan) added: e.g. the
        accumulators of several files."""
        for line, chosen in other.selections.items():
            self._chose(line, chosen)
        for key in {*other.parts, *other.spilled}:
            loaded = [CellMoments.load(f, key[1]) for f in other.spilled.get(key, [])]
            self._put(key, other.parts.get(key, []) + loaded)
        return self

    def _chose(self, line: int, selections: list[dict]) -> None:
        chosen = self.selections.setdefault(line, [])
        chosen += [s for s in selections if s not in chosen]

    def _put(self, key: tuple[int, float], parts: list[CellMoments]) -> None:
        """Moments added to a line's; combined once :data:`MERGE_PARTS` wait (each combine sorts
        the whole line's cells, so combining every chunk would cost chunks × cells); with a
        ``spill_dir``, written there whenever more than :data:`HOLD_BYTES` are held."""
        held = self.parts.setdefault(key, [])
        held += parts
        if len(held) >= MERGE_PARTS:
            self.parts[key] = [CellMoments.combined(held)]
        held = sum(m.nbytes for ms in self.parts.values() for m in ms)
        if self.spill_dir is not None and held > HOLD_BYTES:
            for k, ms in self.parts.items():
                if ms:
                    self._write(k, ms)

    def _write(self, key: tuple[int, float], parts: list[CellMoments]) -> None:
        """A line's moments held in memory, combined, to a file of spill_dir."""
        self._written += 1
        path = self.spill_dir / f"moments_{key[0]}_{key[1]:g}_{self._written}.npy"
        CellMoments.combined(parts).save(path)
        self.spilled.setdefault(key, []).append(path)
        self.parts[key] = []

    def _at(self, line: int, cell: float) -> CellMoments:
        """The line's moments on ``cell``."""
        if (line, cell) in self.parts or (line, cell) in self.spilled or self.plan is not None:
            return self._combined(line, cell)
        f = int(round(cell / self.base_m))
        if not np.isclose(f * self.base_m, cell):
            raise ValueError(f"a {cell} m cell is not a whole number of the {self.base_m} m "
                             "accumulation cells")
        return self._combined(line, self.base_m).coarsened(f)

    def _combined(self, line: int, cell: float) -> CellMoments:
        """The line's parts on ``cell`` combined, and kept so (a line is in several pairs): in
        memory, or as one file of spill_dir when it has spilled."""
        key = (line, cell)
        parts, files = self.parts.get(key, []), self.spilled.get(key, [])
        if files:
            whole = CellMoments.combined([CellMoments.load(f, cell) for f in files] + parts)
            if len(files) + len(parts) > 1:
                for f in files:
                    f.unlink()
                self.spilled[key] = []
                self._write(key, [whole])
            return whole
        if len(parts) > 1:
            self.parts[key] = parts = [CellMoments.combined(parts)]
        return parts[0] if parts else CellMoments.empty(cell)

    def line_moments(self, line: int) -> CellMoments:
        """The line's moments on the smallest cell of its pairs (for checks within one line)."""
        sizes = self.plan.sizes(line) if self.plan else {self.base_m}
        return self._at(line, min(sizes)) if sizes else CellMoments.empty(self.base_m)

    def differences(self, settings: QualitySettings | None = None, threads: int = 1
                    ) -> tuple[list[PairQuality], list[str]]:
        """The PairQuality of every overlapping pair of lines (ids ascending) and notes about lines
        that overlap no other; the pairs computed ``threads`` at a time (each pair on its own: the
        same results however many), once every line's moments are combined here."""
        from calidar.strips.distribute import run_tasks

        s = settings or QualitySettings(cell_m=self.cell_m)
        plan = self.plan
        if plan is None:
            grid = overlap_cell(self.cell_m)
            counts = {i: self._at(i, grid) for i in self.selections}
            plan = overlap_plan({i: (c.keys, c.count) for i, c in counts.items()}, grid, s)
        if any(self.spilled.values()):  # moments on disk: one pair's at a time in memory
            threads, tasks = 1, ((a, cell, b) for (a, b), cell in plan.cells.items())
            pairs = (pair_quality(a, self._at(a, cell), b, self._at(b, cell), s)
                     for a, cell, b in tasks)
        else:  # each line's moments combined here (not in the threads), the pairs in threads
            moments = {(i, cell): self._at(i, cell)
                       for (a, b), cell in plan.cells.items() for i in (a, b)}
            pairs = run_tasks(pair_quality, [(a, moments[a, cell], b, moments[b, cell], s)
                                             for (a, b), cell in plan.cells.items()],
                              threads=threads)
        results = []
        for q in pairs:
            q.points_a, q.points_b = self.selections.get(q.a, []), self.selections.get(q.b, [])
            results.append(q)
        return results, plan.notes


def _cell_size(densities, s: QualitySettings) -> float:
    """2 m, or the whole metres holding ≈ 1.5 · min_points at the sparser density."""
    return float(max(2.0, np.ceil(np.sqrt(1.5 * s.min_points / max(min(densities), 1e-9)))))


def swath_difference(a: int, points_a: np.ndarray, b: int, points_b: np.ndarray,
                     settings: QualitySettings | None = None) -> PairQuality:
    """Vertical and planimetric agreement of two strips' points (each (N, 3), metres, z up) held in
    memory."""
    s = settings or QualitySettings()
    (q,) = swath_differences({a: [points_a], b: [points_b]}, s)[0] or [_no_overlap(a, b, s)]
    return q


def swath_differences(lines: Mapping[int, Iterable[np.ndarray]],
                      settings: QualitySettings | None = None
                      ) -> tuple[list[PairQuality], list[str]]:
    """Swath differences of every overlapping pair of flight lines, each given as an iterable of
    point chunks (N, 3) metric, z up (already selected: :mod:`calidar.strips.selection`)."""
    s = settings or QualitySettings()
    acc = SwathAccumulator(s.cell_m)
    for i, chunks in lines.items():
        for xyz in chunks:
            acc.add(i, xyz)
    return acc.differences(s)


def _no_overlap(a: int, b: int, s: QualitySettings) -> PairQuality:
    return PairQuality(a, b, 0, None, None, None, None, cell_m=s.cell_m or 2.0)


def pair_quality(a: int, moments_a: CellMoments, b: int, moments_b: CellMoments,
                 s: QualitySettings) -> PairQuality:
    """Swath difference of two lines from their cell moments on one grid (the pair's cell)."""
    cell = moments_a.cell_m
    ps = PlaneSettings(min_points=s.min_points, max_rms_m=s.max_rms_m, min_spread=0.15)
    _, ia, ib = np.intersect1d(moments_a.keys, moments_b.keys, assume_unique=True,
                               return_indices=True)
    # planes of the shared cells only
    pa, pb = _planes(moments_a.select(ia), ps), _planes(moments_b.select(ib), ps)
    keys, ia, ib = np.intersect1d(pa[0].keys, pb[0].keys, assume_unique=True, return_indices=True)
    ij = key_indices(keys)
    centre = (ij + 0.5) * cell
    (ma, na), (mb, nb) = (pa[0].select(ia), pa[1][ia]), (pb[0].select(ib), pb[1][ib])
    ca, cb = ma.centroid(), mb.centroid()

    def z_at(c, n):  # height of the plane through c with normal n at the cell centre
        off = centre - c[:, :2]  # the cell centre from the plane's centroid
        return c[:, 2] - (n[:, 0] * off[:, 0] + n[:, 1] * off[:, 1]) / n[:, 2]

    cos_max = np.cos(np.radians(s.max_slope_deg))
    flat = (na[:, 2] >= cos_max) & (nb[:, 2] >= cos_max)
    dz = z_at(ca, na) - z_at(cb, nb)
    q = PairQuality(a, b, int(flat.sum()), None, None, None, None, cell_m=cell,
                    n_points_a=int(ma.count[flat].sum()), n_points_b=int(mb.count[flat].sum()))
    if flat.any():
        d = dz[flat]
        q.median_dz_m, q.rmsdz_m = float(np.median(d)), float(np.sqrt(np.mean(d * d)))
        q.max_abs_dz_m, q.mean_dz_m = float(np.max(np.abs(d))), float(np.mean(d))
        lo, hi = ij[flat].min(axis=0), ij[flat].max(axis=0)
        q.grid = np.full((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), np.nan)
        q.grid[hi[1] - ij[flat, 1], ij[flat, 0] - lo[0]] = d
        q.origin = (float(lo[0] * cell), float((hi[1] + 1) * cell))
    noise = 0.25 * (gradient_noise(ma.covariance(), ma.count, na)
                    + gradient_noise(mb.covariance(), mb.count, nb))
    # a cell one line sees across a fold (a sliver of another face): out
    ga, gb = gradients(na), gradients(nb)
    alike = np.hypot(*(ga - gb).T) <= s.planimetric.max_neighbour_dslope / 2
    _planimetric(q, centre, np.where(alike, dz, np.nan), 0.5 * (ga + gb), noise, s)
    return q


def _planes(m: CellMoments, ps: PlaneSettings) -> tuple[CellMoments, np.ndarray]:
    """The planar cells' moments and their normals (K, 3)."""
    m = m.select(np.flatnonzero(m.count >= max(ps.min_points, 4)))
    planar, normal, _ = planar_cells(m.covariance(), m.cell_m, ps)
    return m.select(planar), normal


def _planimetric(q: PairQuality, centre: np.ndarray, dz: np.ndarray, grad: np.ndarray,
                 noise: np.ndarray, s: QualitySettings) -> None:
    """dx, dy of a relative to b jointly with the difference's offset and tilt, where determined."""
    q.n_sloped = int(np.sum(np.hypot(grad[:, 0], grad[:, 1]) > np.tan(np.radians(s.min_slope_deg))))
    q.planimetric = p = planimetric_offsets(centre, dz, grad, q.cell_m, s.planimetric, noise)
    if p.status == "determined":
        q.dx_m, q.dy_m, q.sigma_dx_m, q.sigma_dy_m = p.dx_m, p.dy_m, p.sigma_dx_m, p.sigma_dy_m
