"""A map of a north-up grid as a PNG picture drawn directly (numpy colour table + Pillow),
without a matplotlib figure: the cells in diverging colours centred on 0, a frame with x and y
ticks in metres, a colour bar with its scale and label, and a title. ``calidar quality`` draws one
per pair (18 for an 8-strip survey): a matplotlib figure each cost ≈ 0.2 CPU s (text layout and
two draws for the tight bounding box), this ≈ 0.03 s.

The colours are ColorBrewer's 11-class "RdBu" diverging scheme (Brewer, Harrower and The
Pennsylvania State University, colorbrewer2.org; the anchors of matplotlib's "RdBu"), reversed
(red positive), interpolated linearly into :data:`LUT_SIZE` steps; a value v shows the step
⌊(v + lim) / (2 lim) · LUT_SIZE⌋ (clipped), as matplotlib's ``imshow(vmin=-lim, vmax=lim)``.
Cells are drawn nearest-neighbour, each picture pixel showing the cell under its centre; NaN
cells white.
"""

from __future__ import annotations

import io
import math
from functools import lru_cache
from importlib.util import find_spec
from pathlib import Path

import numpy as np

#: ColorBrewer "RdBu" (11 classes), dark red to dark blue
RDBU = ((103, 0, 31), (178, 24, 43), (214, 96, 77), (244, 165, 130), (253, 219, 199),
        (247, 247, 247), (209, 229, 240), (146, 197, 222), (67, 147, 195), (33, 102, 172),
        (5, 48, 97))
LUT_SIZE = 256
MAP_W, MAP_H = 600, 440  #: the map at most, pixels (smaller grids scaled up to touch one of them)
BAR_W, BAR_MIN_H = 18, 200  #: colour bar width and least height, pixels
FONT_PX, TITLE_PX = 13, 15
LINE_PX = FONT_PX + 3  #: a line of tick labels, pixels
INK, BACKGROUND = (0, 0, 0), (255, 255, 255)


def diverging_lut() -> np.ndarray:
    """(LUT_SIZE, 3) uint8: blue (negative) through white to red (positive)."""
    anchors = np.array(RDBU[::-1], float)
    t = np.linspace(0.0, 1.0, LUT_SIZE)
    at = np.linspace(0.0, 1.0, len(anchors))
    rgb = np.column_stack([np.interp(t, at, anchors[:, k]) for k in range(3)])
    return rgb.round().astype(np.uint8)


def colours(values: np.ndarray, lim: float) -> np.ndarray:
    """(…, 3) uint8 colours of ``values`` on the scale ±``lim``; NaN white."""
    t = (np.nan_to_num(values, nan=0.0) + lim) / (2.0 * lim)
    idx = np.clip((t * LUT_SIZE).astype(np.int64), 0, LUT_SIZE - 1)
    rgb = diverging_lut()[idx]
    rgb[~np.isfinite(values)] = BACKGROUND
    return rgb


def nice_ticks(lo: float, hi: float, px: float, width) -> tuple[np.ndarray, list[str]]:
    """Ticks over [lo, hi] on an axis of ``px`` pixels: the finest step of 1, 2, 2.5 or 5 × 10^k
    whose labels (each ``width(label)`` pixels wide) keep ≥ 12 px apart; their labels."""
    span = max(hi - lo, 1e-12)
    best = None
    for k in range(math.floor(math.log10(span)) - 2, math.floor(math.log10(span)) + 2):
        for m in (1.0, 2.0, 2.5, 5.0):
            step = m * 10.0**k
            if span / step > px / 12:  # labels could not keep 12 px apart
                continue
            ticks = np.arange(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1) * step
            if ticks.size == 0:
                continue
            labels = [_label(v, step) for v in ticks]
            gap = px * step / span
            best = (ticks, labels)
            if gap >= max(width(s) for s in labels) + 12:
                return best
    return best if best is not None else (np.array([]), [])


def _label(v: float, step: float) -> str:
    k = math.floor(math.log10(step) + 1e-9)
    decimals = max(0, -k + (1 if round(step / 10.0**k, 6) == 2.5 else 0))
    text = f"{v:.{decimals}f}"
    return "0" if float(text) == 0 else text.replace("-", "−")


@lru_cache(maxsize=4)
def text_font(px: int):
    """DejaVu Sans (matplotlib's own font, from its installed data, matplotlib not imported) at
    ``px``; Pillow's default font where it is missing."""
    from PIL import ImageFont

    spec = find_spec("matplotlib")
    if spec is not None and spec.submodule_search_locations:
        path = Path(spec.submodule_search_locations[0]) / "mpl-data/fonts/ttf/DejaVuSans.ttf"
        if path.exists():
            return ImageFont.truetype(str(path), px)
    return ImageFont.load_default(px)


def map_png(grid: np.ndarray, origin: tuple[float, float], cell_m: float, title: str, label: str,
            lim: float | None = None) -> bytes:
    """The picture (PNG bytes) of ``grid`` (ny, nx; row 0 north, NaN no data; ``origin`` its
    north-west corner, m; square cells of ``cell_m``) on ±``lim`` (default the 98th percentile of
    |value|), with x/y ticks in metres, a colour bar labelled ``label`` and ``title``."""
    from PIL import Image, ImageDraw

    if lim is None:
        lim = float(np.nanpercentile(np.abs(grid), 98)) if np.isfinite(grid).any() else 1.0
    lim = lim if lim > 0 and np.isfinite(lim) else 1.0
    ny, nx = grid.shape
    scale = min(MAP_W / nx, MAP_H / ny)
    w, h = max(1, round(nx * scale)), max(1, round(ny * scale))
    rows = np.minimum(((np.arange(h) + 0.5) * ny / h).astype(np.int64), ny - 1)
    cols = np.minimum(((np.arange(w) + 0.5) * nx / w).astype(np.int64), nx - 1)
    font, big = text_font(FONT_PX), text_font(TITLE_PX)
    span = (nx * cell_m, ny * cell_m)
    xt = nice_ticks(origin[0], origin[0] + span[0], w, font.getlength)
    yt = nice_ticks(origin[1] - span[1], origin[1], h, lambda s: 1.4 * LINE_PX)
    bar_h = max(h, BAR_MIN_H)
    bt = nice_ticks(-lim, lim, bar_h, lambda s: 1.4 * LINE_PX)
    left = 8 + LINE_PX + 6 + widest(font, yt[1]) + 8
    top = 10 + TITLE_PX + 12
    bar_x = left + w + 22
    label_x = bar_x + BAR_W + 6 + widest(font, bt[1]) + 8
    size = (max(label_x + FONT_PX + 13, int(big.getlength(title)) + 20),
            top + max(h + 2 * LINE_PX + 10, bar_h) + 10)
    img = Image.new("RGB", size, BACKGROUND)
    img.paste(Image.fromarray(colours(grid[rows][:, cols], lim)), (left, top))
    draw = ImageDraw.Draw(img)
    draw.text((size[0] / 2, 10), title, fill=INK, font=big, anchor="mt")
    draw.rectangle((left - 1, top - 1, left + w, top + h), outline=INK)
    for v, s in zip(*xt):
        px = left + (v - origin[0]) / span[0] * w
        draw.line((px, top + h, px, top + h + 4), fill=INK)
        draw.text((px, top + h + 6), s, fill=INK, font=font, anchor="mt")
    for v, s in zip(*yt):
        py = top + (origin[1] - v) / span[1] * h
        draw.line((left - 5, py, left - 1, py), fill=INK)
        draw.text((left - 7, py), s, fill=INK, font=font, anchor="rm")
    draw.text((left + w / 2, top + h + LINE_PX + 10), "x [m]", fill=INK, font=font, anchor="mt")
    vertical_text(img, "y [m]", font, (8, top + h / 2))
    colour_bar(img, draw, (bar_x, top, bar_h), lim, bt, font)
    vertical_text(img, label, font, (label_x, top + bar_h / 2))
    return png_bytes(img)


def png_bytes(img) -> bytes:
    """A Pillow image as PNG bytes."""
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def widest(font, labels) -> int:
    return int(max((font.getlength(s) for s in labels), default=0))


def colour_bar(img, draw, at: tuple[int, int, int], lim: float, ticks, font) -> None:
    """The colour bar at (x, top, height): +lim at the top, −lim at the bottom, ``ticks`` (values,
    labels) on its right."""
    from PIL import Image

    x, top, h = at
    values = lim - (np.arange(h) + 0.5) / h * 2.0 * lim
    img.paste(Image.fromarray(np.repeat(colours(values, lim)[:, None, :], BAR_W, axis=1)), (x, top))
    draw.rectangle((x - 1, top - 1, x + BAR_W, top + h), outline=INK)
    for v, s in zip(*ticks):
        py = top + (lim - v) / (2.0 * lim) * h
        draw.line((x + BAR_W, py, x + BAR_W + 4, py), fill=INK)
        draw.text((x + BAR_W + 6, py), s, fill=INK, font=font, anchor="lm")


def vertical_text(img, text: str, font, at: tuple[float, float]) -> None:
    """``text`` turned 90° (reading upwards), its left edge at x = at[0], centred on y = at[1]."""
    mask = turned_text(text, font, 90.0)
    paste_ink(img, mask, (at[0], at[1] - mask.size[1] / 2))


def turned_text(text: str, font, degrees: float):
    """``text`` as a mask (a Pillow "L" image, ink 255) turned by ``degrees`` anticlockwise
    (reading upwards), the mask grown to hold it."""
    from PIL import Image, ImageDraw

    strip = Image.new("L", (int(font.getlength(text)) + 2, FONT_PX + 5), 0)
    ImageDraw.Draw(strip).text((0, 0), text, fill=255, font=font)
    return strip.rotate(degrees, expand=True, resample=Image.BICUBIC)


def paste_ink(img, mask, corner: tuple[float, float]) -> None:
    """Ink (:data:`INK`) through ``mask`` onto ``img``, the mask's top left at ``corner`` (x, y)."""
    from PIL import Image

    img.paste(Image.new("RGB", mask.size, INK), (int(corner[0]), int(corner[1])), mask)
