"""The verdict a reader sees first: is this result good, and why.

A :class:`Verdict` is a list of :class:`Finding` s, each a plain pass / warn / fail with the
numbers behind it and, when it is not a pass, what to do. The overall status is the worst
finding's. Each method builds its own findings (what a strip calibration checks differs from a
range calibration); the report puts the verdict at the top of the page and the CLI prints it.

>>> v = Verdict("boresight roll, pitch, yaw from 18 strip pairs", [
...     Finding("pass", "global test", "σ0 = 1.03 (expected 0.97–1.03 at 95 %)"),
...     Finding("warn", "lever_arm_z", "σ 12 cm: not determined by these strips",
...             "hold it at the measured value or add a flight line at a second height")])
>>> v.status
'warn'
>>> v.to_dict()["findings"][1]["action"]
'hold it at the measured value or add a flight line at a second height'
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

STATUSES = ("pass", "warn", "fail")


@dataclass(frozen=True)
class Finding:
    """One check: its status, what was checked, the numbers, and what to do when it is not a pass."""

    status: str  #: "pass" | "warn" | "fail"
    check: str  #: what was checked, a few words ("global test of σ0", "lever_arm_z")
    detail: str  #: the numbers behind it, in the units people use
    action: str = ""  #: what to do about it (empty for a pass)

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")


@dataclass
class Verdict:
    """What was estimated (one sentence) and the findings; ``status`` is the worst of them."""

    summary: str
    findings: list[Finding] = field(default_factory=list)

    @property
    def status(self) -> str:
        return max((f.status for f in self.findings), key=STATUSES.index, default="pass")

    def headline(self) -> str:
        """One line: PASS / WARN / FAIL and the summary."""
        return f"{self.status.upper()}: {self.summary}"

    def to_dict(self) -> dict:
        return {"status": self.status, "summary": self.summary, "findings": [asdict(f) for f in self.findings]}
