"""Reports built from analysis results (HTML + PNG); never computed inside the analysis.

Each report is its own module (``bench.app.reports.startup_report`` …): importing one
imports only its own plotting and analysis."""
