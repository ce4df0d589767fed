"""What :mod:`.localize` finds: where a residual departs from the model's noise floor.

Frozen records, one per finding (a time segment, a spectral line or band, an Allan τ range, a
jump, a correlation with a logged input), each able to describe itself in one line, and
:class:`Localization` holding them all with the curves the report plots. Units as in
:mod:`.localize`: the sensor unit, s, Hz.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

INPUT_COLUMNS = ("input", "cross_input", "temp", "t_on", "vib", "accel", "supply")


@dataclass(frozen=True)
class Segment:
    """A time segment whose residual departs from the floor: mean (unit) and rms/σ."""

    start_s: float
    end_s: float
    mean: float
    rms_ratio: float
    z_mean: float

    def describe(self) -> str:
        return (f"segment {self.start_s:.6g}–{self.end_s:.6g} s: mean {self.mean:.3g} "
                f"({self.z_mean:+.1f} σ of a mean), rms {self.rms_ratio:.2f}× the floor")


#: Spectral findings told one by one in the descriptions (the strongest); the rest as a count and
#: a span — a floor that is coloured, not white, flags hundreds of bins.
SHOWN_BANDS = 6


@dataclass(frozen=True)
class Band:
    """Frequencies whose PSD exceeds the white floor: ``kind`` is "line" or "band"."""

    kind: str
    f_low_hz: float
    f_high_hz: float
    peak_hz: float
    peak_ratio: float

    def describe(self) -> str:
        where = (f"{self.peak_hz:.4g} Hz" if self.kind == "line"
                 else f"{self.f_low_hz:.4g}–{self.f_high_hz:.4g} Hz (peak {self.peak_hz:.4g} Hz)")
        return f"spectral {self.kind} at {where}: PSD {self.peak_ratio:.3g}× the white floor"


@dataclass(frozen=True)
class TauRange:
    """Averaging times whose Allan deviation lies outside the white expectation's CI."""

    tau_low_s: float
    tau_high_s: float
    worst_ratio: float

    def describe(self) -> str:
        return (f"Allan deviation at τ = {self.tau_low_s:.4g}–{self.tau_high_s:.4g} s: up to "
                f"{self.worst_ratio:.3g}× the white-noise expectation")


@dataclass(frozen=True)
class Jump:
    """One sample far beyond the floor (a step or a spike at that instant)."""

    t_s: float
    value: float
    z: float

    def describe(self) -> str:
        return f"jump at t = {self.t_s:.6g} s: {self.value:.3g} ({self.z:+.1f} σ)"


@dataclass(frozen=True)
class InputCorrelation:
    """Correlation of the residual with a transform of a logged column."""

    column: str
    transform: str  # "x", "x^2", "x^3", "|x|", "dx/dt"
    r: float
    z: float
    n_eff: float

    def describe(self) -> str:
        return (f"correlation with {self.transform.replace('x', self.column, 1)}: r = {self.r:+.3f} "
                f"({self.z:+.1f} σ, effective n {self.n_eff:.0f})")


@dataclass(frozen=True)
class Localization:
    """Everything flagged, plus the curves the report plots (PSD, ADEV and their floors)."""

    segments: tuple[Segment, ...]
    cusum_p: float
    bands: tuple[Band, ...]
    taus: tuple[TauRange, ...]
    correlations: tuple[InputCorrelation, ...]
    freq_hz: np.ndarray = field(repr=False)
    psd: np.ndarray = field(repr=False)
    psd_floor: float = 0.0
    tau_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    adev: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    adev_white: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    alpha: float = 0.01
    jumps: tuple[Jump, ...] = ()

    @property
    def any_structure(self) -> bool:
        """True when any test flags departure from the floor."""
        return bool(self.segments or self.bands or self.taus or self.correlations or self.jumps
                    or self.cusum_p < self.alpha)

    def descriptions(self) -> list[str]:
        """One line per finding, for the report and the "unexplained structure" list."""
        segs = sorted(self.segments, key=lambda s: -abs(s.z_mean))
        out = [s.describe() for s in segs[:4]]
        if len(segs) > 4:
            out.append(f"… and {len(segs) - 4} more segments depart (from "
                       f"{min(s.start_s for s in segs):.6g} s to {max(s.end_s for s in segs):.6g} s)")
        if self.cusum_p < self.alpha:
            out.append(f"cumulative sum departs from a zero-mean record (CUSUM p = {self.cusum_p:.2g})")
        out += [j.describe() for j in self.jumps]
        bands = sorted(self.bands, key=lambda b: -b.peak_ratio)  # the strongest first, a few by name
        out += [b.describe() for b in bands[:SHOWN_BANDS]]
        if len(bands) > SHOWN_BANDS:
            rest = bands[SHOWN_BANDS:]
            out.append(f"… and {len(rest)} more spectral lines or bands above the white floor (from "
                       f"{min(b.f_low_hz for b in rest):.4g} Hz to {max(b.f_high_hz for b in rest):.4g} Hz, up to "
                       f"{max(b.peak_ratio for b in rest):.3g}×): a coloured floor rather than lines")
        out += [t.describe() for t in self.taus]
        out += [c.describe() for c in self.correlations]
        return out

    def to_dict(self) -> dict:
        return {"segments": [s.__dict__ for s in self.segments], "cusum_p": self.cusum_p,
                "bands": [b.__dict__ for b in self.bands], "taus": [t.__dict__ for t in self.taus],
                "correlations": [c.__dict__ for c in self.correlations],
                "jumps": [j.__dict__ for j in self.jumps],
                "descriptions": self.descriptions()}
