"""Which experiment separates two candidates that the record cannot tell apart.

Pairs the catalogue is known to confuse have a specific recipe; otherwise the recipe follows
from the logged inputs each needs (vary one independently of the other) or, for a waveform
against a random process, from repeating the record.
"""

from __future__ import annotations

# Experiments that separate pairs the catalogue can confuse on a given record.
SEPARATING = {
    frozenset({"warmup_exponential", "temperature_bias"}):
        "vary temperature independently of time since power-on (soak at a second temperature, or power-cycle at a stable temperature)",
    frozenset({"warmup_exponential", "linear_drift"}):
        "record longer after power-on (an exponential settles, a drift keeps going) or power-cycle",
    frozenset({"linear_drift", "temperature_bias"}):
        "hold temperature constant for a long record, or ramp it down as well as up",
    frozenset({"linear_drift", "rate_random_walk"}):
        "repeat the record: a drift repeats with the same slope, a random walk does not",
    frozenset({"gauss_markov", "rate_random_walk"}):
        "a record much longer than the correlation time: Gauss–Markov levels off in the Allan curve, a random walk keeps rising",
    frozenset({"k2_nonlinearity", "scale_factor_asymmetry"}):
        "apply inputs of both signs with equal magnitudes (k2 is even, asymmetry is odd)",
    frozenset({"k3_nonlinearity", "saturation"}):
        "step the input towards full range: saturation clips abruptly, k3 bends smoothly",
    frozenset({"temperature_bias", "temperature_scale_factor"}):
        "change temperature at zero input and at a large input",
    frozenset({"time_delay", "lowpass_bandwidth"}):
        "sweep input frequency: a delay shifts phase linearly without attenuating, a low-pass attenuates",
    frozenset({"dead_zone", "quantization"}):
        "apply slow ramps through zero at several levels: the dead zone sits at zero only",
    frozenset({"vibration_rectification", "linear_drift"}):
        "switch vibration on and off during the record",
    frozenset({"g_sensitivity", "temperature_bias"}):
        "change orientation (specific force) at constant temperature",
}


def separating_experiment(a: str, b: str, catalogue: dict) -> str:
    key = frozenset({a, b})
    if key in SEPARATING:
        return f"{a} vs {b}: {SEPARATING[key]}"
    if catalogue[a].stochastic != catalogue[b].stochastic:
        det, sto_ = (a, b) if catalogue[b].stochastic else (b, a)
        need = ", ".join(sorted(set(catalogue[det].inputs) - {"t", "t_on"}))
        how = f" with the same {need} profile" if need else ""
        return (f"{a} vs {b}: repeat the record{how}: {det} repeats its waveform, {sto_} (a random "
                f"process) does not")
    ia, ib = set(catalogue[a].inputs), set(catalogue[b].inputs)
    if ia != ib:
        da = ", ".join(sorted(ia - ib)) or "time"
        db = ", ".join(sorted(ib - ia)) or "time"
        return f"{a} vs {b}: vary {da} independently of {db}"
    return f"{a} vs {b}: a record with a wider range of {', '.join(sorted(ia)) or 'time'}"
