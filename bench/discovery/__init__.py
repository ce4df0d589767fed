"""Discrepancy workflow (issue 7): logged records, the effect catalogue, models and their files."""

from bench.discovery.data import CSV_COLUMNS, Record

__all__ = ["CSV_COLUMNS", "Record"]
