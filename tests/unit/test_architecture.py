"""The house rules of docs/architecture.md, checked on the source: layers run one way (the library
never imports the CLI), no import circles, small functions and modules."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "calidar"
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 400
MAX_LINE_CHARS = 100

#: Known breaches still being mended (each entry names its issue); the lists only shrink.
FUNCTION_ALLOWANCE: set[str] = set()  # issue 20
MODULE_ALLOWANCE: set[str] = set()  # issue 20
CLI_IMPORT_ALLOWANCE: set[str] = set()
#: Modules whose lines may still pass MAX_LINE_CHARS (issue 29: reshaped package by package; the list
#: only shrinks, and must stay empty). "calidar.x.*" names the package calidar.x and all under it; any other entry one module.
LINE_LENGTH_ALLOWANCE: set[str] = set()  # empty since the sixth session of 27 Nov: every module reshaped


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path) -> set[str]:
    """Every calidar module ``name`` imports, at module level or inside functions."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            found.add(base)
            found |= {f"{base}.{a.name}" for a in node.names}
    return {m for m in found if m == "calidar" or m.startswith("calidar.")}


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        deps = set()
        for m in _imports(name, path):
            while m not in mods and "." in m:  # `from calidar.x import name` names a module or an attribute
                m = m.rsplit(".", 1)[0]
            if m in mods and m != name:
                deps.add(m)
        graph[name] = deps
    return graph


def test_the_library_never_imports_the_cli():
    graph = _graph()
    up = {m for m, deps in graph.items() if not m.startswith("calidar.cli") and m != "calidar.__main__"
          and any(d.startswith("calidar.cli") for d in deps)}
    assert up <= CLI_IMPORT_ALLOWANCE, f"library modules importing calidar.cli: {sorted(up - CLI_IMPORT_ALLOWANCE)}"
    bench = [p.name for p in (ROOT / "benchmarks").glob("*.py") if "calidar.cli" in p.read_text(encoding="utf-8")
             and "calidar.cli" not in CLI_IMPORT_ALLOWANCE]
    assert not bench, f"benchmarks importing calidar.cli (call the pipelines instead): {bench}"


#: the layers, top to bottom (docs/architecture.md): a module may import its own layer and those below.
#: A module belongs to the layer of its longest matching prefix (the scanner models are core, their
#: structural-error analysis a method).
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("cli", ("calidar.cli", "calidar.__main__")),
    ("demo", ("calidar.demo",)),
    ("pipelines", ("calidar.pipelines",)),
    ("ingest", ("calidar.ingest",)),
    ("methods", ("calidar.strips", "calidar.accuracy", "calidar.rangecal", "calidar.photon", "calidar.sim", "calidar.tpu",
                 "calidar.trajrec", "calidar.planning", "calidar.scanners.analysis",
                 "calidar.scanners.separability", "calidar.scanners.settings", "calidar.scanners.sources",
                 "calidar.scanners.verdict", "calidar.scanners.figures",
                 "calidar.scanners.report")),
    ("io", ("calidar.io", "calidar.sensor_import")),
    ("core", ("calidar.georef", "calidar.crs", "calidar.cells", "calidar.sensor", "calidar.scanners", "calidar.trajectory",
              "calidar.frames", "calidar.trajectory_accuracy", "calidar.adjust", "calidar.report", "calidar.verdict", "calidar.provenance")),
    ("base", ("calidar.errors", "calidar.validate", "calidar.outputs", "calidar.interrupts", "calidar.run_lock",
              "calidar.memory")),
]


def _layer(module: str) -> int | None:
    """Index in LAYERS of ``module``'s layer (longest matching prefix), None when it has none."""
    found = [(len(p), k) for k, (_, prefixes) in enumerate(LAYERS) for p in prefixes
             if module == p or module.startswith(p + ".")]
    return max(found)[1] if found else None


def test_layers_run_one_way():
    graph = _graph()
    graph.pop("calidar")  # the package's face: the public API, imported lazily by name
    unplaced = sorted(m for m in graph if _layer(m) is None)
    assert not unplaced, f"modules in no layer (add them to LAYERS and docs/architecture.md): {unplaced}"
    up = sorted(f"{m} ({LAYERS[_layer(m)][0]}) imports {d} ({LAYERS[_layer(d)][0]})"
                for m, deps in graph.items() for d in deps if d != "calidar" and _layer(d) < _layer(m))
    assert not up, "imports pointing up a layer:\n" + "\n".join(up)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            # a package's __init__ re-exporting its modules is not a circle of design
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    graph = _graph()
    # a package's face (__init__) may re-export what its modules define: drop edges into a package's own face
    for m, deps in graph.items():
        graph[m] = {d for d in deps if not m.startswith(d + ".")}
    assert _cycles(graph) == []


def _long_functions() -> list[tuple[str, int]]:
    out = []
    for name, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    out.append((f"{name}:{node.name}", n))
    return out


def test_functions_are_short():
    long = [(f, n) for f, n in _long_functions() if f not in FUNCTION_ALLOWANCE]
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_modules_are_small():
    big = [(m, n) for m, p in _modules().items()
           if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES and m not in MODULE_ALLOWANCE]
    assert not big, f"modules over {MAX_MODULE_LINES} lines: {big}"


def _over_long(text: str) -> list[int]:
    """Numbers (from 1) of the lines of ``text`` over MAX_LINE_CHARS characters."""
    return [k for k, line in enumerate(text.splitlines(), 1) if len(line) > MAX_LINE_CHARS]


def _long_lines() -> dict[str, list[int]]:
    """Line numbers over MAX_LINE_CHARS characters, by module (only modules that have any)."""
    found = {name: _over_long(path.read_text(encoding="utf-8")) for name, path in _modules().items()}
    return {name: lines for name, lines in found.items() if lines}


def _line_allowed(module: str, entry: str) -> bool:
    """Whether the LINE_LENGTH_ALLOWANCE ``entry`` covers ``module``."""
    if entry.endswith(".*"):
        package = entry[:-2]
        return module == package or module.startswith(package + ".")
    return module == entry


def test_lines_are_short():
    """At most MAX_LINE_CHARS characters a line (docs/conventions.md, "Code layout"): a longer line is
    reshaped (name the intermediate value, split the function), not wrapped."""
    long = {m: lines for m, lines in _long_lines().items()
            if not any(_line_allowed(m, entry) for entry in LINE_LENGTH_ALLOWANCE)}
    assert not long, f"lines over {MAX_LINE_CHARS} characters (module: line numbers): {long}"


def test_the_line_rule_finds_what_it_looks_for():
    assert _line_allowed("calidar.io.las", "calidar.io.*") and _line_allowed("calidar.io", "calidar.io.*")
    assert not _line_allowed("calidar.iox", "calidar.io.*") and not _line_allowed("calidar.io.las", "calidar")
    text = "x = 1\n" + "y = '" + "é" * (MAX_LINE_CHARS - 6) + "'\n" + "z = '" + "é" * (MAX_LINE_CHARS - 5) + "'\n"
    assert _over_long(text) == [3]  # characters, not bytes: line 2 has exactly MAX_LINE_CHARS


@pytest.mark.parametrize("allowance", ["FUNCTION_ALLOWANCE", "MODULE_ALLOWANCE", "CLI_IMPORT_ALLOWANCE",
                                       "LINE_LENGTH_ALLOWANCE"])
def test_allowances_name_only_what_still_breaks(allowance):
    """An allowance entry that no longer breaks the rule must be removed (the lists only shrink)."""
    allowed = globals()[allowance]
    if allowance == "FUNCTION_ALLOWANCE":
        breaking = {f for f, _ in _long_functions()}
    elif allowance == "MODULE_ALLOWANCE":
        breaking = {m for m, p in _modules().items() if len(p.read_text(encoding="utf-8").splitlines()) > MAX_MODULE_LINES}
    elif allowance == "LINE_LENGTH_ALLOWANCE":
        long = _long_lines()
        breaking = {entry for entry in allowed if any(_line_allowed(m, entry) for m in long)}
    else:
        breaking = {m for m, deps in _graph().items() if any(d.startswith("calidar.cli") for d in deps)}
    assert allowed <= breaking, f"{allowance} names modules that now keep the rule: {sorted(allowed - breaking)}"


#: method and engine packages that write no file: outputs are written by pipelines/ (through io/)
NO_WRITE_PACKAGES = ("strips", "adjust", "photon", "rangecal", "planning", "scanners", "tpu")
#: modules that write scratch files of a run's temporary folder (never an output), by module:function
SCRATCH_ALLOWANCE = {"calidar.strips.cell_moments:save"}  # moments spilled to the streaming engine's temporary folder
_WRITE_CALLS = {"write_text", "write_bytes", "savefig", "savetxt", "savez", "savez_compressed", "to_csv", "tofile",
                "write_text_atomic", "atomic_path", "output_folder", "MemoryFile"}


def _write_mode(call: ast.Call) -> str:
    """The mode of an ``open(...)`` call when it is a constant ("r" when not given)."""
    mode = next((k.value for k in call.keywords if k.arg == "mode"), call.args[1] if len(call.args) > 1 else None)
    return mode.value if isinstance(mode, ast.Constant) and isinstance(mode.value, str) else "r"


def _scan(tree: ast.AST, on_import, on_call) -> list[tuple[int, str, str]]:
    """(line, enclosing function, what) of each import and call of a module's syntax tree that
    ``on_import(modules)`` / ``on_call(call, name, owner)`` name (a string; None: not a hit)."""
    found = []

    def visit(node, where):
        for child in ast.iter_child_nodes(node):
            inner = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else where
            what = None
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                mods = [a.name for a in child.names] if isinstance(child, ast.Import) else [child.module or ""]
                what = on_import(mods)
            elif isinstance(child, ast.Call):
                f = child.func
                name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
                owner = f.value.id if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) else ""
                what = on_call(child, name, owner)
            if what:
                found.append((child.lineno, where, what))
            visit(child, inner)

    visit(tree, "")
    return found


def _write_call(call: ast.Call, name: str, owner: str) -> str | None:
    if name == "open" and set(_write_mode(call)) & set("wax+"):
        return f"open(..., {_write_mode(call)!r})"
    if name in _WRITE_CALLS or (name == "save" and owner in ("np", "numpy")) \
            or (name == "dump" and owner in ("json", "pickle")) \
            or (name == "write" and "report" in owner.lower()):
        return f"{owner + '.' if owner else ''}{name}"
    return None


def _file_writes(tree: ast.AST) -> list[tuple[int, str, str]]:
    """(line, enclosing function, what) of each file write in a module's syntax tree: ``open`` (builtin,
    laspy's, rasterio's) in a writing mode, pathlib/matplotlib/numpy/pandas writers, ``json``/``pickle``
    ``dump`` to a file, the atomic writers of :mod:`calidar.outputs` (and importing that module), a
    report's ``write``."""
    return _scan(tree, lambda mods: "imports calidar.outputs" if "calidar.outputs" in mods else None,
                 _write_call)


def test_the_write_scan_finds_what_it_looks_for():
    source = '''
import json
from calidar.outputs import atomic_path
def a(p, fig, doc, report):
    with open(p, "w") as f:
        json.dump(doc, f)
    open(p, mode="ab")
    open(p)
    p.write_text("x")
    fig.savefig(p)
    report.write(p)
    laspy.open(p, mode="w")
    rasterio.open(p, "r")
'''
    found = _file_writes(ast.parse(source))
    assert [w for _, _, w in found] == ["imports calidar.outputs", "open(..., 'w')", "json.dump", "open(..., 'ab')",
                                        "p.write_text", "fig.savefig", "report.write", "open(..., 'w')"]
    assert [line for line, _, _ in found] == [3, 5, 6, 7, 9, 10, 11, 12]  # open(p) and rasterio's read: not writes
    assert {where for _, where, _ in found} == {"", "a"}


#: modules that read back scratch files of a run's temporary folder (never an input), by module:function
READ_SCRATCH_ALLOWANCE = {"calidar.strips.cell_moments:load"}  # the moments cell_moments:save spilled
#: calls that open or read a file: builtin/laspy/rasterio/h5py open, numpy's and pandas' readers, csv readers,
#: pathlib's read_text/read_bytes, and every ``read_…`` function (calidar.validate.read_text, the io readers)
_READ_CALLS = {"open", "File", "loadtxt", "genfromtxt", "fromfile", "memmap", "reader", "DictReader", "imread",
               "read_text", "read_bytes"}
_READ_MODULES = ("csv", "h5py", "laspy", "rasterio", "tomllib", "pandas")


def _read_import(mods: list[str]) -> str | None:
    hit = [m for m in mods if m.split(".")[0] in _READ_MODULES]
    return f"imports {hit[0]}" if hit else None


def _read_call(call: ast.Call, name: str, owner: str) -> str | None:
    if name in _READ_CALLS or name.startswith("read_") \
            or (name == "load" and owner in ("np", "numpy", "json", "pickle", "tomllib")) \
            or (name == "read" and (owner == "laspy" or owner[:1].isupper())):
        return f"{owner + '.' if owner else ''}{name}"
    return None


def _file_reads(tree: ast.AST) -> list[tuple[int, str, str]]:
    """(line, enclosing function, what) of each file read in a module's syntax tree: the calls of
    :data:`_READ_CALLS`, any ``read_…`` function, ``np.load``/``json.load``/``pickle.load``/``tomllib.load``, a
    class's or laspy's ``read``, and importing a file-format module (:data:`_READ_MODULES`)."""
    return _scan(tree, _read_import, _read_call)


def test_the_read_scan_finds_what_it_looks_for():
    source = '''
import csv
import numpy as np
def a(p, q):
    with open(p) as f:
        f.read()
    np.loadtxt(p)
    np.load(p)
    q.read_text()
    read_las(p)
    laspy.open(p)
    h5py.File(p, "r")
    Sensor.read(p)
    csv.reader(f)
    np.loadtxts(p)
    ns.read(p)
    np.save(p, q)
'''
    found = _file_reads(ast.parse(source))
    assert [w for _, _, w in found] == ["imports csv", "open", "np.loadtxt", "np.load", "q.read_text", "read_las",
                                        "laspy.open", "h5py.File", "Sensor.read", "csv.reader"]
    assert [line for line, _, _ in found] == [2, 5, 7, 8, 9, 10, 11, 12, 13, 14]  # f.read(), ns.read, np.save: not
    assert {where for _, where, _ in found} == {"", "a"}


#: the two scans of the method layer's file access: (the scan, its allowance of a run's scratch
#: files by module:function, where the access belongs instead)
FILE_SCANS = {
    "writes": (_file_writes, SCRATCH_ALLOWANCE, "move them to io/ and pipelines/"),
    "reads": (_file_reads, READ_SCRATCH_ALLOWANCE, "move them to io/, called from pipelines/"),
}


def _scan_modules(scan, packages=None) -> list[tuple[str, int, str, str]]:
    """(module, line, enclosing function, what) of every hit of ``scan`` in the modules (of the
    ``packages`` only, e.g. NO_WRITE_PACKAGES, when given)."""
    return [(name, line, where, what) for name, path in _modules().items()
            if packages is None or name.split(".")[1:2] and name.split(".")[1] in packages
            for line, where, what in scan(ast.parse(path.read_text(encoding="utf-8")))]


@pytest.mark.parametrize("kind", FILE_SCANS)
def test_methods_touch_no_file(kind):
    """strips, adjust, photon, rangecal, planning, scanners and tpu compute on what they are given:
    pipelines/ read the files (through io/) and write the results; no module of theirs opens a
    file, for reading or for writing (a run's scratch files aside: the allowances)."""
    scan, allowance, instead = FILE_SCANS[kind]
    found = [f"{name}:{where} line {line}: {what}"
             for name, line, where, what in _scan_modules(scan, NO_WRITE_PACKAGES)
             if f"{name}:{where}" not in allowance]
    assert not found, f"file {kind} in the method layer ({instead}):\n" + "\n".join(found)


@pytest.mark.parametrize("kind", FILE_SCANS)
def test_scratch_allowances_name_only_what_still_does_it(kind):
    scan, allowance, _ = FILE_SCANS[kind]
    hits = {f"{name}:{where}" for name, _, where, _ in _scan_modules(scan)}
    assert allowance <= hits, f"the allowance of scratch {kind} names what {kind} no more: " \
                              f"{sorted(allowance - hits)}"
