"""``calidar quality``: vertical and planimetric agreement of overlapping flight lines."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.markup import escape

from calidar.cli.common import CONFIG_HELP, FORCE_HELP, config_values, console, given_options
from calidar.cli.options import CRS, GEOID_UNDULATION, POINT_VALUES, TIME_SYSTEM, parse_classes
from calidar.pipelines.quality import QualityConfig, measure

#: options → (QualityConfig attribute, parse)
OPTIONS = {"cell": ("settings.cell_m", None), "classes": ("classes", parse_classes), **POINT_VALUES}


STRIPS = typer.Argument(..., help="LAS/LAZ files (one or several flight lines each).")
OUT = typer.Option(None, "--out", help="Folder for quality.json and dz rasters (GeoTIFF, PNG).")
CELL = typer.Option(None, "--cell",
                    help="Grid cell of the difference, m (default 2 m or coarser when sparse).")
CLASSES = typer.Option(
    None, "--classes", help="LAS classes to compare, e.g. 2 or 2,6 (default: ground, class 2, when "
    "a file has it, else last and single returns on smooth cells).")


#: the command's help (its line breaks are those --help shows)
QUALITY_HELP = ("Swath-overlap differences between flight lines (dz = a − b): median, RMSDz, max, "
                "planimetric offsets\n(dx, dy ± σ, or not determined and why), and the USGS Lidar "
                "Base Specification swath checks with the\nquality level (QL0–QL3) each meets; "
                "with --out, config.toml holds this run's settings (for --config).")


def quality(
    ctx: typer.Context,
    strips: list[Path] = STRIPS,
    as_json: bool = typer.Option(False, "--json", help="Print the per-pair results as JSON."),
    out: Path | None = OUT,
    cell: float | None = CELL,
    classes: str | None = CLASSES,
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar quality`` (its help: QUALITY_HELP)."""
    from calidar.outputs import check_out_dir, claim_output, guard_inputs, output_folder
    from calidar.pipelines.quality import write_pairs_rasters
    from calidar.strips.usgs import usgs_checks

    cfg = QualityConfig.configure(config, config_values(given_options(ctx), OPTIONS))
    if out:
        check_out_dir(out, force)
        guard_inputs([], [*strips, config], [out])
        claim_output(out)  # --out is this run's from its start (released when the run ends)
    index, file_crs, results, notes, selections, precisions = measure(strips, cfg)
    checks = usgs_checks(results, precisions)
    doc = _document(index.how, results, notes, selections, checks, precisions)
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    if out:
        projected = file_crs is not None and not file_crs.is_geographic
        with output_folder(out, force, inputs=[*strips, config]) as tmp:
            write_pairs_rasters(results, tmp, file_crs if projected else None, force=True)
            (tmp / "quality.json").write_text(text, encoding="utf-8")
            cfg.write(tmp / "config.toml")
    if as_json:
        print(text, end="")
        return
    _print_table(index.how, results, selections, notes)
    _print_usgs(checks, precisions)
    if out:
        console.print(f"wrote {escape(str(out))}/quality.json, config.toml and dz rasters",
                      highlight=False, soft_wrap=True)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("quality", help=QUALITY_HELP)(quality)


def _document(how, results, notes, selections, checks, precisions) -> dict:
    """quality.json: the pairs, the points used, the notes and the USGS swath checks."""
    from calidar.strips.usgs import SPECIFICATION, common_level, summary

    usgs = {"specification": SPECIFICATION, "status": summary(checks),
            "meets": common_level(checks), "checks": [c.to_dict() for c in checks],
            "lines": [p.to_dict() for p in precisions]}
    return {"lines_from": how, "points_used": {str(p): s.to_dict() for p, s in selections.items()},
            "pairs": [q.to_dict() for q in results], "notes": notes, "usgs": usgs}


def _print_table(how, results, selections, notes) -> None:
    """The per-pair results as a table, which points were used and the notes."""
    from rich.table import Table

    table = Table(title=f"Swath-overlap differences (flight lines from {how}; dz = a − b)")
    heads = ("a", "b", "cells", "points a", "points b", "median dz [m]", "RMSDz [m]",
             "max |dz| [m]", "dx±σ [m]", "dy±σ [m]")
    for h in heads:
        table.add_column(h, justify="right")

    def f(v, sign="+"):
        return "—" if v is None else f"{v:{sign}.3f}"

    def pm(v, s):
        return "—" if v is None else f"{v:+.3f}±{s:.3f}"

    for q in results:
        table.add_row(str(q.a), str(q.b), str(q.n_cells), str(q.n_points_a), str(q.n_points_b),
                      f(q.median_dz_m), f(q.rmsdz_m, ""), f(q.max_abs_dz_m, ""),
                      pm(q.dx_m, q.sigma_dx_m), pm(q.dy_m, q.sigma_dy_m))
    console.print(table)
    console.print("dx, dy: strip a's horizontal offset from b, fitted with the height difference's "
                  "offset and tilt; σ from the cells' scatter and its correlation (20 m blocks); — "
                  "where not determined", highlight=False, soft_wrap=True)
    for q in results:
        if q.planimetric is not None and q.planimetric.status != "determined":
            console.print(f"{q.a}–{q.b}: dx, dy not determined: "
                          f"{escape(q.planimetric.reason)}", highlight=False, soft_wrap=True)
    for p, sel in selections.items():
        console.print(f"points used from {escape(p.name)}: {escape(sel.describe())}",
                      highlight=False)
    for n in notes:
        console.print(f"note: {escape(n)}", highlight=False, soft_wrap=True)


def _print_usgs(checks, precisions) -> None:
    """The USGS Lidar Base Specification swath checks and the quality level each meets."""
    from rich.table import Table

    from calidar.strips.usgs import SPECIFICATION, THRESHOLDS_M, summary

    table = Table(title=SPECIFICATION)
    for h in ("check", "value [m]", "cells", *THRESHOLDS_M, "meets"):
        table.add_column(h, justify="right")
    for k, c in enumerate(checks):
        limits = (f"{'≤' if k < 2 else '±'} {t[k]:.2f}" for t in THRESHOLDS_M.values())
        table.add_row(c.name, "—" if c.value_m is None else f"{c.value_m:.3f}", str(c.n_cells),
                      *limits, c.status)
    console.print(table)
    for p in precisions:
        if p.sigma_m is not None:
            console.print(f"line {p.line}: smooth-surface σ {p.sigma_m:.3f} m, max diff ≈ "
                          f"{p.max_diff_m:.3f} m over {p.n_cells} cells of {p.cell_m:g} m",
                          highlight=False)
    console.print(summary(checks), highlight=False)
