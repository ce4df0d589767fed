"""Which experiment separates two candidates that the record cannot tell apart.

Pairs the catalogue is known to confuse have a specific recipe, declared on either effect
(``Effect.separating``, :meth:`.effects.Catalogue.separating_recipe`); otherwise the recipe
follows from the logged inputs each needs (vary one independently of the other) or, for a
waveform against a random process, from repeating the record.
"""

from __future__ import annotations

from bench.discovery.effects import CATALOGUE


def separating_experiment(a: str, b: str) -> str:
    """``"a vs b: <experiment>"`` for two catalogue ids."""
    recipe = CATALOGUE.separating_recipe(a, b)
    if recipe is not None:
        return f"{a} vs {b}: {recipe}"
    ea, eb = CATALOGUE.effect(a), CATALOGUE.effect(b)
    if ea.stochastic != eb.stochastic:
        det, sto_ = (ea, eb) if eb.stochastic else (eb, ea)
        need = ", ".join(sorted(set(det.inputs) - {"t", "t_on"}))
        how = f" with the same {need} profile" if need else ""
        return (f"{a} vs {b}: repeat the record{how}: {det.id} repeats its waveform, {sto_.id} (a random "
                f"process) does not")
    ia, ib = set(ea.inputs), set(eb.inputs)
    if ia != ib:
        da = ", ".join(sorted(ia - ib)) or "time"
        db = ", ".join(sorted(ib - ia)) or "time"
        return f"{a} vs {b}: vary {da} independently of {db}"
    return f"{a} vs {b}: a record with a wider range of {', '.join(sorted(ia)) or 'time'}"
