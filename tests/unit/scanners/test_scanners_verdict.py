"""The structural-error verdict: which errors break the pointing spec and by how much, which are
not separable from the boresight; the files and the report section of an analysis."""

import json

import numpy as np
import pytest

from calidar.report import Report
from calidar.scanners.analysis import analyze, pattern_angles
from calidar.pipelines.scanner_files import separability_summary, write_curves
from calidar.scanners.report import add_section
from calidar.scanners.separability import separability
from calidar.scanners.settings import AnalysisSettings
from calidar.scanners.sources import error_sources
from calidar.scanners.verdict import analysis_verdict


def _run(model, errors, **kw):
    a = analyze(AnalysisSettings(model, 500.0, errors, **kw))
    sep = separability(a.scanner, error_sources(a.model), pattern_angles(a.scanner, 360, np.radians(a.settings.fov_deg)),
                       a.range_m)
    return a, sep, analysis_verdict(a, sep)


def _by_check(v):
    return {f.check: f for f in v.findings}


def test_published_palmer_example_breaks_a_10_arcsec_spec_by_the_right_factors():
    a, _, v = _run("palmer", {"eccentricity": 15e-6 / 0.075, "delta_l": 0.02, "delta_r": 0.02})
    f = _by_check(v)
    assert v.status == "fail"
    # δ_R = 0.02° tilts the beam by 2·72″ = 144″: 14.4× the spec; its tolerance alone is 5″ = 0.001389°
    d_r = f["mirror-normal–axis angle error δ_R"]
    assert d_r.status == "fail" and "144″" in d_r.detail and "14.4×" in d_r.detail and "0.001389° (5″)" in d_r.action
    assert f["encoder eccentricity ε/r"].status == "fail" and "1.1×" in f["encoder eccentricity ε/r"].detail
    assert f["all errors together"].status == "fail"
    # δ_L: a pitch of −2 δ_L; only 6.6 % is its own
    d_l = f["δ_L vs the boresight"]
    assert d_l.status == "warn" and "pitch of −2.00 × δ_L" in d_l.detail and "6.6%" in d_l.detail
    assert "δ_R" in f["separable from the boresight"].detail and "ε/r" in f["separable from the boresight"].detail


def test_errors_within_the_spec_pass():
    a, _, v = _run("palmer", {"eccentricity": 5e-6 / 0.075, "delta_l": 0.0005, "delta_r": 0.0005})
    f = _by_check(v)
    assert all(f[s.label].status == "pass" for s in error_sources("palmer"))
    assert f["all errors together"].status == "pass"
    assert v.status == "warn"  # only δ_L's separability


def test_linear_offset_is_named_a_roll_exactly():
    _, _, v = _run("linear", {"scan_angle_offset": 0.001})
    f = _by_check(v)["scan-angle offset vs the boresight"]
    assert f.status == "warn" and "roll of −1.00" in f.detail and "exactly" in f.detail


def test_files_and_section(tmp_path):
    a, sep, v = _run("wedge", {"wedge_angle_error": 0.01})
    paths = write_curves(a, tmp_path)
    assert {p.name for p in paths} == {"pattern.png", "displacement_wedge_angle_error.png"}
    assert (tmp_path / "displacement_wedge_angle_error.csv").read_text().startswith("encoder_angle_deg,dx_m")
    doc = separability_summary(sep)
    assert json.loads(json.dumps(doc))["own_part"]["wedge_angle_error"] == pytest.approx(1.0, abs=1e-3)
    rep = Report("t")
    rep.add_verdict(v)
    add_section(rep, a, sep)
    html = rep.html()
    assert "own part [%]" in html and "worst pointing [″]" in html and "−0.000" not in html
