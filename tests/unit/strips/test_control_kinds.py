"""Kinds of ground control are objects (issue 29): a new kind is one module implementing the kinds'
protocol (:class:`calidar.strips.control.ControlPoints`'s attributes and methods) plus its name in the
configuration (:data:`calidar.strips.config.CONTROL_KINDS`); the pipeline reads its file, the calibrator
takes its rows, the verdict and the report word it without a change, and no module branches on a kind's
name. The end-to-end run of the double: tests/acceptance/test_control_kind_double.py."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from calidar.strips import config as strip_config
from control_double import SurveyedMarks, write_marks

SRC = Path(__file__).resolve().parents[3] / "src" / "calidar"
#: the kinds' own modules and the configuration that registers them
OWN = {"strips/control.py", "strips/control_planes.py", "strips/control_cloud.py", "strips/config.py"}


@pytest.fixture
def registered(monkeypatch):
    """The configuration's one change: the new kind's name."""
    monkeypatch.setitem(strip_config.CONTROL_KINDS, SurveyedMarks.kind, SurveyedMarks)


def _kind_branches(tree: ast.AST, names: set[str]) -> list[str]:
    """Where a module compares a kind (``kind``, ``x.kind``, ``x.get("kind")``) with a kind's name, indexes the
    registry by one, or keys a dict literal by two or more of them."""
    def mentions_kind(node) -> bool:
        return any((isinstance(n, ast.Name) and "kind" in n.id) or (isinstance(n, ast.Attribute) and n.attr == "kind")
                   or (isinstance(n, ast.Constant) and n.value == "kind") for n in ast.walk(node))

    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(isinstance(n, ast.Constant) and n.value in names for n in sides) and any(map(mentions_kind, sides)):
                found.append(f"{node.lineno}: compares a kind")
        elif isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "CONTROL_KINDS" \
                and isinstance(node.slice, ast.Constant):
            found.append(f"{node.lineno}: CONTROL_KINDS[{node.slice.value!r}]")
        elif isinstance(node, ast.Dict):
            keys = {k.value for k in node.keys if isinstance(k, ast.Constant)}
            if len(keys & names) >= 2:
                found.append(f"{node.lineno}: a dict by kind")
    return sorted(found, key=lambda f: int(f.split(":")[0]))


def test_the_kind_scan_finds_what_it_looks_for():
    source = '''
planes = kind != "points"
what = {"points": "a", "cloud": "b"}.get(kind)
ok = control.get("kind", "points") == "points" or control.get("kind") == "cloud"
planes = CONTROL_KINDS["surfaces"].from_file(f)
rows = {"points": [], "strips": []}
same = name == "points"
'''
    assert _kind_branches(ast.parse(source), set(strip_config.CONTROL_KINDS)) == [
        "2: compares a kind", "3: a dict by kind", "4: compares a kind", "4: compares a kind",
        "5: CONTROL_KINDS['surfaces']"]


def test_no_module_branches_on_a_control_kinds_name():
    names = set(strip_config.CONTROL_KINDS)
    found = {p.relative_to(SRC).as_posix(): f for p in sorted(SRC.rglob("*.py"))
             if p.relative_to(SRC).as_posix() not in OWN
             and (f := _kind_branches(ast.parse(p.read_text(encoding="utf-8")), names))}
    assert found == {}, f"branches on a control kind's name (give the kind the behaviour instead): {found}"


def test_every_kind_implements_the_protocol():
    from calidar.strips.control import ControlPoints

    attributes = ("kind", "label", "words", "row_noun", "dz_meaning", "how_to_give", "reaches_beyond_strips",
                  "accepts", "reader", "takes_sigma", "notes", "keep_xy", "rows", "survey_parameters", "survey_design")
    for name, kind in strip_config.CONTROL_KINDS.items():
        assert kind.kind == name and all(hasattr(kind, a) for a in attributes), name
        assert kind is ControlPoints or kind.reader is not None, f"{name}: no reader"
    assert [k for k in strip_config.CONTROL_KINDS.values() if k.accepts is None] == [ControlPoints]


def test_the_pipeline_reads_a_new_kinds_file_through_its_reader(registered, tmp_path):
    from calidar.pipelines.control import control_kind_of, control_points, read_control
    from calidar.strips.strip import LocalFrame

    xyz = np.array([[500010.0, 5200020.0, 101.0], [500060.0, 5200080.0, 103.0], [500110.0, 5200030.0, 99.5]])
    path = write_marks(tmp_path / "ground.marks", ["M1", "M2", "M3"], xyz, [0.01, 0.02, 0.01])
    assert control_kind_of(path) is SurveyedMarks
    read = read_control(path, None, ("EPSG:32632", None))
    assert read.kind == "marks" and read.notes == ("3 surveyed marks read from ground.marks",)
    frame = LocalFrame.at(read.survey_ecef)
    marks = control_points(read, frame)
    assert isinstance(marks, SurveyedMarks) and list(marks.ids) == ["M1", "M2", "M3"]
    np.testing.assert_allclose(frame.to_ecef(marks.local), read.survey_ecef, atol=1e-6)
    np.testing.assert_allclose(marks.sigma_m, [0.01, 0.02, 0.01])
    with pytest.raises(Exception, match="--control-sigma"):  # its kind takes no --control-sigma
        read_control(path, None, ("EPSG:32632", None), sigma_m=0.02)


def test_the_verdict_and_report_word_a_new_kind_from_its_class(registered):
    from calidar.report import Report
    from calidar.strips.control_verdict import control_finding, words
    from calidar.strips.report import _control_part

    control = {"kind": "marks", "label": "surveyed marks", "n_points": 3, "n_used": 2, "n_rows": 2,
               "not_covered": ["M3"], "rms_dz_before_m": 0.05, "rms_dz_after_m": 0.01,
               "points": [{"id": "M1", "strip": 1, "dz_before_m": 0.05, "dz_after_m": 0.01, "sigma_m": 0.01},
                          {"id": "M2", "strip": 2, "dz_before_m": -0.04, "dz_after_m": -0.01, "sigma_m": 0.01}]}
    assert words(control) == "surveyed marks (the test double)"
    assert strip_config.control_action().endswith("; or marks: a JSON file of id, x, y, z, sigma)")
    finding = control_finding(control)
    assert finding.status == "warn" and "2 of 3 surveyed marks" in finding.detail  # M3 not covered
    section = Report("test").section("control")
    _control_part(section, control)
    text = " ".join(str(b) for b in section.blocks)
    assert "the test double&#x27;s words" in text and ">mark</th>" in text  # its words, its table's first column
