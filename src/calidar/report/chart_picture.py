"""The strip calibration report's charts as PNG pictures drawn directly (numpy + Pillow), without a
matplotlib figure: a correlation matrix as a heat map with each value in its cell, and the
residuals before and after calibration as two overlaid histograms.

Importing matplotlib and drawing these two charts with it cost ≈ 0.8 CPU s a ``calidar boresight``
run, whatever the flight's size (the import 0.4 s); these take a few hundredths. Colours, scale
and text follow :mod:`calidar.report.map_picture` (ColorBrewer's RdBu reversed on ±1, DejaVu
Sans); the histograms' two colours are matplotlib's first two default cycle colours (its
"tab10" blue and orange), each at half opacity over the other, as before.
"""

from __future__ import annotations

import math

import numpy as np

from calidar.report.map_picture import (BACKGROUND, BAR_W, FONT_PX, INK, LINE_PX, TITLE_PX,
                                        colour_bar, colours, nice_ticks, paste_ink, png_bytes,
                                        text_font, turned_text, vertical_text, widest)

CELL_PX = 58  #: a correlation cell's side, pixels
LABEL_ANGLE = 35  #: the correlation's column labels turned by, degrees (reading upwards)
PLOT_W, PLOT_H = 560, 260  #: the histogram's plotting area, pixels
BINS = 80  #: histogram bins over ±(99th percentile of |residual|)
BEFORE, AFTER = (31, 119, 180), (255, 127, 14)  #: "tab10" blue and orange
ALPHA = 0.5  #: each histogram's opacity
DARK = 0.55  #: |ρ| above which a cell's text is white


def correlation_text(v: float) -> str:
    """A correlation as its cell shows it: two decimals, signed, zero unsigned; "—" when
    undefined."""
    if not np.isfinite(v):
        return "—"
    return f"{v:+.2f}".replace("+0.00", "0.00").replace("-0.00", "0.00")


def correlation_png(corr: np.ndarray, names: list[str]) -> bytes:
    """The picture (PNG bytes) of an n × n correlation matrix (NaN: undefined, white): cells in
    diverging colours on ±1, each value written in its cell (white on dark cells), the names
    along both axes, a colour bar labelled "correlation ρ"."""
    from PIL import Image, ImageDraw

    n = len(names)
    font = text_font(FONT_PX)
    side = n * CELL_PX
    cos, sin = math.cos(math.radians(LABEL_ANGLE)), math.sin(math.radians(LABEL_ANGLE))
    name_w = widest(font, names)
    left = max(10 + name_w + 8, int(10 + name_w * cos + FONT_PX - CELL_PX / 2))
    top = 12
    bar_h = max(side, 120)
    bt = nice_ticks(-1.0, 1.0, bar_h, lambda s: 1.4 * LINE_PX)
    bar_x = left + side + 22
    label_x = bar_x + BAR_W + 6 + widest(font, bt[1]) + 8
    size = (label_x + FONT_PX + 13, top + max(side + int(name_w * sin + FONT_PX * cos) + 16, bar_h)
            + 10)
    img = Image.new("RGB", size, BACKGROUND)
    cells = np.repeat(np.repeat(colours(np.asarray(corr, float), 1.0), CELL_PX, 0), CELL_PX, 1)
    img.paste(Image.fromarray(np.ascontiguousarray(cells)), (left, top))
    draw = ImageDraw.Draw(img)
    draw.rectangle((left - 1, top - 1, left + side, top + side), outline=INK)
    for i in range(n):
        centre = (i + 0.5) * CELL_PX
        draw.line((left - 5, top + centre, left - 1, top + centre), fill=INK)
        draw.text((left - 7, top + centre), names[i], fill=INK, font=font, anchor="rm")
        draw.line((left + centre, top + side, left + centre, top + side + 4), fill=INK)
        _turned(img, names[i], font, (left + centre, top + side + 6))
        for j in range(n):
            v = float(corr[i, j])
            ink = BACKGROUND if np.isfinite(v) and abs(v) > DARK else INK
            draw.text((left + (j + 0.5) * CELL_PX, top + centre), correlation_text(v), fill=ink,
                      font=font, anchor="mm")
    colour_bar(img, draw, (bar_x, top, bar_h), 1.0, bt, font)
    vertical_text(img, "correlation ρ", font, (label_x, top + bar_h / 2))
    return png_bytes(img)


def _turned(img, text: str, font, end: tuple[float, float]) -> None:
    """``text`` turned by :data:`LABEL_ANGLE` (reading upwards), its end at ``end`` (x, y):
    a column label under its tick."""
    mask = turned_text(text, font, LABEL_ANGLE)
    paste_ink(img, mask, (end[0] - mask.size[0], end[1]))


def histogram_png(before: np.ndarray, after: np.ndarray, unit: str = "m",
                  title: str = "Residuals") -> bytes:
    """The picture (PNG bytes) of two overlaid histograms of residuals (in ``unit``), before and
    after a calibration: :data:`BINS` bins over ±(99th percentile of every |residual|), a
    legend with each one's RMS, x and y ticks, the title."""
    from PIL import Image, ImageDraw

    before, after = np.asarray(before, float), np.asarray(after, float)
    both = np.abs(np.r_[before, after])
    lim = float(np.percentile(both, 99)) if both.size else 1.0
    lim = lim if lim > 0 and np.isfinite(lim) else 1.0
    edges = np.linspace(-lim, lim, BINS + 1)
    counts = [np.histogram(r, bins=edges)[0] for r in (before, after)]
    top_count = max(1, max(int(c.max()) for c in counts)) * 1.05
    font, big = text_font(FONT_PX), text_font(TITLE_PX)
    xt = nice_ticks(-lim, lim, PLOT_W, font.getlength)
    yt = nice_ticks(0.0, top_count, PLOT_H, lambda s: 1.4 * LINE_PX)
    left, top = 8 + LINE_PX + 6 + widest(font, yt[1]) + 8, 10 + TITLE_PX + 12
    size = (left + PLOT_W + 20, top + PLOT_H + 2 * LINE_PX + 20)
    img = Image.new("RGB", size, BACKGROUND)
    img.paste(Image.fromarray(_bars(counts, top_count)), (left, top))
    draw = ImageDraw.Draw(img)
    draw.text((left + PLOT_W / 2, 10), title, fill=INK, font=big, anchor="mt")
    draw.rectangle((left - 1, top - 1, left + PLOT_W, top + PLOT_H), outline=INK)
    for v, s in zip(*xt):
        px = left + (v + lim) / (2 * lim) * PLOT_W
        draw.line((px, top + PLOT_H, px, top + PLOT_H + 4), fill=INK)
        draw.text((px, top + PLOT_H + 6), s, fill=INK, font=font, anchor="mt")
    for v, s in zip(*yt):
        py = top + PLOT_H - v / top_count * PLOT_H
        draw.line((left - 5, py, left - 1, py), fill=INK)
        draw.text((left - 7, py), s, fill=INK, font=font, anchor="rm")
    draw.text((left + PLOT_W / 2, top + PLOT_H + LINE_PX + 10), f"residual [{unit}]", fill=INK,
              font=font, anchor="mt")
    vertical_text(img, "count", font, (8, top + PLOT_H / 2))
    legend = [f"{what} (RMS {_rms(r):.4g} {unit})" for what, r in (("before", before),
                                                                    ("after", after))]
    _legend(draw, legend, font, (left + PLOT_W - 8, top + 8))
    return png_bytes(img)


def _bars(counts: list[np.ndarray], top_count: float) -> np.ndarray:
    """(PLOT_H, PLOT_W, 3) uint8: each histogram's bars over the last, at :data:`ALPHA`."""
    canvas = np.full((PLOT_H, PLOT_W, 3), BACKGROUND, float)
    column_bin = np.minimum((np.arange(PLOT_W) + 0.5) * BINS // PLOT_W, BINS - 1).astype(int)
    rows = np.arange(PLOT_H)[:, None]
    for c, rgb in zip(counts, (BEFORE, AFTER)):
        bar_top = PLOT_H - c[column_bin] / top_count * PLOT_H
        covered = (rows + 0.5 >= bar_top[None, :]) & (c[column_bin] > 0)[None, :]
        canvas[covered] = (1 - ALPHA) * canvas[covered] + ALPHA * np.array(rgb, float)
    return canvas.round().astype(np.uint8)


def _legend(draw, labels: list[str], font, corner: tuple[float, float]) -> None:
    """A framed legend of the two histograms, its top-right corner at ``corner``."""
    swatch = 18
    w = swatch + 8 + widest(font, labels) + 14
    h = len(labels) * (LINE_PX + 4) + 8
    x0, y0 = corner[0] - w, corner[1]
    draw.rectangle((x0, y0, corner[0], y0 + h), fill=BACKGROUND, outline=(204, 204, 204))
    for k, (text, rgb) in enumerate(zip(labels, (BEFORE, AFTER))):
        y = y0 + 6 + k * (LINE_PX + 4)
        shade = tuple(round((1 - ALPHA) * b + ALPHA * c) for b, c in zip(BACKGROUND, rgb))
        draw.rectangle((x0 + 7, y + 3, x0 + 7 + swatch, y + LINE_PX - 3), fill=shade)
        draw.text((x0 + 7 + swatch + 8, y + LINE_PX / 2), text, fill=INK, font=font, anchor="lm")


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")
