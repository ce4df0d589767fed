"""The logged record the discrepancy workflow works on: time, output and every logged stimulus.

Units: ``t_s`` in s; ``y`` in the sensor unit (g for accelerometers, deg/s for gyros and the
MHD sensor); ``input`` and ``cross_input`` in the same unit as the applied quantity (g or
deg/s); ``temp_c`` in degC; ``t_on_s`` in s since power-on; ``vib_grms`` in g rms;
``accel_g`` the specific force along a gyro's input axis in g (what ``g_sensitivity`` acts on);
``supply_v`` the sensor's supply voltage in V (logged by the bench; no catalogue effect uses it,
so a dependence on it is reported as unexplained structure, never named).

CSV columns (header names) and the field each fills:

=============  ===============  =================================================
column         field            meaning
=============  ===============  =================================================
``t``          ``t_s``          time, s, strictly increasing (required)
``y``          ``y``            sensor output, g or deg/s (required)
``input``      ``input``        applied acceleration (g) or rate (deg/s)
``cross_input`` ``cross_input`` applied quantity along the cross axis (misalignment)
``temp``       ``temp_c``       sensor temperature, degC
``t_on``       ``t_on_s``       time since power-on, s (absent: ``t - t[0]``)
``vib``        ``vib_grms``     vibration level, g rms
``accel``      ``accel_g``      specific force along a gyro's axis, g
``supply``     ``supply_v``     supply voltage, V
=============  ===============  =================================================
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property
from typing import Any

import numpy as np

# CSV header name -> Record field.
CSV_COLUMNS: dict[str, str] = {
    "t": "t_s", "y": "y", "input": "input", "cross_input": "cross_input", "temp": "temp_c",
    "t_on": "t_on_s", "vib": "vib_grms", "accel": "accel_g", "supply": "supply_v",
}
# Physically plausible ranges of the logged columns: outside them the file is wrong, not the unit.
_RANGES: dict[str, tuple[float, float]] = {
    "temp_c": (-100.0, 200.0),
    "t_on_s": (0.0, np.inf),
    "vib_grms": (0.0, 1000.0),
    "supply_v": (-1000.0, 1000.0),
}


@dataclass(frozen=True, eq=False)
class Record:
    """One logged experiment: output ``y`` at times ``t_s`` and the logged stimuli.

    Every column is a 1-D float array of the same length as ``t_s`` (or None when not logged).
    ``t_on_s`` absent means the record starts at power-on (``column("t_on")`` = ``t - t[0]``).
    Construction validates: ValueError naming the column, the bad value and the allowed range.
    """

    t_s: np.ndarray
    y: np.ndarray
    input: np.ndarray | None = None
    temp_c: np.ndarray | None = None
    t_on_s: np.ndarray | None = None
    vib_grms: np.ndarray | None = None
    cross_input: np.ndarray | None = None
    accel_g: np.ndarray | None = None
    supply_v: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = _as_column("t", self.t_s, None)
        if t.size < 2:
            raise ValueError(f"t: {t.size} samples; a record needs at least 2")
        dt = np.diff(t)
        if np.any(dt <= 0):
            i = int(np.argmax(dt <= 0))
            raise ValueError(f"t: not strictly increasing at row {i + 1} "
                             f"(t={float(t[i + 1])!r} after {float(t[i])!r}); allowed: t[i+1] > t[i]")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "y", _as_column("y", self.y, t.size))
        for f in fields(self)[2:]:
            v = getattr(self, f.name)
            if v is None:
                continue
            col = _as_column(_short(f.name), v, t.size)
            lo, hi = _RANGES.get(f.name, (-np.inf, np.inf))
            bad = (col < lo) | (col > hi)
            if np.any(bad):
                i = int(np.argmax(bad))
                raise ValueError(f"{_short(f.name)}: value {float(col[i])!r} at row {i} outside "
                                 f"the allowed range [{lo}, {hi}]")
            object.__setattr__(self, f.name, col)

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.size)

    @property
    def duration_s(self) -> float:
        """Span of the record, s."""
        return float(self.t_s[-1] - self.t_s[0])

    @cached_property
    def dt_s(self) -> float:
        """Median sample interval, s."""
        return float(np.median(np.diff(self.t_s)))

    @property
    def rate_hz(self) -> float:
        """Sample rate from the median interval, Hz."""
        return 1.0 / self.dt_s

    @cached_property
    def _uniform(self) -> bool:
        return self._check_uniform(1e-3)

    def is_uniform(self, rtol: float = 1e-3) -> bool:
        """True when every sample interval is within ``rtol`` of the median."""
        return self._uniform if rtol == 1e-3 else self._check_uniform(rtol)

    def _check_uniform(self, rtol: float) -> bool:
        dt = np.diff(self.t_s)
        return bool(np.all(np.abs(dt - self.dt_s) <= rtol * self.dt_s))

    def logged(self, name: str) -> bool:
        """True when column ``name`` (CSV name or field name) was logged (no fallback)."""
        if name in ("t", "y", "t_s"):
            return True
        return getattr(self, _field(name)) is not None

    def varies(self, name: str) -> bool:
        """True when column ``name`` was logged and is not constant (a constant input is one
        with the bias: bias and scale factor are not separable on it)."""
        return self.logged(name) and float(np.ptp(self.column(name))) > 0

    def has(self, name: str) -> bool:
        """True when ``column(name)`` is available ("t_on" always is: fallback t - t[0])."""
        return _field(name) == "t_on_s" or self.logged(name)

    def column(self, name: str) -> np.ndarray:
        """The column ``name`` ("t", "y", "input", "cross_input", "temp", "t_on", "vib",
        "accel", "supply" or the field name). ``t_on`` falls back to ``t - t[0]``; a column that was not
        logged raises ValueError naming it and the logged ones."""
        f = _field(name)
        v = getattr(self, f)
        if v is None:
            if f == "t_on_s":
                return self.t_s - self.t_s[0]
            have = [k for k, fn in CSV_COLUMNS.items() if getattr(self, fn) is not None]
            raise ValueError(f"column {name!r} was not logged in this record; logged: {have}")
        return v

    def _mapped(self, fn) -> Record:
        """Every logged column through ``fn`` (an array in, an array out), ``t_on`` materialised
        first so the new record keeps the time since power-on."""
        kw: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "t_on_s" and v is None:
                v = self.t_s - self.t_s[0]
            kw[f.name] = None if v is None else fn(np.asarray(v))
        return Record(**kw)

    def slice(self, idx) -> Record:
        """The rows ``idx`` (a slice, an integer index array or a boolean mask) of every column.

        ``t_on`` is materialised first so a slice keeps the time since power-on."""
        return self._mapped(lambda v: v[idx])

    def block_means(self, m: int) -> Record:
        """Every column averaged over consecutive blocks of ``m`` rows (the last ``n mod m`` rows,
        fewer than a block, left out): the record seen at 1/``m`` of its rate. ``t_on`` is
        materialised first, so the means keep the time since power-on."""
        if isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= self.n // 2:
            raise ValueError(f"block length m = {m!r}; allowed: an integer in [1, {self.n // 2}]")
        k = self.n // m
        return self._mapped(lambda v: v[:k * m].reshape(k, m).mean(axis=1))

    def replace(self, **changes) -> Record:
        """A copy with some fields replaced (e.g. ``y=``), validated again."""
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        unknown = set(changes) - set(kw)
        if unknown:
            raise ValueError(f"unknown Record field(s) {sorted(unknown)}; allowed: {sorted(kw)}")
        kw.update(changes)
        return Record(**kw)

    def to_columns(self) -> dict[str, np.ndarray]:
        """The logged columns under their CSV names (inverse of ``from_columns``)."""
        return {k: getattr(self, f) for k, f in CSV_COLUMNS.items() if getattr(self, f) is not None}

    @classmethod
    def from_columns(cls, columns: dict) -> Record:
        """Build from CSV-style columns ``{"t": ..., "y": ..., "input": ..., ...}``.

        Header names are matched case-insensitively after stripping blanks; field names
        (``t_s``, ``temp_c`` ...) are accepted too. ``t`` and ``y`` are required; an unknown
        column raises ValueError naming it and the allowed ones."""
        kw: dict[str, Any] = {}
        allowed = set(CSV_COLUMNS) | set(CSV_COLUMNS.values())
        for key, val in columns.items():
            k = str(key).strip().lower()
            if k not in allowed:
                raise ValueError(f"unknown column {key!r}; allowed: {list(CSV_COLUMNS)}")
            f = CSV_COLUMNS.get(k, k)
            if f in kw:
                raise ValueError(f"column {key!r} given twice")
            kw[f] = val
        for req in ("t_s", "y"):
            if req not in kw:
                raise ValueError(f"missing required column {_short(req)!r}; "
                                 f"columns given: {list(columns)}")
        return cls(**kw)


def _short(field_name: str) -> str:
    for k, f in CSV_COLUMNS.items():
        if f == field_name:
            return k
    return field_name


def _field(name: str) -> str:
    if name in CSV_COLUMNS:
        return CSV_COLUMNS[name]
    if name in CSV_COLUMNS.values():
        return name
    raise ValueError(f"unknown column name {name!r}; allowed: {list(CSV_COLUMNS)}")


def _as_column(name: str, v, n: int | None) -> np.ndarray:
    try:
        a = np.array(v, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not numeric ({exc}); allowed: finite real numbers") from None
    if a.ndim != 1:
        raise ValueError(f"{name}: shape {a.shape}; allowed: a 1-D column")
    if n is not None and a.size != n:
        raise ValueError(f"{name}: length {a.size} differs from t's length {n}; "
                         f"allowed: exactly {n} values")
    bad = ~np.isfinite(a)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ValueError(f"{name}: non-finite value {float(a[i])!r} at row {i}; "
                         f"allowed: finite values in (-inf, inf)")
    a.setflags(write=False)
    return a
