"""Reports built from analysis results (HTML + PNG); never computed inside the analysis."""

from bench.app.reports.startup_report import write_startup_report

__all__ = ["write_startup_report"]
