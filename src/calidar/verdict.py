"""The verdict a reader sees first: is this result good, and why.

A :class:`Verdict` is a list of :class:`Finding` s, each a plain pass / warn / fail with the
numbers behind it and, when it is not a pass, what to do; or a note: something the reader must
know to read the numbers right (σ conservative by a factor, what "determined" means), which is
neither a check passed nor a problem. The overall status is the worst finding's (pass when there
are only notes). Each method builds its own findings (what a strip calibration checks differs from a
range calibration); the report puts the verdict at the top of the page and the CLI prints it.

>>> v = Verdict("boresight roll, pitch, yaw from 18 strip pairs", [
...     Finding("pass", "global test", "σ0 = 1.03 (expected 0.97–1.03 at 95 %)"),
...     Finding("warn", "lever_arm_z", "σ 12 cm: not determined by these strips",
...             "hold it at the measured value or add a flight line at a second height")])
>>> v.status
'warn'
>>> Verdict("a note alone", [Finding("note", "global test", "σ0 = 0.72, below its range")]).status
'pass'
>>> v.to_dict()["findings"][1]["action"]
'hold it at the measured value or add a flight line at a second height'

Numbers in the units people use: angles in degrees with σ also in arc-seconds, lengths in mm.

>>> angle_text(math.radians(0.0302), math.radians(0.00053))
'+0.03020° ± 0.00053° (1.9″)'
>>> length_text(-2e-13, 0.0041), length_text(0.0312, 0.12)
('0.0 mm ± 4.1 mm', '+31.2 mm ± 120 mm')
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

STATUSES = ("pass", "warn", "fail")
NOTE = "note"  #: a finding that informs and does not rate: it never changes the verdict's status


@dataclass(frozen=True)
class Finding:
    """One check: its status, what was checked, the numbers, and what to do when it is not a
    pass."""

    status: str  #: "pass" | "warn" | "fail" | "note"
    check: str  #: what was checked, a few words ("global test of σ0", "lever_arm_z")
    detail: str  #: the numbers behind it, in the units people use
    action: str = ""  #: what to do about it (empty for a pass)

    def __post_init__(self):
        if self.status not in (*STATUSES, NOTE):
            raise ValueError(f"status must be one of {(*STATUSES, NOTE)}, got {self.status!r}")


@dataclass
class Verdict:
    """What was estimated (one sentence) and the findings; ``status`` is the worst of them."""

    summary: str
    findings: list[Finding] = field(default_factory=list)

    @property
    def status(self) -> str:
        rated = [f.status for f in self.findings if f.status != NOTE]
        return max(rated, key=STATUSES.index, default="pass")

    def headline(self) -> str:
        """One line: PASS / WARN / FAIL and the summary."""
        return f"{self.status.upper()}: {self.summary}"

    def to_dict(self) -> dict:
        findings = [asdict(f) for f in self.findings]
        return {"status": self.status, "summary": self.summary, "findings": findings}


def signed(value: float, digits: int) -> str:
    """``value`` with a sign and ``digits`` decimals, never "-0" (rounded zero is shown as 0)."""
    text = f"{value:+.{digits}f}"
    return text[1:] if float(text) == 0 else text


def angle_text(value_rad: float, sigma_rad: float | None = None) -> str:
    """An angle in degrees with its σ in degrees and arc-seconds: "+0.03021° ± 0.00053° (1.9″)"."""
    v = math.degrees(value_rad)
    if sigma_rad is None or not math.isfinite(sigma_rad):
        return f"{signed(v, 5)}°" + ("" if sigma_rad is None else " ± ∞")
    s = math.degrees(sigma_rad)
    # decimals that show σ to two significant digits (2 to 7)
    digits = min(max(2, 1 - math.floor(math.log10(s)) if s > 0 else 5), 7)
    return f"{signed(v, digits)}° ± {s:.{digits}f}° ({two_digits(s * 3600)}″)"


def length_text(value_m: float, sigma_m: float | None = None) -> str:
    """A length in millimetres (metres beyond 10 m): "+31.2 mm ± 4.1 mm"."""
    if abs(value_m) >= 10:
        sigma = "" if sigma_m is None else f" ± {two_digits(sigma_m)} m"
        return f"{signed(value_m, 3)} m{sigma}"
    if sigma_m is None:
        return f"{signed(value_m * 1e3, 1)} mm"
    if not math.isfinite(sigma_m):
        return f"{signed(value_m * 1e3, 1)} mm ± ∞"
    return f"{signed(value_m * 1e3, 1)} mm ± {two_digits(sigma_m * 1e3)} mm"


def two_digits(x: float) -> str:
    """``x`` ≥ 0 to two significant digits, without an exponent: 0.0053, 1.9, 12, 120."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    digits = max(0, 1 - math.floor(math.log10(abs(x))))
    return f"{round(x, digits):.{digits}f}"
