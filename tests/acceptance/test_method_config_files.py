"""Every command's ``--config`` (issue 29), one parametrized test: a run writes its configuration beside
its results (config.toml, or <name>.config.toml beside a command's one output file), that file given
back with --config repeats the run exactly (the same outputs), an option given with it replaces the
file's setting and keeps the others, and a bad value in such a file is one line naming the file, the
key and its option, exit 1, nothing written."""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
import pytest

HEADER = "line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps\n"
LINES = HEADER + "1,-30,-60,-30,60,80,8\n2,-30,60,-30,-60,80,8\n3,30,-60,30,60,80,8\n4,30,60,30,-60,80,8\n"


@dataclass(frozen=True)
class Case:
    """One command: its inputs ({S} survey, {P} photons, {T} total-station, {W} the test's folder, {R} real
    data), the options of its first run, what that run's config.toml must hold, the outputs compared,
    an option given with --config (its key's new value, and a key whose file value stays), and a bad
    file with the key and option its error must name."""

    command: tuple[str, ...]
    inputs: tuple[str, ...]
    options: tuple[str, ...]
    written: dict  #: {dotted key: value} the first run's config.toml holds
    outputs: tuple[str, ...]  #: files compared (JSON without its run record; others byte for byte)
    override: tuple[tuple[str, ...], dict] | None  #: (an option, {dotted key: value} afterwards)
    bad: tuple[str, str]  #: (a bad config file's text, "key (--option)" its error names)
    file_out: str | None = None  #: the command writes one file (else a folder): its name
    codes: tuple[int, ...] = (0, 3)
    marks: tuple = field(default_factory=tuple)


CASES = [
    Case(("range-cal",), ("{T}/observations.csv", "--truth", "{T}/truth.json"), ("--tolerance", "0.05", "--fix-scale"),
         {"tolerance_m": 0.05, "fix_scale": True}, ("solution.json",), (("--tolerance", "0.02"), {"tolerance_m": 0.02,
                                                                                                 "fix_scale": True}),
         ("tolerance_m = -1.0\n", "tolerance_m (--tolerance)")),
    Case(("ccr",), ("{P}/ATL03_sim.h5", "--ccr", "{P}/ccr.csv"), ("--bootstrap", "0", "--diameter-range", "9,14"),
         {"beams": "all", "search.bootstrap": 0, "search.diameter_min": 9.0, "search.diameter_max": 14.0},
         ("solution.json",), (("--seed", "5"), {"search.seed": 5, "search.diameter_min": 9.0}),
         ('[search]\ndiameter_step = 5.0\n', "search.diameter_step (--diameter-step)")),
    Case(("tpu",), ("{S}/strips/line_001.laz", "-t", "{S}/sbet.out", "--sensor", "{S}/sensor.toml"),
         ("--range-sigma", "0.02", "--trajectory-sigma", "0.05,0.005"),
         {"noise.range_sigma_m": 0.02, "trajectory_sigma": [0.05, math.radians(0.005)]}, ("tpu.json",),
         (("--beam-divergence", "0"), {"noise.beam_divergence_rad": 0.0, "noise.range_sigma_m": 0.02}),
         ("[noise]\nrange_sigma_m = -0.01\n", "noise.range_sigma_m (--range-sigma)")),
    Case(("quality",), ("{S}/strips/line_001.laz", "{S}/strips/line_002.laz"), ("--cell", "3", "--classes", "2,6"),
         {"cell_m": 3.0, "classes": [2, 6]}, ("quality.json",), (("--cell", "4"), {"cell_m": 4.0, "classes": [2, 6]}),
         ("cell_m = 0.0\n", "cell_m (--cell)")),
    Case(("accuracy",), ("{S}/strips/line_001.laz", "--checkpoints", "{W}/checkpoints.csv"),
         ("--radius", "8", "--survey-sigma", "0.03"), {"radius_m": 8.0, "survey_sigma_m": 0.03}, ("accuracy.json",),
         (("--radius", "6"), {"radius_m": 6.0, "survey_sigma_m": 0.03}), ("radius_m = 1e6\n", "radius_m (--radius)")),
    Case(("plan",), ("{W}/lines.csv", "--sensor", "{S}/sensor.toml"), ("--fov", "60", "--no-suggest"),
         {"fov_deg": 60.0, "suggest": False, "terrain.kind": "flat"}, ("plan.json",),
         (("--pulse-rate", "30000"), {"pulse_rate_hz": 30000.0, "fov_deg": 60.0}),
         ('estimate = ["heading"]\n', "estimate (--estimate)")),
    Case(("scanner", "analyze"), (), ("--model", "palmer", "--range", "150", "--delta-l", "0.01"),
         {"model": "palmer", "range_m": 150.0, "errors.delta_l_deg": 0.01}, ("summary.json",),
         (("--range", "120"), {"range_m": 120.0, "errors.delta_l_deg": 0.01}),
         ('model = "palmer"\nrange_m = -5.0\n', "range_m (--range)")),
    Case(("denoise",), ("{P}/ATL03_sim.h5",), ("--beam", "GT1L"), {"beams": ["gt1l"], "shot_spacing_m": 0.7},
         ("photons.csv",), (("--shot-spacing-m", "0.8"), {"shot_spacing_m": 0.8, "beams": ["gt1l"]}),
         ('beams = ["gt9x"]\n', "beams (--beam)"), file_out="photons.csv", codes=(0,)),
    Case(("georef",), ("{R}/optech_csd/sample.csd",), ("--crs", "EPSG:32611+3855", "--geoid-undulation", "-30"),
         {"crs": "EPSG:32611+3855", "geoid_undulation_m": -30.0}, ("points.las",),
         (("--geoid-undulation", "-25"), {"crs": "EPSG:32611+3855", "geoid_undulation_m": -25.0}),
         ("geoid_undulation_m = 1e6\n", "geoid_undulation_m (--geoid-undulation)"), file_out="points.las", codes=(0,)),
    Case(("trajectory",), ("{S}/strips/line_001.laz",), ("--rate", "20", "--encoder-sigma", "0.2,0.3"),
         {"rate_hz": 20.0, "mount_sigma.scan_offset_rad": math.radians(0.2)}, ("trajectory.csv",), None,
         ("[mount_sigma]\nscan_scale = -1.0\n", "mount_sigma.scan_scale (--encoder-sigma)"), file_out="trajectory.csv",
         codes=(0,), marks=(pytest.mark.slow,)),
]


def _key(doc: dict, dotted: str):
    for part in dotted.split("."):
        doc = doc[part]
    return doc


def _outputs(case: Case, out: Path) -> dict:
    folder = out.parent if case.file_out else out
    found = {}
    for name in case.outputs:
        if name.endswith(".json"):
            doc = json.loads((folder / name).read_text())
            doc.pop("run", None)
            found[name] = doc
        else:
            found[name] = (folder / name).read_bytes()
    return found


def _config_of(case: Case, out: Path) -> Path:
    return out.with_name(out.stem + ".config.toml") if case.file_out else out / "config.toml"


def _inputs(corpus, tmp_path: Path, case: Case, real: Path | None) -> list[str]:
    if case.command == ("accuracy",):
        _checkpoints(corpus.root / "survey" / "strips" / "line_001.laz", tmp_path / "checkpoints.csv")
    (tmp_path / "lines.csv").write_text(LINES)
    r = corpus.root
    return [a.format(S=r / "survey", P=r / "photons", T=r / "total-station", W=tmp_path, R=real) for a in case.inputs]


def _checkpoints(strip: Path, path: Path) -> None:
    """Thirty of the strip's ground points, spread along it, as non-vegetated checkpoints."""
    import laspy
    import numpy as np

    las = laspy.read(strip)
    ground = np.flatnonzero(np.asarray(las.classification) == 2)
    pick = ground[np.linspace(0, len(ground) - 1, 30).astype(int)]
    x, y, z = (np.asarray(v)[pick] for v in (las.x, las.y, las.z))
    rows = [f"C{k},{x[k]:.3f},{y[k]:.3f},{z[k]:.3f},non-vegetated" for k in range(len(pick))]
    path.write_text("id,x,y,z,class\n" + "\n".join(rows) + "\n")


@pytest.mark.parametrize("case", [pytest.param(c, id=" ".join(c.command), marks=c.marks) for c in CASES])
def test_every_command_repeats_from_its_config_toml(cli, corpus, tmp_path, request, case):
    real = request.getfixturevalue("real_data") if any("{R}" in a for a in case.inputs) else None
    inputs = _inputs(corpus, tmp_path, case, real)

    def out(name: str) -> Path:
        return tmp_path / name / case.file_out if case.file_out else tmp_path / name

    def run(name: str, *extra) -> Path:
        code, _, err = cli(*case.command, *inputs, *extra, "--out", out(name))
        assert code in case.codes, err
        return _config_of(case, out(name))

    written = tomllib.loads(run("a", *case.options).read_text())
    for key, value in case.written.items():
        assert _key(written, key) == pytest.approx(value), key
    again = run("b", "--config", _config_of(case, out("a")))
    assert _outputs(case, out("a")) == _outputs(case, out("b"))
    assert tomllib.loads(again.read_text()) == written
    if case.override is not None:
        option, expected = case.override
        changed = tomllib.loads(run("c", "--config", _config_of(case, out("a")), *option).read_text())
        for key, value in expected.items():
            assert _key(changed, key) == pytest.approx(value), key

    bad = tmp_path / "mine.toml"
    bad.write_text(case.bad[0])
    code, _, err = cli(*case.command, *inputs, "--config", bad, "--out", out("d"))
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 1 and len(lines) == 1, err
    assert lines[0].startswith(f"error: {bad}: {case.bad[1]}: expected"), lines[0]
    assert not out("d").exists() and not _config_of(case, out("d")).exists()


def test_every_command_with_a_config_file_is_here():
    """Each command with a --config option (but boresight: tests/acceptance/test_boresight_config.py) is a case."""
    import typer.main

    from calidar.cli import app

    def leaves(group, prefix=()):
        for name, cmd in typer.main.get_command(group).commands.items() if prefix == () else group.commands.items():
            if hasattr(cmd, "commands"):
                yield from leaves(cmd, (*prefix, name))
            else:
                yield (*prefix, name), cmd

    with_config = {" ".join(n) for n, c in leaves(app) if any("--config" in p.opts for p in c.params)}
    assert with_config - {"boresight"} == {" ".join(c.command) for c in CASES}
