"""The files the application reads and writes for the library: compensation and model files.

The library turns these documents into objects and back (``compensation_from_toml``,
``model_to_toml``, ...) without touching a file; opening, reading and writing the file is the
application's part, and an unreadable file is named here (ValueError) as every other bad input.
"""

from __future__ import annotations

import os
from pathlib import Path

from bench.analysis.thermal import CompensationModel, compensation_from_toml, compensation_to_toml
from bench.discovery.model import Model, model_from_toml, model_to_toml

__all__ = ["read_compensation", "read_model", "write_compensation", "write_model"]


def _read(path: str | os.PathLike[str], what: str) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ValueError(f"cannot read {what} {os.fspath(path)!r}: {reason}") from None


def write_compensation(model: CompensationModel, path: str | os.PathLike[str]) -> None:
    """Write a thermal compensation file (TOML) to ``path``."""
    Path(path).write_text(compensation_to_toml(model), encoding="utf-8")


def read_compensation(path: str | os.PathLike[str]) -> CompensationModel:
    """Read and validate a compensation file (ValueError naming the bad key or the unreadable path)."""
    return compensation_from_toml(_read(path, "compensation file"))


def write_model(model: Model, path: str | os.PathLike[str], *, rate_hz: float | None = None) -> None:
    """Write the TOML model file; ``rate_hz`` (the record's sample rate) is recorded with the
    per-sample noise sd (``Model.at_rate``), so the file means the same at any rate."""
    if rate_hz is not None:
        model = model.at_rate(rate_hz)
    Path(path).write_text(model_to_toml(model), encoding="utf-8")


def read_model(path: str | os.PathLike[str], *, rate_hz: float | None = None) -> Model:
    """Read and validate a TOML model file (ValueError naming the bad key, value or range);
    with ``rate_hz``, carried to that sample rate (``Model.at_rate``: noise_sd rescaled when the
    file records its rate)."""
    model = model_from_toml(_read(path, "model file"))
    return model if rate_hz is None else model.at_rate(rate_hz)
