"""The overlap quality of flight lines streamed from their files, as delivered and
re-georeferenced (the boresight report's stages), in one more read of the files.

``calidar quality`` first counts the selected points of each line on the 5 m overlap grid
(which lines overlap, each pair's cell: :func:`calidar.strips.quality.overlap_plan`), then
accumulates cell moments on the plan's cells. Here the counts come from the strip ingest's
first pass, which reads every point anyway (:class:`LineCounts`), so one read gives every
stage (:func:`stage_pass`): per chunk and line, the selected points of each stage go to that
stage's :class:`~calidar.strips.quality.SwathAccumulator` on the delivered plan, and each
stage's own counts are kept (as delivered in full; re-georeferenced as the points whose 5 m
cell changed). A stage whose own plan differs from the one it was measured on (a pair at the
edge of overlapping, a density at a cell-size step, a grid the ingest did not share) is read
once more on its own plan (:func:`lines_quality`), so every stage is what ``calidar
quality`` gives on its files. The caller reads each file as one task; only cell moments and
counts come back.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from calidar.errors import InputError
from calidar.strips.overlap import cell_counts, cell_keys, merge_counts
from calidar.strips.quality import (OverlapPlan, QualitySettings, SwathAccumulator, overlap_cell,
                                    overlap_plan)
from calidar.strips.selection import GROUND, PointSelection, choose_selection

#: the default rules, counted for every line before its classes decide between them
RULES = (PointSelection("ground", (GROUND,)), PointSelection("last returns"))


@dataclass
class LineCounts:
    """Per flight line (or group of points), how many points each default rule keeps in each
    cell of the overlap grid, and the LAS classes present: what a plan is made of."""

    grid_m: float
    counts: dict = field(default_factory=dict)  #: (line, rule) → (sorted cell keys, counts)
    present: dict = field(default_factory=dict)  #: line → set of LAS classes

    def add(self, line: int, points, keys: np.ndarray) -> None:
        """``points`` of one line (anything with the selection fields) in grid cells ``keys``."""
        if points.classification is not None:
            self.present.setdefault(line, set()).update(np.unique(points.classification).tolist())
        for rule in RULES:
            # (no classes: last returns only)
            if rule.classes is None or points.classification is not None:
                self._put((line, rule), cell_counts(keys[rule.mask(points)]))

    def merge(self, other: "LineCounts", line_of: Callable[[int], int] = int) -> "LineCounts":
        """``other``'s counts added to these, its ids mapped by ``line_of`` (e.g. groups →
        lines)."""
        for (i, rule), kn in other.counts.items():
            self._put((line_of(i), rule), kn)
        for i, classes in other.present.items():
            self.present.setdefault(line_of(i), set()).update(classes)
        return self

    def _put(self, key, kn) -> None:
        self.counts[key] = merge_counts(self.counts[key], kn) if key in self.counts else kn

    def chosen(self, names: Mapping[int, str]) -> dict[int, PointSelection]:
        """The selection of each line from the classes it holds (ground, else last returns)."""
        lines = sorted({i for i, _ in self.counts})

        def classes(i):
            return np.array(sorted(self.present[i])) if i in self.present else None

        return {i: choose_selection(names.get(i), classes(i)) for i in lines}

    def of(self, chosen: Mapping[int, PointSelection]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """(keys, counts) per line of the points its chosen selection keeps."""
        return {i: self.counts[i, s] for i, s in chosen.items() if (i, s) in self.counts}


@dataclass
class StagePass:
    """What one read of the lines gives, per stage: its accumulator (None: not measured in this
    read) and its counts per line (stage 0's chosen points; later stages' changes from them)."""

    accs: list
    counts: list

    @classmethod
    def start(cls, plans: list[OverlapPlan | None], cell_m: float | None = None, count: bool = True,
              spill_dir=None) -> "StagePass":
        """Nothing read yet: an accumulator per planned stage (spilling to ``spill_dir``, if
        given)."""
        return cls([None if p is None else SwathAccumulator(cell_m, p, spill_dir) for p in plans],
                   [{} for _ in plans] if count else [])

    def merge(self, other: "StagePass") -> "StagePass":
        """Both reads' points together (e.g. two files)."""
        for acc, more in zip(self.accs, other.accs):
            if acc is not None:
                acc.merge(more)
        for mine, theirs in zip(self.counts, other.counts):
            for i, kn in theirs.items():
                mine[i] = merge_counts(mine[i], kn) if i in mine else kn
        return self


def chosen_points(chosen: Mapping[int, PointSelection]) -> Callable:
    """``select(chunk, line ids)`` of :func:`calidar.ingest.source.line_chunks`: the mask of the
    points each line's ``chosen`` selection keeps (a line without one: none), the rows
    :func:`stage_pass` reads of a chunk's versions: the others are not re-georeferenced."""
    def select(chunk, ids: np.ndarray) -> np.ndarray:
        one = ids.size and ids[0] == ids[-1] and np.all(ids == ids[0])
        lines = [int(ids[0])] if one else np.unique(ids).tolist()
        rules: dict = {}
        for i in lines:
            if chosen.get(i) is not None:
                rules.setdefault(chosen[i], []).append(i)
        mask = np.zeros(ids.size, bool)
        for sel, mine in rules.items():
            keep = sel.mask(chunk)
            mask |= keep if len(mine) == len(lines) else keep & np.isin(ids, mine)
        return mask
    return select


def stage_pass(chunks: Iterable[tuple[int, list]], metric, plans: list[OverlapPlan | None],
               chosen: Mapping[int, PointSelection], cell_m: float | None = None,
               count: bool = True) -> StagePass:
    """One read of ``chunks`` (line id, [LasPoints per stage]): stage k's cell moments on
    ``plans[k]`` (None: not measured) of each line's ``chosen`` points in ``metric``
    coordinates; with ``count``, stage 0's counts on the overlap grid and, for later stages, the
    changes from stage 0 (the points whose cell moved: +1 where they are, −1 where they were)."""
    grid = overlap_cell(cell_m)
    out = StagePass.start(plans, cell_m, count)
    for i, versions in chunks:
        sel = chosen.get(i)
        if sel is None:  # a line without any selected point in the counts
            continue
        keep = sel.mask(versions[0])
        if keep.all():  # every point (as usual): the versions' own arrays, no copies
            xyz = [metric.of(v.xyz) for v in versions]
        else:
            rows = np.flatnonzero(keep)
            xyz = [metric.of(v.xyz.take(rows, axis=0)) for v in versions]  # (v.xyz[mask], faster)
        for acc, x in zip(out.accs, xyz):
            if acc is not None:
                acc.add(i, x, sel)
        if count:
            keys = [cell_keys(x, grid) for x in xyz]
            parts = [[cell_counts(keys[0])]]
            for k in keys[1:]:
                moved = k != keys[0]
                gone = cell_counts(keys[0][moved])
                parts.append([cell_counts(k[moved]), (gone[0], -gone[1])])
            for counts, kns in zip(out.counts, parts):
                counts[i] = merge_counts(*([counts[i]] if i in counts else []), *kns)
    return out


def lines_quality(read: Callable[[list, dict, bool], StagePass], first: LineCounts, n_stages: int,
                  names: Mapping[int, str] | None = None,
                  settings: QualitySettings = QualitySettings(), threads: int = 1) -> list[list]:
    """Per stage, the PairQuality of every overlapping pair of lines: ``read(plans, chosen,
    count)`` streams every line through :func:`stage_pass`; ``first`` holds stage 0's counts
    (which decide the plan every stage is measured on first). Stages whose own plan differs are
    read again on it. The stages' differences are computed ``threads`` at a time (with
    threads > 1, all at once when no moments went to disk: they are small then)."""
    from calidar.strips.distribute import run_tasks

    names = names or {}
    chosen = first.chosen(names)
    used = [overlap_plan(first.of(chosen), first.grid_m, settings, names)] * n_stages
    got = read(used, chosen, True)
    base = got.counts[0]
    own = [base] + [{i: merge_counts(*([base[i]] if i in base else []), *([d[i]] if i in d else []))
                     for i in {*base, *d}} for d in got.counts[1:]]
    plans = [overlap_plan(c, overlap_cell(settings.cell_m), settings, names) for c in own]
    redo = [p if p != u else None for p, u in zip(plans, used)]
    again = read(redo, chosen, False) if any(p is not None for p in redo) else None
    accs = [again.accs[k] if redo[k] is not None else acc for k, acc in enumerate(got.accs)]
    for acc in accs:
        for i in chosen:  # lines without a selected point: named in the notes
            acc.add(i, np.zeros((0, 3)))
    spilled = any(a.spill_dir is not None and any(a.spilled.values()) for a in accs)
    # all at once when the moments are in memory and threads are allowed
    at_once = max(threads, len(accs)) if threads > 1 and not spilled else threads
    tasks = [(a, settings, names) for a in accs]
    return [r[0] for r in run_tasks(checked_differences, tasks, threads=at_once)]


def checked_differences(acc, settings, names: dict[int, str], threads: int = 1):
    """The accumulator's pairs and notes (``threads`` pairs at a time); an error when no line
    overlaps another (lines named by ``names`` {id: file name})."""
    from calidar.strips.overlap import strip_name

    results, notes = acc.differences(settings, threads)
    if not results:
        listed = ", ".join(strip_name(i, names) for i in sorted(acc.selections))
        n = len(acc.selections)
        if settings.cell_m is not None:
            raise InputError(None, "--cell", f"no {settings.cell_m:g} m cell holds points of two "
                             f"of the {n} flight lines ({listed}); expected a larger cell (or "
                             "leave --cell out to have one chosen), unless the lines do not "
                             "overlap")
        raise InputError(None, "STRIPS", f"none of the {n} flight lines ({listed}) overlap "
                         "another; nothing to compare")
    empty = [f"{q.a}–{q.b}" for q in results if q.n_cells == 0]
    if empty and settings.cell_m is not None:
        cell = f"{settings.cell_m:g} m cell"
        if len(empty) == len(results):
            raise InputError(None, "--cell", f"no {cell} of any overlap is smooth and holds "
                             "enough points of both lines; expected a larger cell, to hold more "
                             "points (or leave --cell out to have one chosen)")
        notes.append(f"pairs {', '.join(empty)}: no {cell} is smooth and holds enough points of "
                     "both lines (a larger --cell holds more points; a smaller one is smoother on "
                     "rough ground)")
    return results, notes
