"""``calidar simulate total-station`` and ``calidar range-cal`` end to end, and every bad
input giving exit code 1 with one line naming the file and the line."""

import json

import pytest


@pytest.fixture
def simulated(tmp_path, cli):
    code, out, err = cli("simulate", "total-station", "--seed", "11", "--out", tmp_path / "sim", "--outliers", "1")
    assert code == 0, err
    return tmp_path / "sim"


def test_simulate_and_calibrate_end_to_end(simulated, tmp_path, cli):
    truth = json.loads((simulated / "truth.json").read_text())
    assert set(truth) >= {"range_offset_m", "range_scale_ppm", "noise"}
    out = tmp_path / "cal"
    code, stdout, err = cli("range-cal", simulated / "observations.csv", "--out", out, "--truth", simulated / "truth.json")
    assert code == 0, err
    doc = json.loads((out / "solution.json").read_text())
    off = doc["parameters"]["range_offset"]
    assert off["unit"] == "m" and doc["parameters"]["range_scale"]["unit"] == "ppm"
    assert off["truth"] == pytest.approx(truth["range_offset_m"])
    assert abs(off["error"]) < 3 * off["sigma"]
    assert doc["intervals95"]["range_offset"]["low"] < off["value"] < doc["intervals95"]["range_offset"]["high"]
    assert "delta_s_m" in doc["two_step_method"]
    # the simulated gross error is found and named by its line
    bad = truth["outliers"][0]
    rejected = doc["outliers"]["rejected"]
    assert [(r["group"], r["point"]) for r in rejected] == [(bad["group"], bad["point"])]
    line = (simulated / "observations.csv").read_text().splitlines()[rejected[0]["line"] - 1]
    assert f",{bad['group']},{bad['point']}," in line
    assert f"line {rejected[0]['line']}" in stdout
    html = (out / "report.html").read_text()
    assert "Range calibration" in html and html.count("<img") >= 2
    # no silent overwrite
    code, _, err = cli("range-cal", simulated / "observations.csv", "--out", out)
    assert code == 1 and "--force" in err


def test_acceptance_exit_codes(simulated, tmp_path, cli):
    truth = json.loads((simulated / "truth.json").read_text())
    obs = simulated / "observations.csv"
    big = abs(truth["range_offset_m"]) + 0.2
    code, out, _ = cli("range-cal", obs, "--out", tmp_path / "a", "--tolerance", big)
    assert code == 0 and "acceptance: PASS" in out
    code, out, _ = cli("range-cal", obs, "--out", tmp_path / "b", "--tolerance", 1e-4)
    assert code == 3 and "acceptance: FAIL" in out
    doc = json.loads((tmp_path / "b" / "solution.json").read_text())
    assert doc["acceptance"]["passed"] is False
    code, _, err = cli("range-cal", obs, "--out", tmp_path / "c", "--tolerance", -1)
    assert code == 1 and "--tolerance" in err


def _lines(path):
    return path.read_text().splitlines()


def _index(lines, start):
    return next(i for i, ln in enumerate(lines) if ln.startswith(start))


def _drop(start):
    def f(lines):
        i = _index(lines, start)
        del lines[i]
        return lines
    return f


def _replace_field(start, col, value):
    def f(lines):
        i = _index(lines, start)
        cells = lines[i].split(",")
        cells[col] = value
        lines[i] = ",".join(cells)
        return lines
    return f


def _header(old, new):
    def f(lines):
        i = _index(lines, "setup,")
        lines[i] = lines[i].replace(old, new)
        return lines
    return f


def _expected_line(kind):
    """The 1-based line the error must name, computed from the mutated file."""
    def group_g2(lines):
        return max(i for i, ln in enumerate(lines) if ln.startswith("TS1,G2,")) + 1

    return {
        "group_g2": group_g2,
        "header": lambda lines: _index(lines, "setup,") + 1,
        "ts2_first": lambda lines: _index(lines, "TS2,") + 1,
        "row_g1a": lambda lines: _index(lines, "TS1,G1,A") + 1,
        "row_g1b": lambda lines: _index(lines, "TS1,G1,B") + 1,
        "sigma": lambda lines: _index(lines, "#! scanner_sigma_mm") + 1,
    }[kind]


BAD_CASES = {
    "group missing a point": (_drop("TS1,G2,D"), "group_g2", "missing point(s) D"),
    "group with a point twice": (_replace_field("TS1,G1,B", 2, "A"), "row_g1b", "second point A"),
    "zenith distance out of range": (_replace_field("TS1,G1,A", 4, "200.5"), "row_g1a", "angle out of range"),
    "horizontal direction out of range": (_replace_field("TS1,G1,A", 3, "360.0"), "row_g1a", "angle out of range"),
    "negative direction": (_replace_field("TS1,G1,A", 3, "-1"), "row_g1a", "angle out of range"),
    "mixed units": (_header("zd_deg", "zd_gon"), "header", "mixed angle units"),
    "unknown angle unit": (_header("hz_deg", "hz_rad"), "header", "unknown angle unit"),
    "unknown column": (_header("scanner_m", "scanner_m,remark"), "header", "unknown column 'remark'"),
    "missing column": (_header(",slope_m", ""), "header", "missing column(s) slope_m"),
    "setup missing its P observation": (_drop("TS2,,P,"), "ts2_first", "setup TS2: missing its P observation"),
    "extra value in a row": (_replace_field("TS1,G1,A", 5, "12,5"), "row_g1a", "expected 7 comma-separated values"),
    "bad distance": (_replace_field("TS1,G1,A", 5, "abc"), "row_g1a", "slope_m: expected a slope distance"),
    "undeclared setup": (_replace_field("TS1,G1,A", 0, "TS9"), "row_g1a", "'TS9' is not declared"),
    "unknown point": (_replace_field("TS1,G1,A", 2, "X"), "row_g1a", "expected P, A, B, C, D or E<name>"),
    "feature point without scanner range": (_replace_field("TS1,G1,A", 6, ""), "row_g1a", "scanner range of A"),
    "bad scanner sigma": (_replace_field("#! scanner_sigma_mm", 0, "#! scanner_sigma_mm: -2"), "sigma", "positive"),
}


@pytest.mark.parametrize("case", list(BAD_CASES))
def test_bad_input_names_file_and_line(simulated, tmp_path, cli, case):
    mutate, where, phrase = BAD_CASES[case]
    original = _lines(simulated / "observations.csv")
    lines = mutate(list(original))
    # rows edited in place keep their line number (found in the original); dropped rows shift the rest
    expected = _expected_line(where)(original if where.startswith("row") else lines)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    before = bad.read_bytes()
    code, out, err = cli("range-cal", bad, "--out", tmp_path / "out")
    assert code == 1
    msg = err.strip()
    assert "\n" not in msg and "Traceback" not in msg
    assert str(bad) in msg and f"line {expected}:" in msg, msg
    assert phrase in msg, msg
    assert bad.read_bytes() == before and not (tmp_path / "out").exists()


@pytest.mark.parametrize("text,phrase", [
    ("setup,group,point,hz_deg,zd_deg,slope_m,scanner_m\n", "line 1: expected the directive '#! calidar-total-station 1'"),
    ("#! calidar-total-station 1\nsetup,group,point,hz_deg,zd_deg,slope_m,scanner_m\n", "line 2: expected the directive '#! scanner_sigma_mm"),
    ("#! calidar-total-station 1\n#! scanner_sigma_mm: 2\nsetup,group,point,hz_deg,zd_deg,slope_m,scanner_m\n", "line 3: expected at least one '#! setup"),
    ("#! calidar-total-station 1\n#! scanner_sigma_mm: 2\n#! setup: T angle_arcsec=1 distance_mm=1 distance_ppm=1\n"
     "setup,group,point,hz_deg,zd_deg,slope_m,scanner_m\n", "line 4: expected observation rows"),
    ("#! calidar-total-station 1\n#! scanner_sigma_mm: 2\n#! setup: T angle_arcsec=1 distance_mm=1\n", "line 3: setup T: missing distance_ppm"),
    ("#! calidar-total-station 1\n#! scanner_sigma_mm: 2\n#! setup: T angle_arcsec=1 distance_mm=1 distance_ppm=1\n"
     "setup,group,point,hz_deg,zd_deg,slope_m,scanner_m\nT,,P,10,90,5,\nT,,E1,20,90,5,4\n", "line 6: no feature-point group"),
])
def test_missing_directives_and_rows(tmp_path, cli, text, phrase):
    p = tmp_path / "x.csv"
    p.write_text(text)
    code, _, err = cli("range-cal", p, "--out", tmp_path / "o")
    assert code == 1 and phrase in err, err


def test_missing_file(tmp_path, cli):
    code, _, err = cli("range-cal", tmp_path / "nope.csv", "--out", tmp_path / "o")
    assert code == 1 and "nope.csv" in err


def test_bad_truth_file(simulated, tmp_path, cli):
    t = tmp_path / "truth.json"
    t.write_text("{\n  \"range_offset_m\": 0.1,\n  oops\n}")
    code, _, err = cli("range-cal", simulated / "observations.csv", "--out", tmp_path / "o", "--truth", t)
    assert code == 1 and "truth.json: line 3" in err


def test_demo_step(tmp_path):
    import time

    from calidar.demo.rangecal import range_calibration_step
    from calidar.report import Report

    report = Report("demo")
    t0 = time.perf_counter()
    range_calibration_step(report, tmp_path, seed=5)
    assert time.perf_counter() - t0 < 10.0
    assert [s.title for s in report.sections] == ["Range calibration against a total station (simulated)"]
    doc = json.loads((tmp_path / "range_cal" / "solution.json").read_text())
    truth = json.loads((tmp_path / "range_cal" / "truth.json").read_text())
    off = doc["parameters"]["range_offset"]
    assert abs(off["value"] - truth["range_offset_m"]) < 3 * off["sigma"]
    assert len(doc["outliers"]["rejected"]) >= 1


def test_simulate_options_and_no_overwrite(tmp_path, cli):
    out = tmp_path / "s"
    args = ("simulate", "total-station", "--seed", "4", "--out", out, "--angle-unit", "gon", "--vertical", "va",
            "--setups", "1", "--groups", "2", "--e-points", "3")
    assert cli(*args)[0] == 0
    text = (out / "observations.csv").read_text()
    assert "setup,group,point,hz_gon,va_gon,slope_m,scanner_m" in text and text.count(",E") == 3
    code, _, err = cli(*args)
    assert code == 1 and "--force" in err
    assert cli(*args, "--force")[0] == 0
    code, _, err = cli("simulate", "total-station", "--out", tmp_path / "t", "--angle-unit", "rad")
    assert code == 1 and "--angle-unit" in err
    code, _, err = cli("range-cal", out / "observations.csv", "--out", tmp_path / "c")
    assert code == 0, err


def test_calibration_error_is_one_line_and_leaves_no_output(tmp_path, cli):
    out = tmp_path / "s"
    assert cli("simulate", "total-station", "--out", out, "--setups", "1", "--groups", "1", "--e-points", "0")[0] == 0
    code, _, err = cli("range-cal", out / "observations.csv", "--out", tmp_path / "c")
    assert code == 1 and "range_scale cannot be separated" in err and "\n" not in err.strip()
    assert not (tmp_path / "c").exists()
    code, stdout, err = cli("range-cal", out / "observations.csv", "--out", tmp_path / "c", "--fix-scale")
    assert code == 0, err
    assert "range_scale" not in stdout.split("two-step")[0]
    doc = json.loads((tmp_path / "c" / "solution.json").read_text())
    assert doc["parameters"]["range_scale"]["free"] is False and "range_scale" not in doc["intervals95"]
