"""The verdict's word on height_bias with ground control (strips/control_verdict.py): the control
sees only the whole common height correction (height_bias + the trajectory knots' mean), so when
that is determined height_bias passes with the reason, and stays as it was when it is not."""

from __future__ import annotations

from calidar.strips.control_verdict import _with_the_whole
from calidar.verdict import Finding


def test_height_bias_passes_with_the_whole_vertical_correction_and_says_why():
    hb = Finding("warn", "height_bias", "+3.9 ± 1.1 cm: not determined", "")
    whole = Finding("pass", "vertical trajectory bias", "+4.1 ± 0.57 cm: determined by 10 ground control points")
    f = _with_the_whole(hb, whole, 0.0057)
    assert f.status == "pass" and "follows the trajectory's priors" in f.detail and "±0.57 cm) is determined" in f.detail
    assert f.detail.startswith("+3.9 ± 1.1 cm: the whole vertical correction") and "not determined" not in f.detail
    not_whole = Finding("warn", "vertical trajectory bias", "not determined beyond its prior")
    assert _with_the_whole(hb, not_whole, 0.02) is hb  # the sum not determined either: unchanged
    other = Finding("warn", "range_offset", "not determined")
    assert _with_the_whole(other, whole, 0.0057) is other
