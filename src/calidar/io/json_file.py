"""JSON outputs (solution.json and the like): strict JSON (no NaN or infinity: numpy values made
plain and non-finite values null by :func:`calidar.adjust.solution.json_ready`), written
atomically."""

from __future__ import annotations

import json
from pathlib import Path

from calidar.adjust.solution import json_ready
from calidar.outputs import write_text_atomic


def write_json(path: str | Path, doc: dict, force: bool = True) -> Path:
    """Write ``doc`` as indented strict JSON to ``path`` atomically; returns the path."""
    text = json.dumps(json_ready(doc), indent=2, allow_nan=False) + "\n"
    return write_text_atomic(path, text, force)
