"""The CLI imports only the module of the command it runs (issue 32): the name maps agree with
what each module registers, and a run of one command leaves the others unimported."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import pytest
import typer

from calidar import cli


def _registered(module: str) -> tuple[set[str], set[str]]:
    """(top-level commands and groups, simulate subcommands) that ``module`` registers alone."""
    app, simulate = typer.Typer(), typer.Typer()
    importlib.import_module(f"calidar.cli.{module}").register(app, simulate)
    top = {c.name for c in app.registered_commands} | {g.name for g in app.registered_groups}
    return top, {c.name for c in simulate.registered_commands}


def test_name_maps_match_what_modules_register() -> None:
    top: dict[str, str] = {}
    sim: dict[str, str] = {}
    for module in cli.COMMAND_MODULES:
        names, sims = _registered(module)
        top.update(dict.fromkeys(names, module))
        sim.update(dict.fromkeys(sims, module))
    assert top == cli.COMMAND_NAMES, "a command was added: list it in COMMAND_NAMES"
    assert sim == cli.SIMULATE_NAMES, "a simulate command was added: list it in SIMULATE_NAMES"


@pytest.mark.parametrize(("argv", "modules"), [
    (["quality", "a.laz", "--out", "x"], ["quality"]),
    (["boresight", "--help"], ["boresight"]),
    (["simulate", "survey", "--out", "x"], ["simulate_survey"]),
    (["simulate", "total-station", "--help"], ["rangecal"]),
    (["regeoref", "a.laz"], ["georef"]),
    (["scanner", "analyze"], ["scanner"]),
    (["--help"], None), ([], None), (["simulate", "--help"], None), (["nosuch"], None),
    (["--help", "quality"], None), (["simulate", "nosuch"], None),
])
def test_modules_for(argv: list[str], modules: list[str] | None) -> None:
    assert cli.modules_for(argv) == modules


def test_lazy_app_has_the_same_commands_as_the_whole_app() -> None:
    whole = typer.main.get_command(cli.app)
    for name, module in cli.COMMAND_NAMES.items():
        one = typer.main.get_command(cli.build_app([module]))
        assert name in one.commands
        a, b = one.commands[name], whole.commands[name]
        assert a.get_short_help_str(120) == b.get_short_help_str(120)
        assert [p.name for p in a.params] == [p.name for p in b.params]


_PROBE = """
import json, sys
from calidar.cli import run
code = run({argv!r})
print(json.dumps([code, sorted(m for m in sys.modules if m.startswith("calidar.cli.")
                              or m.split(".")[0] in ("matplotlib", "h5py"))]))
"""


@pytest.mark.parametrize(("argv", "expected"), [
    (["quality", "--help"], ["calidar.cli.common", "calidar.cli.options", "calidar.cli.quality"]),
    (["info", "--help"], ["calidar.cli.common", "calidar.cli.info", "calidar.cli.options"]),
])
def test_a_run_imports_its_command_only(argv: list[str], expected: list[str]) -> None:
    probe = [sys.executable, "-c", _PROBE.format(argv=argv)]
    out = subprocess.run(probe, capture_output=True, text=True, check=True).stdout
    code, modules = json.loads(out.strip().splitlines()[-1])
    assert code == 0
    assert [m for m in modules if m.startswith("calidar.cli.")] == sorted(expected), modules
    assert not [m for m in modules if not m.startswith("calidar.")], modules  # no matplotlib, h5py


def test_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.run(["--help"]) == 0
    text = capsys.readouterr().out
    for name in cli.COMMAND_NAMES:
        assert f" {name} " in text, name
