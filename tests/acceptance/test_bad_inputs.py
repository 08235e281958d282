"""The bad-input corpus (issue 16), part 1: usage errors, ``info``, ``georef``, ``inverse``,
``regeoref``, ``sensor import``. Each case: the exit code (1 bad input, 2 usage), one message
naming the file / option and the field, no traceback, no "internal error", inputs unchanged,
nothing left behind (fixtures in conftest.py, inputs in bad_inputs_corpus.py)."""

from __future__ import annotations

import pytest

from calidar.cli import app


def case(args, *messages: str, id: str):
    """One corpus case: its arguments and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


COMMANDS = {"info", "georef", "inverse", "regeoref", "sensor import"}  #: the commands this module's corpus covers
S1, S2 = "{S}/strips/line_001.laz", "{S}/strips/line_002.laz"
SBET, TOML = "{S}/sbet.out", "{S}/sensor.toml"

USAGE = [
    case([], "Usage: calidar [OPTIONS] COMMAND", id="no-command"),
    case(["info"], "Missing argument 'FILE'", id="info-no-arg"),
    case(["bogus"], "No such command 'bogus'", id="bogus-command"),
    case(["simulate", "survey", "--seed", "abc", "--out", "{O}"], "'--seed': 'abc' is not a valid integer",
                 id="seed-abc"),
    case(["info", "--jsn", "x"], "No such option '--jsn'", id="info-jsn"),
    # click raises this one before any context exists: the usage line is calidar's to give
    case(["info", "--json=3", S1], "Usage: calidar info", "'--json' does not take a value",
                 id="flag-given-a-value"),
    case(["quality", S1, "--cell", "abc"], "'--cell': 'abc' is not a valid float", id="quality-cell-abc"),
    case(["boresight", S1, "--trajectory", SBET, "--out", "{O}"], "Missing option '--sensor'",
                 id="boresight-no-sensor"),
    case(["scanner", "analyze", "--model", "linear", "--range", "100", "--points", "1e9", "--out", "{O}"],
                 "'--points': '1e9' is not a valid integer", id="points-1e9"),
    case(["simulate", "photons", "--n-ccr", "two", "--out", "{O}"], "'--n-ccr'", id="n-ccr-word"),
    case(["denoise", "{P}/ATL03_sim.h5", "--out", "{O}", "--force", "yes"], "unexpected extra argument",
                 id="force-with-value"),
    case(["range-cal", "{T}/observations.csv", "{T}/truth.json", "--out", "{O}"], "unexpected extra argument",
                 id="range-cal-two-files"),
    case(["ccr", "{P}/ATL03_sim.h5", "--out", "{O}"], "Missing option '--ccr'", id="ccr-no-ccr"),
    case(["demo", "--seed", "-1", "--out", "{O}"], "'--seed'", id="demo-seed-negative"),
    case(["simulate", "teleport", "--out", "{O}"], "No such command 'teleport'", id="simulate-bogus"),
    case(["sensor", "import", "x.toml", "--out", "{O}"], "Missing option '--from'", id="sensor-no-from"),
    case(["inverse", S1, "--out", "{O}"], "Missing option '--trajectory'", id="inverse-no-trajectory"),
]


@pytest.mark.parametrize("args, messages", USAGE)
def test_usage_error(bad_input, args, messages):
    bad_input(args, 2, *messages)


INFO = [
    case(["{B}/missing.laz"], "missing.laz", "not found", id="missing"),
    case(["{B}/acc/smrmsg_truncated.out"], "smrmsg_truncated.out", "80 bytes", id="smrmsg-truncated"),
    case(["{B}"], "is a folder", id="folder"),
    case(["{B}/count.las"], "count.las", "3000", "2000", id="las-count-mismatch"),
    case(["{B}/count_low.las"], "count_low.las", "1000", "2000", id="las-count-too-low"),
    case(["{B}/huge.las"], "huge.las", "x", id="las-coordinates-1e300"),
    case(["{B}/garbage.laz"], "garbage.laz", id="las-garbage"),
    case(["{B}/truncated.laz"], "truncated.laz", id="laz-truncated"),
    case(["{B}/zero.las"], "zero.las", "empty", id="las-zero-bytes"),
    case(["{B}/strip[bold]x.laz"], "strip[bold]x.laz", id="bracketed-name"),
    case(["{B}/sbet_truncated.out"], "sbet_truncated.out", "136", id="sbet-truncated"),
    case(["{B}/sbet_height1e9.out"], "sbet_height1e9.out", "height", id="sbet-height-1e9"),
    case(["{B}/sbet_roll50rad.out"], "sbet_roll50rad.out", "roll", id="sbet-roll-50rad"),
    case(["{B}/sbet_nan_time.out"], "sbet_nan_time.out", "time", id="sbet-nan-time"),
    case(["{B}/sbet_lat_deg.out"], "sbet_lat_deg.out", "lat", id="sbet-lat-in-degrees"),
    case(["{B}/sbet_empty.out"], "sbet_empty.out", "empty", id="sbet-empty"),
    case(["{B}/traj_latin1.txt"], "traj_latin1.txt", "UTF-8", id="trajectory-not-utf8"),
    case(["{B}/traj_nan.txt"], "traj_nan.txt", "line 7", id="trajectory-nan-row"),
    case(["{B}/traj_words.txt"], "traj_words.txt", "line 402", id="trajectory-words"),
    case(["{B}/atl03_truncated.h5"], "atl03_truncated.h5", id="atl03-truncated"),
    case(["{B}/atl03_badlat.h5"], "atl03_badlat.h5", "lat_ph", id="atl03-latitude-200"),
    case(["{B}/garbage.csd"], "garbage.csd", "Optech CSD", id="csd-garbage"),
    case(["{B}/truth_latin1.json"], "truth_latin1.json", id="json-not-utf8"),
    case([S1, "--time-system", "gps"], "--time-system", id="time-system-bogus"),
    case([S1, "--crs", "EPSG:0"], "--crs", id="crs-bogus"),
]


@pytest.mark.parametrize("args, messages", INFO)
def test_info(bad_input, args, messages):
    bad_input(["info", *args], 1, *messages)


INVERSE = [
    case(["--sensor", "{B}/sensor_nan.toml"], "sensor_nan.toml", "boresight_roll_deg", id="sensor-nan"),
    case(["--sensor", "{B}/sensor_inf.toml"], "sensor_inf.toml", "boresight_pitch_deg", id="sensor-inf"),
    case(["--sensor", "{B}/sensor_roll1e6.toml"], "sensor_roll1e6.toml", "boresight_roll_deg",
                 id="sensor-roll-1e6"),
    case(["--sensor", "{B}/sensor_scale.toml"], "sensor_scale.toml", "scale_ppm", id="sensor-scale-ppm"),
    case(["--sensor", "{B}/sensor_empty.toml"], "sensor_empty.toml", "missing", id="sensor-empty"),
    case(["--sensor", "{B}/sensor_string.toml"], "sensor_string.toml", "boresight_yaw_deg",
                 id="sensor-string"),
    case(["--sensor", "{B}/sensor_typo.toml"], "sensor_typo.toml", "boresight_yaw_dg", id="sensor-typo"),
    case(["--sensor", "{B}/sensor_missing.toml"], "sensor_missing.toml", "boresight_yaw_deg",
                 id="sensor-missing-key"),
    case(["--sensor", "{B}/sensor_lever2.toml"], "sensor_lever2.toml", "lever_arm_m", id="sensor-lever-2"),
    case(["--sensor", "{B}/sensor_lever_huge.toml"], "sensor_lever_huge.toml", "lever_arm_m",
                 id="sensor-lever-1e6"),
    case(["--sensor", "{B}/sensor_model.toml"], "sensor_model.toml", "spiral", id="sensor-model"),
    case(["--sensor", "{B}/sensor_syntax.toml"], "sensor_syntax.toml", id="sensor-syntax"),
    case(["--sensor", "{B}/sensor_latin1.toml"], "sensor_latin1.toml", "UTF-8", id="sensor-not-utf8"),
    case(["--sensor", "{B}/sensor_offset_nan.toml"], "sensor_offset_nan.toml", "offset_m",
                 id="sensor-offset-nan"),
    case(["--sensor", "{B}/sensor_crs.toml"], "sensor_crs.toml", "crs", id="sensor-crs"),
    case(["-t", "{B}/sbet_height1e9.out"], "sbet_height1e9.out", "height", id="sbet-height-1e9"),
    case(["-t", "{B}/sbet_roll50rad.out"], "sbet_roll50rad.out", "roll", id="sbet-roll-50rad"),
    case(["-t", "{B}/sbet_backwards.out"], "sbet_backwards.out", "time", id="sbet-time-backwards"),
    case(["-t", "{B}/sbet_short.out"], "sbet_short.out", id="sbet-not-covering"),
    case(["-t", "{B}/sbet_text.out"], "sbet_text.out", id="sbet-text"),
    case(["-t", "{B}/traj_latin1.txt"], "traj_latin1.txt", "UTF-8", id="trajectory-not-utf8"),
    case(["-t", SBET, "--trajectory-angles", "grad"], "--trajectory-angles", id="trajectory-angles"),
    case(["-t", SBET, "--trajectory-heading", "magnetic"], "--trajectory-heading", id="trajectory-heading"),
    case(["-t", "{B}/traj_nan.txt", "--trajectory-columns", "time,lat"], "traj_nan.txt",
         "columns: missing", id="trajectory-columns"),
    case(["-t", SBET, "--geoid-undulation", "47"], "--geoid-undulation", id="undulation-ellipsoidal-crs"),
    case(["-t", SBET, "--geoid-undulation", "nan"], "--geoid-undulation", id="undulation-nan"),
    case(["-t", SBET, "--geoid-undulation", "1e9"], "--geoid-undulation", id="undulation-huge"),
    case(["-t", SBET, "--time-system", "utc"], "--time-system", id="time-system"),
]


@pytest.mark.parametrize("extra, messages", INVERSE)
def test_inverse(bad_input, extra, messages):
    args = ["inverse", S1, "--out", "{O}.csv", *extra]
    if "-t" not in extra:
        args += ["-t", SBET]
    bad_input(args, 1, *messages)


POINTS = [
    case("{B}/nan_time.las", "nan_time.las", "gps_time", id="las-nan-times"),
    case("{B}/huge.las", "huge.las", id="las-coordinates-1e300"),
    case("{B}/count.las", "count.las", id="las-count-mismatch"),
    case("{B}/geoid.laz", "geoid.laz", "us_nga_egm08_25.tif", id="geoid-without-grid"),
]


@pytest.mark.parametrize("command", ["inverse", "regeoref"])
@pytest.mark.parametrize("points, messages", POINTS)
def test_bad_points(bad_input, command, points, messages):
    args = ["--out", "{O}.csv"] if command == "inverse" else ["--from", TOML, "--to", TOML, "--out", "{O}"]
    bad_input([command, points, "-t", SBET, *args], 1, *messages)


REGEOREF = [
    case(["--from", "{B}/sensor_nan.toml", "--to", TOML], "sensor_nan.toml", id="from-nan"),
    case(["--from", TOML, "--to", "{B}/sensor_empty.toml"], "sensor_empty.toml", id="to-empty"),
    case(["--from", TOML, "--to", "{B}/sensor_scale.toml"], "scale_ppm", id="to-scale"),
    case(["--from", TOML, "--to", TOML, "--to-trajectory", "{B}/sbet_roll50rad.out"], "sbet_roll50rad.out",
                 id="to-trajectory-roll"),
]


@pytest.mark.parametrize("extra, messages", REGEOREF)
def test_regeoref(bad_input, extra, messages):
    bad_input(["regeoref", S1, S2, "-t", SBET, *extra, "--out", "{O}"], 1, *messages)


@pytest.mark.parametrize("command", ["inverse", "regeoref"])
def test_trajectory_gap_is_not_bridged(bad_input, command):
    """Points amid 10 s without trajectory records are not interpolated across the gap."""
    args = ["--out", "{O}.csv"] if command == "inverse" else ["--from", TOML, "--to", TOML, "--out", "{O}"]
    bad_input([command, S2, "-t", "{B}/sbet_gap.out", *args], 1, "line_002.laz", "gap(s) without records")


def test_info_counts_nan_times(cli, corpus):
    """NaN GPS times are counted and left out of the time ranges (never "GPS time inf … -inf")."""
    code, out, err = cli(*corpus.args(["info", "{B}/nan_time.las"], corpus.root))
    assert code == 0, err
    assert "10 points have NaN/inf GPS times" in out and "inf …" not in out and "… -inf" not in out


@pytest.mark.parametrize("command", ["info", "inverse", "regeoref"])
def test_bracketed_file_names_are_printed_as_written(cli, corpus, tmp_path, command):
    """Rich markup never eats a file name's brackets ([b] would be bold)."""
    args = {"info": [], "inverse": ["-t", SBET, "--out", "{O}/x[y]z.csv"],
            "regeoref": ["-t", SBET, "--from", TOML, "--to", TOML, "--out", "{O}"]}[command]
    code, out, err = cli(*corpus.args([command, "{B}/a[b]c.laz", *args], tmp_path))
    assert code == 0, err
    assert ("a[b]c.laz" if command != "inverse" else "x[y]z.csv") in out


def test_geoid_undulation_is_the_escape(cli, corpus, tmp_path):
    """Heights above EGM2008 without its grid: an error naming the grid (above), or --geoid-undulation.
    geoid.laz holds the survey's ellipsoidal heights, so only N ≈ 0 keeps the geometry possible
    (N = 47 m puts the points 47 m up, 3 m below the UAV: test_bad_inputs_files checks that error)."""
    code, out, err = cli(*corpus.args(["inverse", "{B}/geoid.laz", "-t", SBET, "--out", "{O}/v.csv",
                                       "--geoid-undulation", "0.2"], tmp_path))
    assert code == 0, err
    assert (tmp_path / "v.csv").stat().st_size > 0


def test_regeoref_never_writes_over_its_inputs(bad_input):
    bad_input(["regeoref", S1, S2, "-t", SBET, "--from", TOML, "--to", TOML, "--out", "{S}/strips", "--force"], 1,
              "strips", "input")


def test_inverse_never_writes_over_its_inputs(bad_input):
    bad_input(["inverse", S1, "-t", SBET, "--out", S1, "--force"], 1, "line_001.laz", "input")
    bad_input(["inverse", S1, "-t", SBET, "--out", SBET, "--force"], 1, "sbet.out", "input")


GEOREF = [
    case(["{B}/garbage.csd", "--out", "{O}.laz"], "garbage.csd", id="csd-garbage"),
    case(["{B}/missing.csd", "--out", "{O}.laz"], "missing.csd", id="csd-missing"),
    case(["{B}/garbage.csd", "--out", "{B}/garbage.csd", "--force"], "garbage.csd", id="out-is-input"),
    case(["{B}/garbage.csd", "--out", "{O}.laz", "--geoid-undulation", "inf"], "--geoid-undulation",
                 id="undulation-inf"),
    case(["{B}/garbage.csd", "--out", "{O}.laz", "--crs", "EPSG:0"], "--crs", id="crs-bogus"),
    case(["{B}/garbage.csd", "--out", "{O}.laz", "--geoid-undulation", "1e9"], "--geoid-undulation",
         id="undulation-huge"),
    case(["{B}/garbage.csd", "--out", "{O}.laz", "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case(["{B}/garbage.csd", "--out", "{O}.laz", "--config", "{B}/georef_geoid.toml"],
         "georef_geoid.toml: geoid_undulation_m (--geoid-undulation): expected", id="config-undulation-huge"),
    case(["{B}/garbage.csd", "--out", "{O}.laz", "--config", "{B}/config_crs.toml"], "config_crs.toml: inputs: unknown key",
         id="config-of-boresight"),
]


@pytest.mark.parametrize("args, messages", GEOREF)
def test_georef(bad_input, args, messages):
    bad_input(["georef", *args], 1, *messages)


SENSOR_IMPORT = [
    case(["{B}/leeward_latin1.toml", "--from", "leeward"], "leeward_latin1.toml", "UTF-8", id="leeward-utf8"),
    case(["{B}/leeward_nan.toml", "--from", "leeward"], "leeward_nan.toml", "roll", id="leeward-nan"),
    case(["{B}/leeward_missing.toml", "--from", "leeward"], "leeward_missing.toml", "boresight",
                 id="leeward-missing"),
    case(["{B}/scan2imu_15.txt", "--from", "pdal-scan2imu"], "scan2imu_15.txt", "16", id="scan2imu-15"),
    case(["{B}/scan2imu_nan.txt", "--from", "pdal-scan2imu"], "scan2imu_nan.txt", id="scan2imu-nan"),
    case(["{B}/scan2imu_skew.txt", "--from", "pdal-scan2imu"], "scan2imu_skew.txt", "rotation",
                 id="scan2imu-not-rotation"),
    case(["{B}/garbage.csd", "--from", "optech-csd"], "garbage.csd", id="csd-garbage"),
    case(["{B}/scan2imu_15.txt", "--from", "riegl"], "--from", id="from-bogus"),
    case(["{B}/scan2imu_skew.txt", "--from", "pdal-scan2imu", "--scanner-axes", "x,x,z"], "--scanner-axes",
                 id="scanner-axes"),
    case(["{B}/leeward_missing.toml", "--from", "leeward", "--crs", "EPSG:0"], "--crs", id="crs-bogus"),
]


@pytest.mark.parametrize("args, messages", SENSOR_IMPORT)
def test_sensor_import(bad_input, args, messages):
    bad_input(["sensor", "import", *args, "--out", "{O}.toml"], 1, *messages)


def test_sensor_import_never_writes_over_its_input(bad_input):
    bad_input(["sensor", "import", "{B}/leeward_nan.toml", "--from", "leeward", "--out", "{B}/leeward_nan.toml",
               "--force"], 1, "leeward_nan.toml", "input")


def _commands(group, prefix=()):
    import typer.main

    cmd = typer.main.get_command(group)
    for name, sub in getattr(cmd, "commands", {}).items():
        yield (*prefix, name), sub
        if hasattr(sub, "commands"):
            for n, s in sub.commands.items():
                yield (*prefix, name, n), s


def test_every_command_is_in_the_corpus():
    """A new command comes with its bad-input cases: every command (leaf of ``calidar --help``) is
    covered by one of the corpus modules."""
    import test_bad_inputs_photon
    import test_bad_inputs_plan
    import test_bad_inputs_strips
    import test_bad_inputs_tools
    import test_bad_inputs_tpu
    import test_bad_inputs_trajectory

    leaves = {" ".join(n) for n, c in _commands(app) if not hasattr(c, "commands")}
    covered = (COMMANDS | test_bad_inputs_strips.COMMANDS | test_bad_inputs_photon.COMMANDS | test_bad_inputs_tools.COMMANDS
               | test_bad_inputs_trajectory.COMMANDS | test_bad_inputs_tpu.COMMANDS | test_bad_inputs_plan.COMMANDS)
    assert leaves - covered == set(), "commands without bad-input cases"


@pytest.mark.parametrize("command", sorted(" ".join(n) for n, _ in _commands(app)))
def test_help_shows_flags_as_flags(cli, command):
    code, out, _ = cli(*command.split(), "--help")
    assert code == 0
    assert "BOOLEAN" not in out and "<bool>" not in out.lower()
