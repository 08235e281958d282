"""``calidar simulate total-station`` and ``calidar range-cal`` end to end, and every bad
input giving exit code 1 with one line naming the file (and line) or the option, no traceback,
the inputs unchanged and no output left behind."""

import hashlib
import json
import re

import pytest


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _one_line_error(code, err, *names):
    """The run failed with exit 1 and ONE line on stderr naming each of ``names``."""
    msg = err.strip()
    assert code == 1, msg
    assert "\n" not in msg and "Traceback" not in msg and "internal error" not in msg, msg
    for n in names:
        assert str(n) in msg, msg
    return msg


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
    msg = _one_line_error(code, err, bad)
    assert f"line {expected}:" in msg, msg
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


def _scaled(lines, column, factor, only=None):
    """Rows (not P, not the header) with ``column`` multiplied by ``factor`` (``only``: the row starting so)."""
    out = []
    for ln in lines:
        cells = ln.split(",")
        if len(cells) == 7 and cells[6] and not ln.startswith("setup,") and (only is None or ln.startswith(only)):
            cells[column] = f"{float(cells[column]) * factor:.4f}"
        out.append(",".join(cells))
    return out


def test_scanner_ranges_in_millimetres_are_named_as_such(simulated, tmp_path, cli):
    """Issue 16: ranges in mm gave +999 212 877 ppm and exit 0; now the unit slip is named."""
    bad = tmp_path / "mm.csv"
    bad.write_text("\n".join(_scaled(_lines(simulated / "observations.csv"), 6, 1000.0)) + "\n")
    before = _sha(bad)
    code, _, err = cli("range-cal", bad, "--out", tmp_path / "o")
    msg = _one_line_error(code, err, bad, "scanner_m")
    ratio = float(re.search(r"ranges are ([0-9.]+)×", msg).group(1))
    assert "looks like millimetres" in msg and 950 < ratio < 1050, msg
    assert _sha(bad) == before and not (tmp_path / "o").exists()


def test_one_scanner_range_in_millimetres_is_named_by_its_line(simulated, tmp_path, cli):
    lines = _lines(simulated / "observations.csv")
    bad = tmp_path / "one_mm.csv"
    bad.write_text("\n".join(_scaled(lines, 6, 1000.0, only="TS1,G2,C")) + "\n")
    line = _index(lines, "TS1,G2,C") + 1
    code, _, err = cli("range-cal", bad, "--out", tmp_path / "o")
    msg = _one_line_error(code, err, bad, f"line {line}: scanner_m", "looks like millimetres")
    assert "P→C" in msg


def test_total_station_distances_in_millimetres(simulated, tmp_path, cli):
    lines = [",".join(c[:5] + [f"{float(c[5]) * 1000:.1f}"] + c[6:]) if len(c) == 7 and not ln.startswith("setup,")
             else ln for ln in _lines(simulated / "observations.csv") for c in [ln.split(",")]]
    bad = tmp_path / "ts_mm.csv"
    bad.write_text("\n".join(lines) + "\n")
    code, _, err = cli("range-cal", bad, "--out", tmp_path / "o")
    _one_line_error(code, err, bad, "slope_m", "look like millimetres")


def test_non_utf8_file(simulated, tmp_path, cli):
    bad = tmp_path / "latin1.csv"
    bad.write_bytes((simulated / "observations.csv").read_bytes().replace(b"# simulated", b"# simul\xe9"))
    before = _sha(bad)
    code, _, err = cli("range-cal", bad, "--out", tmp_path / "o")
    _one_line_error(code, err, bad, "encoding", "UTF-8", "0xe9")
    assert _sha(bad) == before and not (tmp_path / "o").exists()


def test_file_beyond_the_size_limit_is_refused_before_reading(tmp_path, cli):
    big = tmp_path / "big.csv"
    with open(big, "wb") as f:  # sparse: no disk, no memory
        f.truncate(65 * 2**20)
    code, _, err = cli("range-cal", big, "--out", tmp_path / "o")
    _one_line_error(code, err, big, "size", "at most 64 MB")


def test_too_many_setups(simulated, tmp_path, cli):
    lines = _lines(simulated / "observations.csv")
    i = _index(lines, "#! setup:")
    extra = [f"#! setup: X{k} angle_arcsec=1 distance_mm=1 distance_ppm=1" for k in range(50)]
    bad = tmp_path / "setups.csv"
    bad.write_text("\n".join(lines[:i] + extra + lines[i:]) + "\n")
    code, _, err = cli("range-cal", bad, "--out", tmp_path / "o")
    _one_line_error(code, err, bad, "more than 50 setups")


@pytest.mark.parametrize("text,field", [
    ("nan", "slope_m"), ("inf", "slope_m"), ("-3", "slope_m"), ("1e300", "slope_m"),
])
def test_non_finite_or_absurd_distances(simulated, tmp_path, cli, text, field):
    lines = _replace_field("TS1,G1,A", 5, text)(_lines(simulated / "observations.csv"))
    bad = tmp_path / "d.csv"
    bad.write_text("\n".join(lines) + "\n")
    code, _, err = cli("range-cal", bad, "--out", tmp_path / "o")
    _one_line_error(code, err, bad, field)


@pytest.mark.parametrize("value", ["nan", "0", "-0.01", "1e6", "inf"])
def test_tolerance_out_of_range(simulated, tmp_path, cli, value):
    code, _, err = cli("range-cal", simulated / "observations.csv", "--out", tmp_path / "o", "--tolerance", value)
    _one_line_error(code, err, "--tolerance", "expected")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("doc,phrase", [
    ('{"range_offset_m": 0.01}', "range_offset_m and range_scale_ppm"),
    ('{"range_offset_m": 1e9, "range_scale_ppm": 0}', "range_offset_m"),
    ('{"range_offset_m": 0.01, "range_scale_ppm": "x"}', "range_offset_m and range_scale_ppm"),
    ('[1, 2]', "JSON object"),
])
def test_bad_truth_values(simulated, tmp_path, cli, doc, phrase):
    t = tmp_path / "truth.json"
    t.write_text(doc)
    code, _, err = cli("range-cal", simulated / "observations.csv", "--out", tmp_path / "o", "--truth", t)
    _one_line_error(code, err, t, phrase)
    assert not (tmp_path / "o").exists()


def test_non_utf8_truth(simulated, tmp_path, cli):
    t = tmp_path / "truth.json"
    t.write_bytes(b'{"range_offset_m": 0.01, "note": "\xff"}')
    code, _, err = cli("range-cal", simulated / "observations.csv", "--out", tmp_path / "o", "--truth", t)
    _one_line_error(code, err, t, "UTF-8")


def test_output_folder_holding_the_input_is_refused_even_with_force(simulated, tmp_path, cli):
    obs = simulated / "observations.csv"
    before = _sha(obs)
    code, _, err = cli("range-cal", obs, "--out", simulated, "--force")
    _one_line_error(code, err, "holds the input")
    assert _sha(obs) == before and sorted(p.name for p in simulated.iterdir()) == ["observations.csv", "truth.json"]


def test_observations_that_are_a_folder(tmp_path, cli):
    code, _, err = cli("range-cal", tmp_path, "--out", tmp_path / "o")
    _one_line_error(code, err, tmp_path, "folder")


def test_solution_and_report_record_the_run_and_the_verdict(simulated, tmp_path, cli):
    obs = simulated / "observations.csv"
    code, stdout, err = cli("range-cal", obs, "--out", tmp_path / "c", "--truth", simulated / "truth.json")
    assert code == 0, err
    doc = json.loads((tmp_path / "c" / "solution.json").read_text())
    assert doc["run"]["inputs"][0]["sha256"] == _sha(obs) and doc["run"]["finished_utc"]
    v = doc["verdict"]
    assert v["status"] == "warn"  # the simulated gross error: found, named, excluded
    outliers = next(f for f in v["findings"] if f["check"] == "outliers")
    assert outliers["status"] == "warn" and f"line {doc['outliers']['rejected'][0]['line']}" in outliers["detail"]
    assert next(f for f in v["findings"] if f["check"] == "against the simulation's truth")["status"] == "pass"
    assert "WARN" in stdout and "P_slope" not in stdout
    html = (tmp_path / "c" / "report.html").read_text()
    assert "verdict v-warn" in html and "How this was made" in html and _sha(obs) in html


SIM_BAD = {
    "negative seed": (["--seed", "-1"], "--seed"),
    "no setup": (["--setups", "0"], "--setups"),
    "too many setups": (["--setups", "51"], "--setups"),
    "no group": (["--groups", "0"], "--groups"),
    "negative E points": (["--e-points", "-1"], "--e-points"),
    "negative outliers": (["--outliers", "-1"], "--outliers"),
    "more outliers than targets": (["--setups", "1", "--groups", "1", "--e-points", "0", "--outliers", "5"], "--outliers"),
    "more targets than range-cal reads": (["--setups", "50", "--groups", "10"], "targets"),
    "angle unit rad": (["--angle-unit", "rad"], "--angle-unit"),
    "vertical convention xx": (["--vertical", "xx"], "--vertical"),
}


@pytest.mark.parametrize("case", list(SIM_BAD))
def test_simulate_bad_options(tmp_path, cli, case):
    args, option = SIM_BAD[case]
    code, _, err = cli("simulate", "total-station", "--out", tmp_path / "s", *args)
    msg = _one_line_error(code, err, option)
    assert msg.startswith("error: --") and not (tmp_path / "s").exists()


def test_excel_export_with_bom_and_crlf_reads(simulated, tmp_path, cli):
    f = tmp_path / "excel.csv"
    f.write_bytes(b"\xef\xbb\xbf" + (simulated / "observations.csv").read_bytes().replace(b"\n", b"\r\n"))
    code, _, err = cli("range-cal", f, "--out", tmp_path / "o")
    assert code == 0, err


def test_semicolon_separated_file_is_named(simulated, tmp_path, cli):
    lines = [ln.replace(",", ";") if not ln.startswith("#") else ln for ln in _lines(simulated / "observations.csv")]
    f = tmp_path / "semicolons.csv"
    f.write_text("\n".join(lines) + "\n")
    code, _, err = cli("range-cal", f, "--out", tmp_path / "o")
    _one_line_error(code, err, f, "header", "separated by ';'")
