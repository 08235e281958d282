"""Numbers as a reader wants them: fixed decimals, a real minus sign, no "−0.00".

>>> signed(-0.0004, 2), signed(1.5, 1), fixed(-1e-12, 3), fixed(-2.25, 1)
('0.00', '+1.5', '0.000', '−2.2')
"""

from __future__ import annotations

import math


def fixed(v: float | None, decimals: int) -> str:
    """``v`` with ``decimals`` decimals, "−" for negatives, zero unsigned; "—" for None or NaN."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    text = f"{v:.{decimals}f}"
    return text.lstrip("-") if float(text) == 0 else text.replace("-", "−")


def signed(v: float | None, decimals: int) -> str:
    """Like :func:`fixed` with an explicit "+" on positive values (corrections, errors)."""
    text = fixed(v, decimals)
    return text if text in ("—",) or text.startswith("−") or float(text) == 0 else "+" + text
