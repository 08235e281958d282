"""A self-contained HTML report (plots embedded as PNG data URIs, no external assets).

>>> rep = Report("calidar demo")
>>> sec = rep.section("Boresight from tie planes")
>>> sec.text("12 strips, 8 overlapping pairs.")
>>> sec.solution(solution, truth={"boresight_roll": 0.0003})   # parameter table
>>> sec.figure(fig, "Residuals before/after")
>>> rep.write("out/report.html")
"""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from calidar import __version__
from calidar.outputs import write_text_atomic

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{border-bottom:2px solid #246;padding-bottom:.2em} h2{color:#246;margin-top:2em;border-bottom:1px solid #ccd}
table{border-collapse:collapse;margin:1em 0;font-size:.92em} th,td{border:1px solid #ccd;padding:.3em .6em;text-align:right}
th{background:#eef2f8} td.l,th.l{text-align:left} .warn{background:#fff4e0;border-left:4px solid #e90;padding:.5em 1em;margin:.5em 0}
.ok{color:#070} .bad{color:#b00} figure{margin:1em 0} figcaption{font-size:.9em;color:#555} img{max-width:100%}
nav ul{columns:2} .meta{color:#666;font-size:.9em}
.verdict{border:2px solid #888;border-radius:6px;padding:.6em 1em;margin:1em 0}
.verdict h3{margin:.1em 0 .4em 0} .verdict ul{margin:.2em 0;padding-left:1.2em} .verdict li{margin:.25em 0}
.v-pass{border-color:#2a7;background:#effaf3} .v-warn{border-color:#e90;background:#fff8ec} .v-fail{border-color:#c33;background:#fdeeee}
.tag{display:inline-block;min-width:3.2em;text-align:center;font-weight:600;border-radius:3px;padding:0 .3em;margin-right:.4em;color:#fff}
.t-pass{background:#2a7} .t-warn{background:#d80} .t-fail{background:#c33} .action{color:#333;font-style:italic}
"""


def _fmt(v, digits: int = 6) -> str:
    if v is None:
        return "—"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        if not np.isfinite(v):
            return "∞" if v > 0 else ("−∞" if v < 0 else "—")
        return f"{v:.{digits}g}"
    return html.escape(str(v))


@dataclass
class Section:
    """One section: blocks of HTML in the order added."""

    title: str
    blocks: list[str] = field(default_factory=list)

    def text(self, paragraph: str) -> None:
        self.blocks.append(f"<p>{html.escape(paragraph)}</p>")

    def warning(self, message: str) -> None:
        self.blocks.append(f'<div class="warn">⚠ {html.escape(message)}</div>')

    def table(self, header: list[str], rows: list[list], caption: str | None = None) -> None:
        """A table; the first column is left-aligned (labels)."""
        head = "".join(f'<th class="{"l" if i == 0 else ""}">{html.escape(str(h))}</th>' for i, h in enumerate(header))
        body = "".join(
            "<tr>" + "".join(f'<td class="{"l" if i == 0 else ""}">{_fmt(c)}</td>' for i, c in enumerate(r)) + "</tr>"
            for r in rows
        )
        cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
        self.blocks.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")

    def solution(self, solution, truth: dict[str, float] | None = None, hidden_prefix: str | None = None) -> None:
        """Parameter table (value, σ, unit, truth and error when known) and diagnostics; parameters
        whose names start with ``hidden_prefix`` (default: the solution's nuisance prefix) are
        counted, not listed."""
        doc = solution.to_dict(truth)
        hidden_prefix = hidden_prefix or solution.nuisance_prefix
        rows = []
        hidden = [n for n in doc["parameters"] if hidden_prefix and n.startswith(hidden_prefix)]
        if hidden:
            self.text(f"{len(hidden)} {hidden_prefix}* parameters are estimated too; solution.json lists them.")
        for name, p in doc["parameters"].items():
            if name in hidden:
                continue
            err = p.get("error")
            within = None
            if err is not None and p["sigma"]:
                within = f"{abs(err) / p['sigma']:.2f} σ"
            rows.append([name, p["value"], p["sigma"], p["unit"], "free" if p["free"] else "fixed",
                         p.get("truth"), err, within])
        self.table(["parameter", "value", "σ", "unit", "", "truth", "error", "|error|/σ"], rows)
        rb, ra = doc["residuals"]["before"], doc["residuals"]["after"]
        self.table(
            ["residuals", "n", "RMS", "median", "max |r|"],
            [["before", rb.get("n"), rb.get("rms"), rb.get("median"), rb.get("max_abs")],
             ["after", ra.get("n"), ra.get("rms"), ra.get("median"), ra.get("max_abs")]],
        )
        self.text(
            f"σ0 = {doc['sigma0']:.4g}, redundancy {doc['dof']:.0f}, condition number {doc['condition_number']:.3g}, "
            f"{len(doc['history']) - 1} iterations, {'converged' if doc['converged'] else 'NOT converged'}."
        )
        for w in doc["warnings"]:
            self.warning(w)

    def figure(self, fig, caption: str = "", dpi: int = 110) -> None:
        """Embed a matplotlib figure as PNG and close it."""
        import matplotlib.pyplot as plt

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        data = base64.b64encode(buf.getvalue()).decode("ascii")
        self.blocks.append(
            f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )

    def html(self, anchor: str) -> str:
        return f'<section id="{anchor}"><h2>{html.escape(self.title)}</h2>\n' + "\n".join(self.blocks) + "</section>"


def verdict_html(verdict, title: str | None = None) -> str:
    """A verdict box: the status and summary, then every finding with its numbers and what to do."""
    items = "".join(
        f'<li><span class="tag t-{f.status}">{f.status.upper()}</span><b>{html.escape(f.check)}</b>: '
        f"{html.escape(f.detail)}" + (f'<br><span class="action">→ {html.escape(f.action)}</span>' if f.action else "")
        + "</li>" for f in verdict.findings)
    head = f"{html.escape(title)}: " if title else ""
    return (f'<div class="verdict v-{verdict.status}"><h3><span class="tag t-{verdict.status}">'
            f"{verdict.status.upper()}</span>{head}{html.escape(verdict.summary)}</h3><ul>{items}</ul></div>")


def record_html(record) -> str:
    """How a result was made: version, command line, inputs with size and sha256, options, times."""
    d = record.to_dict()
    rows = "".join(f"<tr><td class=\"l\">{html.escape(i['path'])}</td><td>{i['size_bytes']:,}</td>"
                   f"<td class=\"l\"><code>{i['sha256']}</code></td></tr>" for i in d["inputs"])
    opts = ", ".join(f"{k} = {v}" for k, v in d["options"].items())
    return (f"<p>calidar {html.escape(d['calidar_version'])} (Python {html.escape(d['python'])}), started "
            f"{html.escape(d['started_utc'])}, finished {html.escape(str(d['finished_utc']))}.</p>"
            f"<p>Command: <code>{html.escape(' '.join(d['argv']))}</code></p>"
            + (f"<p>Options: {html.escape(opts)}</p>" if opts else "")
            + (f"<table><thead><tr><th class=\"l\">input</th><th>bytes</th><th class=\"l\">sha256</th></tr></thead>"
               f"<tbody>{rows}</tbody></table>" if rows else ""))


@dataclass
class Report:
    """A report made of sections, with the verdicts at the top and the run record at the end."""

    title: str = "calidar report"
    sections: list[Section] = field(default_factory=list)
    verdicts: list[tuple[str | None, object]] = field(default_factory=list)  #: (title, calidar.verdict.Verdict)
    record: object | None = None  #: calidar.provenance.RunRecord

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
        nav = "".join(f'<li><a href="#s{i}">{html.escape(s.title)}</a></li>' for i, s in enumerate(self.sections))
        body = "\n".join(s.html(f"s{i}") for i, s in enumerate(self.sections))
        verdicts = "".join(verdict_html(v, t) for t, v in self.verdicts)
        record = (f'<section id="run"><h2>How this was made</h2>{record_html(self.record)}</section>'
                  if self.record is not None else "")
        return (
            f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(self.title)}</title>'
            f"<style>{_CSS}</style></head><body><h1>{html.escape(self.title)}</h1>"
            f'<p class="meta">calidar {__version__} · {stamp}</p>{verdicts}<nav><ul>{nav}</ul></nav>\n{body}\n'
            f"{record}</body></html>\n"
        )

    def write(self, path: str | Path, force: bool = True) -> Path:
        """Write the report atomically."""
        return write_text_atomic(path, self.html(), force)
