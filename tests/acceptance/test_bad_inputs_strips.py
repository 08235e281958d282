"""The bad-input corpus (issue 16), part 2: ``quality`` and ``boresight`` (see test_bad_inputs.py)."""

from __future__ import annotations

import json

import pytest

COMMANDS = {"quality", "boresight"}  #: the commands this module's corpus covers
STRIPS = [f"{{S}}/strips/line_00{k}.laz" for k in range(1, 5)]
S1, S2 = STRIPS[:2]
SBET, TOML, SMRMSG = "{S}/sbet.out", "{S}/sensor.toml", "{S}/smrmsg.out"


def case(args, *messages: str, id: str):
    """One corpus case: its arguments and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


QUALITY = [
    case([S1, S2, "--cell", "0.001"], "--cell", id="cell-0.001"),
    case([S1, S2, "--cell", "1e9"], "--cell", id="cell-1e9"),
    case([S1, S2, "--cell", "500"], "--cell", "no 500 m cell", id="cell-larger-than-the-overlaps"),
    case([S1, S2, "--cell", "0"], "--cell", id="cell-0"),
    case([S1, S2, "--cell", "-2"], "--cell", id="cell-negative"),
    case([S1, S2, "--cell", "nan"], "--cell", id="cell-nan"),
    case([S1, S2, "--cell", "inf"], "--cell", id="cell-inf"),
    case([S1, S2, "{B}/empty.laz"], "empty.laz", "no points", id="empty-strip"),
    case([S1, S2, "{B}/a[b]c.laz"], "a[b]c.laz", "no points", id="bracketed-empty-strip"),
    case([S1, S2, S1], "line_001.laz", "given twice", id="same-strip-twice"),
    case([S1, S2, "{B}/copy_of_line_001.laz"], "copy_of_line_001.laz", "duplicate", id="duplicated-strip"),
    case([S1], "line_001.laz", id="one-strip"),
    case([S1, "{B}/huge.las"], "huge.las", id="coordinates-1e300"),
    case([S1, "{B}/garbage.laz"], "garbage.laz", id="garbage"),
    case([S1, "{B}/truncated.laz"], "truncated.laz", id="truncated"),
    case([S1, "{B}/strip[bold]x.laz"], "strip[bold]x.laz", id="bracketed-garbage"),
    case([S1, "{B}/count.las"], "count.las", id="count-mismatch"),
    case([S1, "{B}/count_low.las"], "count_low.las", "point_count", id="count-too-low"),
    case([S1, "{B}/missing.laz"], "missing.laz", id="missing"),
    case([S1, "{B}/far.laz"], "line_001.laz", "far.laz", id="far-strip-alone"),
    case([S1, S2, "--out", S1, "--force"], "line_001.laz", id="out-is-input"),
    case([S1, S2, "--out", "{S}/strips", "--force"], "strips", "input", id="out-holds-inputs"),
    case([S1, S2, "--out", "{B}/strips_link", "--force"], "strips_link", "input", id="out-links-to-the-inputs"),
    case([S1, S2, "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case([S1, S2, "--config", "{B}/config_not_toml.toml"], "config_not_toml.toml", "TOML", id="config-not-toml"),
    case([S1, S2, "--config", "{B}/quality_cell.toml"], "quality_cell.toml: cell_m (--cell): expected",
         id="config-cell-0"),
    case([S1, S2, "--config", "{B}/quality_classes.toml"], "quality_classes.toml: classes (--classes)",
         id="config-class-300"),
    case([S1, S2, "--config", "{B}/tpu_unknown.toml"], "tpu_unknown.toml: noise: unknown key", id="config-of-tpu"),
]


@pytest.mark.parametrize("args, messages", QUALITY)
def test_quality(bad_input, args, messages):
    bad_input(["quality", *args], 1, *messages)


def _not_json(name):
    raise AssertionError(f"quality.json holds {name}, which is not JSON")


def test_quality_names_a_strip_far_from_the_others(cli, corpus, tmp_path):
    """A strip overlapping none of the others is named (not silently left out)."""
    code, out, err = cli(*corpus.args(["quality", *STRIPS, "{B}/far.laz", "--out", "{O}"], tmp_path / "q"))
    assert code == 0, err
    assert "far.laz" in out + err
    doc = json.loads((tmp_path / "q" / "quality.json").read_text(), parse_constant=_not_json)  # no NaN, Infinity
    assert any("far.laz" in n for n in doc["notes"])


TRAJECTORY = [
    case(["--trajectory", "{B}/sbet_height1e9.out"], "sbet_height1e9.out", "height", id="sbet-height-1e9"),
    case(["--trajectory", "{B}/sbet_roll50rad.out"], "sbet_roll50rad.out", "roll", id="sbet-roll-50rad"),
    case(["--trajectory", "{B}/sbet_truncated.out"], "sbet_truncated.out", "136", id="sbet-truncated"),
    case(["--trajectory", "{B}/sbet_short.out"], "sbet_short.out", id="sbet-not-covering"),
    case(["--trajectory", "{B}/sbet_gap.out"], "sbet_gap.out", "gap(s) without records", id="sbet-gap"),
    case(["--trajectory", "{B}/sbet_nan_time.out"], "sbet_nan_time.out", "time", id="sbet-nan-time"),
    case(["--trajectory", "{B}/traj_latin1.txt"], "traj_latin1.txt", "UTF-8", id="trajectory-not-utf8"),
    case(["--trajectory-accuracy", "{B}/acc_truncated.out"], "acc_truncated.out", "80", id="smrmsg-truncated"),
    case(["--trajectory-accuracy", "{B}/acc_negative.out"], "acc_negative.out", "north", id="smrmsg-negative"),
    case(["--trajectory-accuracy", "{B}/acc_nan.out"], "acc_nan.out", "pitch", id="smrmsg-nan"),
    case(["--trajectory-accuracy", "{B}/acc_huge.out"], "acc_huge.out", "down", id="smrmsg-huge"),
    case(["--trajectory-accuracy", "{B}/acc_short.out"], "acc_short.out", "time", id="smrmsg-not-covering"),
    case(["--trajectory-accuracy", "{B}/missing.out"], "missing.out", id="smrmsg-missing"),
    case(["--trajectory-accuracy", SMRMSG, "--trajectory-sigma", "0.03,0.002"], "--trajectory-sigma",
         id="accuracy-and-sigma"),
    case(["--sensor", "{B}/sensor_nan.toml"], "sensor_nan.toml", "boresight_roll_deg", id="sensor-nan"),
    case(["--sensor", "{B}/sensor_empty.toml"], "sensor_empty.toml", id="sensor-empty"),
    case(["--sensor", "{B}/sensor_roll1e6.toml"], "sensor_roll1e6.toml", id="sensor-roll-1e6"),
    case(["--sensor", "{B}/sensor_scale.toml"], "sensor_scale.toml", "scale_ppm", id="sensor-scale-ppm"),
]

OPTIONS = [
    case(["--trajectory-block", "0"], "--trajectory-block", id="block-0"),
    case(["--trajectory-block", "-1"], "--trajectory-block", id="block-negative"),
    case(["--trajectory-block", "nan"], "--trajectory-block", id="block-nan"),
    case(["--trajectory-block", "1e9"], "--trajectory-block", id="block-1e9"),
    case(["--trajectory-correlation", "0,3"], "--trajectory-correlation", id="correlation-0"),
    case(["--trajectory-correlation", "a,b"], "--trajectory-correlation", id="correlation-words"),
    case(["--trajectory-correlation", "nan,1"], "--trajectory-correlation", id="correlation-nan"),
    case(["--trajectory-correlation", "20"], "--trajectory-correlation", id="correlation-one-value"),
    case(["--trajectory-correlation", "-5,3"], "--trajectory-correlation", id="correlation-negative"),
    case(["--trajectory-correlation", "20,1e9"], "--trajectory-correlation", id="correlation-huge"),
    case(["--trajectory-sigma", "0,0.002"], "--trajectory-sigma", id="sigma-0"),
    case(["--trajectory-sigma", "0.03,-1"], "--trajectory-sigma", id="sigma-attitude-negative"),
    case(["--trajectory-sigma", "0.03,1e9"], "--trajectory-sigma", id="sigma-attitude-huge"),
    case(["--trajectory-sigma", "-1,0.002"], "--trajectory-sigma", id="sigma-negative"),
    case(["--trajectory-sigma", "nan,0.002"], "--trajectory-sigma", id="sigma-nan"),
    case(["--trajectory-sigma", "0.03"], "--trajectory-sigma", id="sigma-one-value"),
    case(["--trajectory-sigma", "1e9,1e9"], "--trajectory-sigma", id="sigma-huge"),
    case(["--trajectory-model", "maybe"], "--trajectory-model", id="model-maybe"),
    case(["--trajectory-model", "off", "--trajectory-sigma", "0.03,0.002"], "--trajectory-model", id="model-off-sigma"),
    case(["--model-check", "maybe"], "--model-check", "on or off", id="model-check-maybe"),
    case(["--model-check", ""], "--model-check", "on or off", id="model-check-empty"),
    case(["--method", "icp"], "--method", id="method"),
    case(["--estimate", "everything"], "--estimate", id="estimate"),
    case(["--estimate", "boresight,trajectory_bias", "--trajectory-model", "off"], "--estimate", "trajectory_bias",
         id="estimate-trajectory-bias-model-off"),
    case(["--strip-points", "5"], "--strip-points", id="strip-points-5"),
    case(["--control-crs", "EPSG:32632"], "--control-crs", "without --control", id="control-crs-alone"),
    case(["--control-crs", "EPSG:999999", "--control", "{S}/sbet.out"], "--control-crs", id="control-crs-unknown"),
    case(["--crs", "EPSG:999999"], "--crs", id="crs-unknown"),
    case(["--time-system", "fortnight"], "--time-system", id="time-system"),
    case(["--geoid-undulation", "nan"], "--geoid-undulation", id="geoid-undulation-nan"),
    case(["--trajectory-crs", "EPSG:999999"], "--trajectory-crs", id="trajectory-crs-unknown"),
    case(["--trajectory-angles", "grad"], "--trajectory-angles", id="trajectory-angles"),
    case(["--trajectory-heading", "magnetic"], "--trajectory-heading", id="trajectory-heading"),
    case(["--trajectory-columns", "time,lat"], "sbet.out", "--trajectory-columns", id="trajectory-columns-of-an-sbet"),
    case(["--scheduler", "::::"], "--scheduler", id="scheduler-address"),
    case(["--control", "{B}/missing.csv"], "missing.csv", id="control-missing"),
    # a reference cloud as control (LAS/LAZ with --control-sigma), each error one line naming file or option
    case(["--control-sigma", "0.02"], "--control-sigma", "without --control", id="control-sigma-alone"),
    case(["--control", S1], "line_001.laz", "--control-sigma", "stated vertical accuracy", id="control-cloud-no-sigma"),
    case(["--control", S1, "--control-sigma", "nan"], "--control-sigma", id="control-cloud-sigma-nan"),
    case(["--control", S1, "--control-sigma", "0"], "--control-sigma", id="control-cloud-sigma-0"),
    case(["--control", "{B}/planes_nan.csv", "--control-sigma", "0.02"], "planes_nan.csv", "--control-sigma",
         "reference cloud", id="control-sigma-with-a-csv"),
    case(["--control", "{B}/empty.laz", "--control-sigma", "0.02"], "empty.laz", "no points", id="control-cloud-empty"),
    case(["--control", "{B}/garbage.laz", "--control-sigma", "0.02"], "garbage.laz", id="control-cloud-garbage"),
    case(["--control", "{B}/missing.laz", "--control-sigma", "0.02"], "missing.laz", id="control-cloud-missing"),
    case(["--control", "{B}/rough.laz", "--control-sigma", "0.02"], "rough.laz", "smooth surface",
         id="control-cloud-no-planar-cell"),
    # control surfaces (surveyed planes: plane, x, y, z, sigma), each named by file, line and field
    case(["--control", "{B}/planes_nosigma.csv"], "planes_nosigma.csv", "sigma", "line 1", id="control-planes-no-sigma"),
    case(["--control", "{B}/planes_nan.csv"], "planes_nan.csv", "z", "line 4", "'nan'", id="control-planes-nan"),
    case(["--control", "{B}/planes_two.csv"], "planes_two.csv", "plane", "line 2", "2 point(s)", id="control-planes-two"),
    case(["--control", "{B}/planes_sigma0.csv"], "planes_sigma0.csv", "sigma", "line 2", "σ > 0",
         id="control-planes-sigma-0"),
    case(["--control", "{B}/planes_line.csv"], "planes_line.csv", "x/y", "line 2", "along a line",
         id="control-planes-collinear"),
    case(["--control", "{B}/planes_off.csv"], "planes_off.csv", "z", "line 5", "off the plane", id="control-planes-off"),
    case(["--checkpoints", "{B}/missing.csv"], "missing.csv", id="checkpoints-missing"),
    case(["--checkpoints-crs", "EPSG:32632"], "--checkpoints-crs", "without --checkpoints", id="checkpoints-crs-alone"),
    case(["--class", "5"], "--class", "without --checkpoints", id="class-alone"),
    case(["--class", "nan", "--checkpoints", "{B}/missing.csv"], "--class", id="class-nan"),
    case(["--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case(["--config", "{B}/config_unknown.toml"], "config_unknown.toml", "solver.wobble", "unknown key",
         id="config-unknown-key"),
    case(["--config", "{B}/config_unknown_section.toml"], "config_unknown_section.toml", "trajectory", "unknown key",
         id="config-unknown-section"),
    case(["--config", "{B}/config_type.toml"], "config_type.toml", "trajectory_model.block_s", "expected float",
         id="config-wrong-type"),
    case(["--config", "{B}/config_estimate.toml"], "config_estimate.toml", "estimate", "everything",
         id="config-estimate"),
    case(["--config", "{B}/config_estimate_text.toml"], "config_estimate_text.toml", "estimate", "list",
         id="config-estimate-not-a-list"),
    case(["--config", "{B}/config_method.toml"], "config_method.toml", "method", "icp", id="config-method"),
    case(["--config", "{B}/config_sigma.toml"], "config_sigma.toml", "trajectory_model.sigma", id="config-sigma"),
    case(["--config", "{B}/config_block.toml"], "config_block.toml", "trajectory_model", "--trajectory-block",
         id="config-block-negative"),
    case(["--config", "{B}/config_off.toml"], "config_off.toml", "trajectory_model.sigma", id="config-model-off-sigma"),
    case(["--config", "{B}/config_shape.toml"], "config_shape.toml", "trajectory_model", "gm1, gm2", "'gm3'",
         id="config-shape"),
    case(["--config", "{B}/config_model_check.toml"], "config_model_check.toml", "model_check", "expected bool",
         id="config-model-check"),
    case(["--config", "{B}/config_vgicp.toml"], "config_vgicp.toml", "vgicp", "voxel_m", id="config-vgicp-voxel"),
    case(["--config", "{B}/config_crs.toml"], "config_crs.toml", "inputs.crs", id="config-crs"),
    case(["--config", "{B}/config_strip_points.toml"], "config_strip_points.toml", "ingest.strip_points",
         id="config-strip-points"),
    case(["--config", "{B}/config_not_toml.toml"], "config_not_toml.toml", "TOML", id="config-not-toml"),
    case(["--config", "{B}/truth_latin1.json"], "truth_latin1.json", "UTF-8", id="config-not-utf8"),
    case(["--workers", "0"], "--workers", id="workers-0"),
    case(["--workers", "-3"], "--workers", id="workers-negative"),
    case(["--workers", "100000"], "--workers", id="workers-huge"),
    case(["--truth", "{B}/truth_latin1.json"], "truth_latin1.json", "UTF-8", id="truth-not-utf8"),
    case(["--truth", "{B}/truth_notjson.json"], "truth_notjson.json", id="truth-not-json"),
    case(["--truth", "{B}/truth_list.json"], "truth_list.json", id="truth-list"),
    case(["--truth", "{P}/truth.json"], "truth.json", id="truth-of-another-simulation"),
]

REST = STRIPS[1:]  #: line_002 … line_004, with which each bad strip is given
STRIP_CASES = [
    case([*STRIPS, "{B}/empty.laz"], "empty.laz", "no points", id="empty-strip"),
    case([*STRIPS, "{B}/a[b]c.laz"], "a[b]c.laz", "no points", id="bracketed-empty-strip"),
    case([*STRIPS, S1], "line_001.laz", "given twice", id="duplicated-strip"),
    case([*STRIPS, "{B}/copy_of_line_001.laz"], "copy_of_line_001.laz", "duplicate", id="copied-strip"),
    case([*REST, "{B}/nan_time.las"], "nan_time.las", "gps_time", id="nan-times"),
    case([*REST, "{B}/huge.las"], "huge.las", id="coordinates-1e300"),
    case([*REST, "{B}/geoid.laz"], "geoid.laz", "expected the CRS of line_002.laz", id="geoid-among-others"),
    case([*REST, "{B}/garbage.laz"], "garbage.laz", id="garbage"),
    case([*REST, "{B}/count.las"], "count.las", id="count-mismatch"),
    case([S1], "line_001.laz", id="one-strip"),
    case(["{B}/geoid.laz"], "geoid.laz", "us_nga_egm08_25.tif", id="geoid-without-grid"),
]


#: options a user cannot give wrongly (flags) or covered by the tests below
NOT_IN_CORPUS = {"--force", "--write-strips", "--all-classes", "--no-all-classes", "--help"}


def test_every_boresight_option_is_in_the_corpus():
    """Each of ``calidar boresight``'s options has a bad-input case here."""
    import typer.main

    from calidar.cli import app

    command = typer.main.get_command(app).commands["boresight"]
    options = {o for p in command.params for o in p.opts if o.startswith("--")}
    given = {a for c in TRAJECTORY + OPTIONS for a in c.values[0] if isinstance(a, str) and a.startswith("--")}
    given |= {"--out", "--trajectory", "--sensor"}  # test_boresight_never_writes_over_its_inputs, TRAJECTORY, USAGE
    assert options - given - NOT_IN_CORPUS == set()


def _boresight(extra, strips=STRIPS):
    args = ["boresight", *strips, *extra, "--out", "{O}"]
    for option, default in (("--trajectory", SBET), ("--sensor", TOML)):
        if option not in extra:
            args += [option, default]
    return args


@pytest.mark.parametrize("extra, messages", TRAJECTORY + OPTIONS)
def test_boresight_options(bad_input, extra, messages):
    bad_input(_boresight(extra), 1, *messages)


@pytest.mark.parametrize("strips, messages", STRIP_CASES)
def test_boresight_strips(bad_input, strips, messages):
    bad_input(_boresight([], strips), 1, *messages)


def test_boresight_names_a_strip_far_from_the_others(cli, corpus, tmp_path):
    """A strip overlapping none of the others is named (not silently left out): far.laz lies
    25 km from where the trajectory flew at its times, so its geometry is the error (issue 27)."""
    code, out, err = cli(*corpus.args(_boresight([], [*STRIPS, "{B}/far.laz"]), tmp_path / "b"))
    assert code == 1, err
    assert "far.laz: xyz" in err and "sideways from the trajectory" in err


def test_boresight_never_writes_over_its_inputs(bad_input):
    """The issue's example: the output folder holds the input strips and sensor.toml."""
    bad_input(["boresight", *STRIPS, "--trajectory", SBET, "--sensor", TOML, "--write-strips", "--out", "{S}",
               "--force"], 1, "input")
    bad_input(["boresight", *STRIPS, "--trajectory", SBET, "--sensor", TOML, "--write-strips", "--out", "{S}/strips",
               "--force"], 1, "input")
    bad_input(["boresight", *STRIPS, "--trajectory", SBET, "--sensor", TOML, "--write-strips", "--out",
               "{B}/strips_link", "--force"], 1, "input")


def test_errors_name_the_output_not_its_temporary(cli, corpus, tmp_path, monkeypatch):
    """A write failing inside the run's transaction (here: a full disk) names --out, never the
    hidden temporary folder, and leaves nothing behind."""
    def full_disk(q, folder, *args, **kw):
        raise OSError(28, "No space left on device", str(folder / f"dz_{q.a}_{q.b}.tif"))

    monkeypatch.setattr("calidar.pipelines.quality.write_rasters", full_disk)
    out = tmp_path / "q"
    code, _, err = cli(*corpus.args(["quality", *STRIPS, "--out", "{O}"], out))
    # --out, the file and the cause (issue 27: one line naming --out and the cause)
    assert code == 1 and err.strip() == f"error: {out}: cannot write {out}/dz_1_2.tif: No space left on device"
    assert list(tmp_path.iterdir()) == []
