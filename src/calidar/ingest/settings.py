"""How the streaming engine reads strips: one :class:`IngestSettings`, built at the edge (the
CLI's options or a configuration file: :class:`calidar.pipelines.strip_config.StripConfig`) and
handed to :class:`calidar.ingest.strips.StripIngest` whole."""

from __future__ import annotations

from dataclasses import dataclass, field

from calidar.io.las import PointOptions
from calidar.strips.lines import GAP_S
from calidar.strips.selection import excluded_words

#: points kept per strip by default: enough for the tie planes and VGICP on the test surveys
#: (results within σ of every overlapping point), small enough for bounded memory
BUDGET_POINTS = 300_000
MIN_BUDGET_POINTS = 10_000  #: fewer leave too few tie planes per pair to be worth a run
BIN_BITS = 40  #: group key = point_source_id << 40 | GPS time bin
#: kept blocks span this many tie-plane patches (of ≈ PlaneSettings.target_points points) across
BLOCK_PATCHES = 6
MAX_BLOCK_CELLS = 20

#: points read at once: with the overlap-quality stages' copies (a chunk re-georeferenced per
#: stage) this, not the files, sets the streaming memory (docs/validation.md has the peaks measured)
CHUNK_POINTS = 250_000
#: pass 1 keeps what pass 2 and the overlap-quality stages need of each point (stored coordinates,
#: time, point_source_id, the selection's fields: 25 B a point) in files of a temporary folder
#: (:class:`calidar.ingest.held.HeldFiles`) when it runs in this process, so that no
#: point is decompressed twice: files in file order while they fit in this and in half the folder's
#: free space; the others are read again. Memory holds a chunk; 0 turns it off.
HOLD_POINTS_BYTES = 64 * 2**30
HELD_BYTES_PER_POINT = 25


@dataclass(frozen=True)
class IngestSettings:
    """How strips are read: ``budget_points`` kept per strip (None: every overlapping point),
    ``chunk_points`` per read, ``points`` (the shared --crs/--time-system/--geoid-undulation),
    ``gap_s`` (a pause in GPS time that starts a flight line when point_source_id does not
    tell them apart), the overlap grid (``cell_m``, ``min_cells``, ``min_points_per_cell``
    as :func:`calidar.strips.overlap.find_overlaps`) and the side of the square blocks kept
    whole (``block_cells`` overlap cells; None: :data:`BLOCK_PATCHES` tie-plane patches at the
    survey's density, at most :data:`MAX_BLOCK_CELLS`), and whether the calibration's points
    keep every LAS class (``all_classes``; default False: the points of
    :data:`calidar.strips.selection.EXCLUDED_CLASSES`, vegetation 3–5, noise 7/18 and water 9,
    are neither counted in the budget nor kept — an unclassified file loses none)."""

    budget_points: int | None = BUDGET_POINTS
    block_cells: int | None = None
    chunk_points: int = CHUNK_POINTS
    points: PointOptions = field(default_factory=PointOptions)
    gap_s: float = GAP_S
    cell_m: float = 5.0
    min_cells: int = 4
    min_points_per_cell: int = 3
    hold_bytes: int = HOLD_POINTS_BYTES  #: see :data:`HOLD_POINTS_BYTES`
    all_classes: bool = False

    def classes_text(self) -> str:
        """Which LAS classes the calibration's points are of, for the report."""
        if self.all_classes:
            return "every LAS class (--all-classes)"
        return (f"every LAS class but {excluded_words()} "
                "(of classified files; --all-classes keeps them)")
