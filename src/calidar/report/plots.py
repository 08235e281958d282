"""matplotlib for the report sections that still draw with it (Agg backend): ``plt``.

The strip calibration report's charts and maps are drawn without it
(:mod:`calidar.report.chart_picture`, :mod:`calidar.report.map_picture`)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402, F401
