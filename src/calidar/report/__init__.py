"""The HTML report: one self-contained file that every calibration adds a section to."""

from calidar.report.html import Report, Section

__all__ = ["Report", "Section"]
