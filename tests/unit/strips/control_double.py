"""A test double of a kind of ground control (issue 29): surveyed marks given as a JSON file, a kind
that calidar does not have. It is this one module; registering it is the configuration's one change
(its name in :data:`calidar.strips.config.CONTROL_KINDS`). Its rows are control points' (a mark is a
point on the ground), its names, words, file and reader its own."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import numpy as np

from calidar.strips.control import ControlPoints


def read_marks(path) -> SimpleNamespace:
    """The double's file: {"crs": ..., "marks": [{"id", "x", "y", "z", "sigma"}, ...]} (a test file: no checks)."""
    doc = json.loads(Path(path).read_text())
    marks = doc["marks"]
    return SimpleNamespace(path=Path(path), crs=doc.get("crs"), ids=np.array([m["id"] for m in marks]),
                           xyz=np.array([[m["x"], m["y"], m["z"]] for m in marks], float),
                           sigma_m=np.array([m["sigma"] for m in marks], float))


def write_marks(path: Path, ids, xyz, sigma, crs: str | None = None) -> Path:
    marks = [{"id": str(i), "x": float(p[0]), "y": float(p[1]), "z": float(p[2]), "sigma": float(s)}
             for i, p, s in zip(ids, xyz, sigma)]
    Path(path).write_text(json.dumps({"crs": crs, "marks": marks}))
    return Path(path)


@dataclass(frozen=True)
class SurveyedMarks(ControlPoints):
    """Surveyed marks: control points from a JSON file."""

    kind: ClassVar[str] = "marks"
    label: ClassVar[str] = "surveyed marks"
    words: ClassVar[str] = "surveyed marks (the test double)"
    row_noun: ClassVar[str] = "mark"
    dz_meaning: ClassVar[str] = "(dz: the strip's surface minus the mark — the test double's words)"
    how_to_give: ClassVar[str] = "marks: a JSON file of id, x, y, z, sigma"
    reaches_beyond_strips: ClassVar[bool] = False
    accepts: ClassVar = staticmethod(lambda path: Path(path).suffix == ".marks")
    reader: ClassVar = staticmethod(read_marks)
    takes_sigma: ClassVar[bool] = False

    @classmethod
    def from_file(cls, f, local: np.ndarray) -> SurveyedMarks:
        return cls(f.ids, local, f.sigma_m)

    @classmethod
    def notes(cls, f, targets) -> tuple[str, ...]:
        return (f"{len(targets.ids)} surveyed marks read from {f.path.name}",)
