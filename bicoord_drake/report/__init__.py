"""The dataset report: one self-contained HTML page per dataset (no Drake)."""

from bicoord_drake.report.page import build_report, write_report

__all__ = ["build_report", "write_report"]
