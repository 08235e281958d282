"""The public API (``calidar.<name>``): every name resolves, carries a docstring example, and the
examples run as doctests (on tiny simulated inputs, in a temporary folder)."""

from __future__ import annotations

import doctest
import importlib
import subprocess
import sys
import tempfile

import pytest

import calidar

NAMES = [n for n in calidar.__all__ if n != "__version__"]
MODULES = sorted({module for module, _ in calidar._API.values()})


def test_every_public_name_resolves_and_shows_an_example():
    for name in NAMES:
        obj = getattr(calidar, name)
        assert obj.__doc__ and ">>> " in obj.__doc__, f"calidar.{name} has no docstring example"
        assert obj.__module__ in MODULES, (name, obj.__module__)
    assert set(NAMES) <= set(dir(calidar))
    with pytest.raises(AttributeError, match="no attribute 'calibrate'"):
        calidar.calibrate  # noqa: B018


@pytest.mark.parametrize("module", MODULES)
def test_docstring_examples_run(module, tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the examples' tempfile.mkdtemp() land here
    mod = importlib.import_module(module)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, report=True)
    assert result.attempted > 0, f"{module}: no examples found"
    assert result.failed == 0, f"{module}: {result.failed} of {result.attempted} examples failed (see the output)"
    exported = [n for n, (m, _) in calidar._API.items() if m == module]
    finder = doctest.DocTestFinder()
    tested = {t.name.rsplit(".", 1)[-1] for t in finder.find(mod) if t.examples}
    for name in exported:
        assert calidar._API[name][1] in tested, f"calidar.{name}: its example is not among {module}'s doctests"


def test_import_calidar_stays_cheap():
    """``import calidar`` imports none of the public names' modules (nor numpy) until one is used."""
    code = ("import sys, calidar; heavy = [m for m in sys.modules if m == 'numpy' or m.startswith('calidar.')]; "
            "print(heavy); calidar.Sensor; print('calidar.sensor' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "[]" and out[1] == "True", out
