"""A self-contained HTML report (plots embedded as PNG data URIs, no external assets).

>>> import tempfile
>>> from pathlib import Path
>>> import numpy as np
>>> from calidar.adjust import FunctionProblem, Parameter, ParameterSet, SolverOptions, solve
>>> from calidar.report.plots import plt
>>> roll = ParameterSet([Parameter("boresight_roll", 0.0, "rad")])
>>> observed = np.array([3.1e-4, 2.9e-4])
>>> problem = FunctionProblem(lambda v: v["boresight_roll"] - observed, roll, sigma=1e-4)
>>> solution = solve(problem, SolverOptions(robust=None))
>>> rep = Report("calidar demo")
>>> sec = rep.section("Boresight from tie planes")
>>> sec.text("12 strips, 8 overlapping pairs.")
>>> sec.solution(solution, truth={"boresight_roll": 0.0003})   # parameter table
>>> fig, ax = plt.subplots()
>>> _ = ax.plot([1, 2], [0.03, 0.01])
>>> sec.figure(fig, "Residuals before/after")
>>> rep.write(Path(tempfile.mkdtemp()) / "report.html").name
'report.html'
"""

from __future__ import annotations

import base64
import html
import io
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from calidar import __version__
from calidar.outputs import shown_path, write_text_atomic
from calidar.provenance import RunRecord

#: a command-line option in prose (--all-classes, --method planes): kept on one line, since
#: browsers may break a line after a hyphen
_OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9]*(?:-[a-z0-9]+)*")


def prose(text: str) -> str:
    """``text`` escaped for HTML, its command-line options unbroken (``<span class="opt">``)."""
    return _OPTION.sub(lambda m: f'<span class="opt">{m.group(0)}</span>', html.escape(text))


_CSS = (
    "\n"
    "body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;"
    "margin:2em auto;padding:0 1em;color:#222}\n"
    "h1{border-bottom:2px solid #246;padding-bottom:.2em} h2{color:#246;margin-top:2em;"
    "border-bottom:1px solid #ccd}\n"
    "table{border-collapse:collapse;margin:1em 0;font-size:.92em}"
    " th,td{border:1px solid #ccd;padding:.3em .6em;text-align:right}\n"
    "th{background:#eef2f8} td.l,th.l{text-align:left} .warn{background:#fff4e0;"
    "border-left:4px solid #e90;padding:.5em 1em;margin:.5em 0}\n"
    ".ok{color:#070} .bad{color:#b00} figure{margin:1em 0} figcaption{font-size:.9em;"
    "color:#555} img{max-width:100%}\n"
    "nav ul{columns:2} .meta{color:#666;font-size:.9em} .opt{white-space:nowrap}\n"
    "pre{background:#f4f6fa;border:1px solid #dde;padding:.5em .8em;overflow-x:auto;"
    "white-space:pre-wrap;word-break:break-all}\n"
    "caption{caption-side:top;text-align:left;color:#555;font-size:.9em;padding:.2em 0}"
    " .refs{font-size:.9em}\n"
    ".verdict{border:2px solid #888;border-radius:6px;padding:.6em 1em;margin:1em 0}\n"
    ".verdict h3{margin:.1em 0 .4em 0} .verdict ul{margin:.2em 0;padding-left:1.2em}"
    " .verdict li{margin:.25em 0}\n"
    ".v-pass{border-color:#2a7;background:#effaf3} .v-warn{border-color:#e90;"
    "background:#fff8ec} .v-fail{border-color:#c33;background:#fdeeee}\n"
    ".tag{display:inline-block;min-width:3.2em;text-align:center;font-weight:600;"
    "border-radius:3px;padding:0 .3em;margin-right:.4em;color:#fff}\n"
    ".t-pass{background:#2a7} .t-warn{background:#d80} .t-fail{background:#c33}"
    " .t-note{background:#47a} .action{color:#333;font-style:italic}\n"
)


def _align(column: int) -> str:
    """A table cell's class: "l" (left-aligned) for the first column, the labels."""
    return "l" if column == 0 else ""


def _row_html(row: list, formats: list) -> str:
    """One table row, each cell formatted with its column's spec."""
    cells = "".join(f'<td class="{_align(i)}">{_fmt(c, spec=formats[i])}</td>'
                    for i, c in enumerate(row))
    return f"<tr>{cells}</tr>"


def _fmt(v, digits: int = 6, spec: str | None = None) -> str:
    """A table cell: numbers with ``spec`` (or ``digits`` significant digits), never "-0"."""
    if v is None:
        return "—"
    if isinstance(v, (int, np.integer)) and not spec:
        return str(int(v))
    if isinstance(v, (float, np.floating, int, np.integer)):
        if not np.isfinite(v):
            return "∞" if v > 0 else ("−∞" if v < 0 else "—")
        text = f"{v:{spec}}" if spec else f"{v:.{digits}g}"
        return text[1:] if text.startswith("-") and float(text) == 0 else text
    return html.escape(str(v))


@dataclass
class Section:
    """One section: blocks of HTML in the order added."""

    title: str
    blocks: list[str] = field(default_factory=list)

    def text(self, paragraph: str) -> None:
        self.blocks.append(f"<p>{prose(paragraph)}</p>")

    def heading(self, text: str) -> None:
        """A sub-heading inside the section."""
        self.blocks.append(f"<h3>{html.escape(text)}</h3>")

    def code(self, text: str, caption: str | None = None) -> None:
        """A command or other literal text, in a copyable block (``caption`` before it)."""
        cap = f"<p>{html.escape(caption)}</p>" if caption else ""
        self.blocks.append(f"{cap}<pre><code>{html.escape(text)}</code></pre>")

    def references(self, items: list[str]) -> None:
        """A numbered list of cited works."""
        listed = "".join(f"<li>{html.escape(r)}</li>" for r in items)
        self.blocks.append(f'<ol class="refs">{listed}</ol>')

    def warning(self, message: str) -> None:
        self.blocks.append(f'<div class="warn">⚠ {prose(message)}</div>')

    def table(self, header: list[str], rows: list[list], caption: str | None = None,
              formats: list | None = None) -> None:
        """A table; the first column is left-aligned (labels). ``formats``: per column a format
        spec for numbers (e.g. ".1f"; a fixed-point zero is never shown as -0) or None (general)."""
        head = "".join(f'<th class="{_align(i)}">{html.escape(str(h))}</th>'
                       for i, h in enumerate(header))
        fmts = list(formats or []) + [None] * len(header)
        body = "".join(_row_html(r, fmts) for r in rows)
        cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
        table = f"<thead><tr>{head}</tr></thead><tbody>{body}</tbody>"
        self.blocks.append(f"<table>{cap}{table}</table>")

    def solution(self, solution, truth: dict[str, float] | None = None,
                 hidden_prefix: str | None = None, residual_unit: str = "m",
                 residual_factor: float = 1.0) -> None:
        """Parameter table (estimate, σ, truth and error when known, each with its unit, digits
        from σ) and diagnostics; parameters whose names start with ``hidden_prefix`` (default: the
        solution's nuisance prefix) are counted, not listed. Residuals are shown
        × ``residual_factor`` in ``residual_unit`` (e.g. 1e3 and "mm" for residuals in metres)."""
        doc = solution.to_dict(truth)
        hidden_prefix = hidden_prefix or solution.nuisance_prefix
        hidden = [n for n in doc["parameters"] if hidden_prefix and n.startswith(hidden_prefix)]
        if hidden:
            # one prefix or several
            shown = (hidden_prefix,) if isinstance(hidden_prefix, str) else hidden_prefix
            prefixes = ", ".join(p + "*" for p in shown)
            self.text(f"{len(hidden)} {prefixes} parameters are estimated too; "
                      "solution.json lists them.")
        rows = [[name, *parameter_cells(p)] for name, p in doc["parameters"].items()
                if name not in hidden]
        header = ["parameter", "estimate", "σ", "status", "truth", "error", "|error| / σ"]
        keep = len(header) if truth else 4  # no truth: no truth, error or |error|/σ columns
        self.table(header[:keep], [r[:keep] for r in rows])
        self._residuals(doc["residuals"], residual_unit, residual_factor)
        solver = "converged" if doc["converged"] else "did NOT converge"
        # a robust fit's engine σ0 is not what its global test reads (calidar.strips.global_test)
        which = (" from the robustly weighted residuals (the verdict's global test says how it is "
                 "read)" if "unit_weight" in doc else "")
        self.text(f"σ0 = {doc['sigma0']:.3f}{which}, redundancy {doc['dof']:.0f}, condition number "
                  f"{doc['condition_number']:.3g}; the solver {solver} in "
                  f"{len(doc['history']) - 1} iterations.")
        for w in doc["warnings"]:
            self.warning(w)

    def _residuals(self, residuals: dict, unit: str, factor: float) -> None:
        """The residual table of solution.json's ``residuals`` (before, after), shown × ``factor``
        in ``unit``."""
        u = f" [{unit}]" if unit else ""
        rows = []
        for label in ("before", "after"):
            r = residuals[label]
            statistics = (r.get(k) for k in ("rms", "median", "max_abs"))
            scaled = [None if v is None else factor * v for v in statistics]
            rows.append([label, r.get("n"), *scaled])
        self.table(["residuals", "n", f"RMS{u}", f"median{u}", f"max |r|{u}"], rows,
                   formats=[None, "d", ".3g", ".2g", ".3g"])

    def figure(self, fig, caption: str = "", dpi: int = 110) -> None:
        """Embed a matplotlib figure as PNG and close it."""
        import matplotlib.pyplot as plt

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        self.picture(buf.getvalue(), caption)

    def picture(self, png: bytes, caption: str = "") -> None:
        """Embed a PNG picture drawn without matplotlib (:mod:`calidar.report.map_picture`,
        :mod:`calidar.report.chart_picture`)."""
        data = base64.b64encode(png).decode("ascii")
        self.blocks.append(
            f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )

    def html(self, anchor: str) -> str:
        blocks = "\n".join(self.blocks)
        return f'<section id="{anchor}"><h2>{html.escape(self.title)}</h2>\n{blocks}</section>'


UNIT_SYMBOLS = {"deg": "°", "1": ""}


def parameter_cells(p: dict) -> list:
    """Cells of one solution.json parameter entry: estimate, σ, free/fixed, truth, error,
    |error|/σ — numbers with their unit and as many decimals as σ's two significant digits
    (zero never shown as -0 or as floating-point dust)."""
    unit = UNIT_SYMBOLS.get(p["unit"], f" {p['unit']}")
    sigma = p["sigma"]
    known = bool(sigma) and np.isfinite(sigma)
    # decimals: those of σ's second significant digit, 0 to 12
    d = min(max(0, 2 - int(np.floor(np.log10(sigma)))), 12) if known else 6

    def show(v, sign=True):
        if v is None:
            return None
        if not known:  # fixed (or undetermined): the value as it is
            return ("0" if v == 0 else f"{v:.6g}") + unit
        text = f"{v:{'+' if sign else ''}.{d}f}"
        if float(text) == 0:
            text = f"{0:.{d}f}"
        return text + unit

    err = p.get("error")
    ratio = f"{abs(err) / sigma:.2f}" if err is not None and sigma else None
    shown_sigma = show(sigma, False) if sigma is not None else None
    status = "estimated" if p["free"] else "held"
    return [show(p["value"]), shown_sigma, status, show(p.get("truth")), show(err), ratio]


def verdict_html(verdict, title: str | None = None) -> str:
    """A verdict box: the status and summary, then every finding with its numbers and what to do."""
    items = "".join(_finding_html(f) for f in verdict.findings)
    head = f"{html.escape(title)}: " if title else ""
    tag = f'<span class="tag t-{verdict.status}">{verdict.status.upper()}</span>'
    return (f'<div class="verdict v-{verdict.status}"><h3>{tag}{head}'
            f"{html.escape(verdict.summary)}</h3><ul>{items}</ul></div>")


def _finding_html(f) -> str:
    """One finding of a verdict: its status tag, check, detail and the action when there is one."""
    tag = f'<span class="tag t-{f.status}">{f.status.upper()}</span>'
    action = f'<br><span class="action">→ {prose(f.action)}</span>' if f.action else ""
    return f"<li>{tag}<b>{html.escape(f.check)}</b>: {prose(f.detail)}{action}</li>"


def record_html(record) -> str:
    """How a result was made: version, command line, inputs with size and sha256, options, times,
    what the Dask tasks sent back."""
    from calidar.provenance import describe_tasks

    d = record.to_dict()
    rows = "".join(f'<tr><td class="l">{html.escape(i["path"])}</td><td>{i["size_bytes"]:,}</td>'
                   f'<td class="l"><code>{i["sha256"]}</code></td></tr>' for i in d["inputs"])
    opts = ", ".join(f"{k} = {v}" for k, v in d["options"].items())
    made = (f"<p>calidar {html.escape(d['calidar_version'])} (Python {html.escape(d['python'])}), "
            f"started {html.escape(d['started_utc'])}, finished "
            f"{html.escape(str(d['finished_utc']))}.</p>"
            f"<p>Command: <code>{html.escape(' '.join(d['argv']))}</code></p>")
    options = f"<p>Options: {html.escape(opts)}</p>" if opts else ""
    tasks = d.get("dask_tasks")
    dask = f"<p>Dask tasks: {html.escape(describe_tasks(tasks))}</p>" if tasks else ""
    head = '<thead><tr><th class="l">input</th><th>bytes</th><th class="l">sha256</th></tr></thead>'
    inputs = f"<table>{head}<tbody>{rows}</tbody></table>" if rows else ""
    return made + options + dask + inputs


@dataclass
class Report:
    """A report made of sections, with the verdicts at the top and the run record at the end."""

    title: str = "calidar report"
    sections: list[Section] = field(default_factory=list)
    #: (title, calidar.verdict.Verdict)
    verdicts: list[tuple[str | None, object]] = field(default_factory=list)
    record: RunRecord | None = None

    def add_verdict(self, verdict, title: str | None = None) -> None:
        """Show ``verdict`` at the top of the page (several: one box each, in order)."""
        self.verdicts.append((title, verdict))

    def section(self, title: str) -> Section:
        """Start a new section and return it."""
        s = Section(title)
        self.sections.append(s)
        return s

    def html(self) -> str:
        stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        nav = "".join(f'<li><a href="#s{i}">{html.escape(s.title)}</a></li>'
                      for i, s in enumerate(self.sections))
        body = "\n".join(s.html(f"s{i}") for i, s in enumerate(self.sections))
        verdicts = "".join(verdict_html(v, t) for t, v in self.verdicts)
        record = ""
        if self.record is not None:
            made = record_html(self.record)
            record = f'<section id="run"><h2>How this was made</h2>{made}</section>'
        # a run writes into a temporary folder (calidar.outputs.output_folder): name the destination
        title = html.escape(self.title)
        head = f'<head><meta charset="utf-8"><title>{title}</title><style>{_CSS}</style></head>'
        meta = f'<p class="meta">calidar {__version__} · {stamp}</p>'
        return shown_path(
            f'<!DOCTYPE html>\n<html lang="en">{head}<body><h1>{title}</h1>'
            f"{meta}{verdicts}<nav><ul>{nav}</ul></nav>\n{body}\n{record}</body></html>\n"
        )

    def write(self, path: str | Path, force: bool = True) -> Path:
        """Write the report atomically."""
        return write_text_atomic(path, self.html(), force)
