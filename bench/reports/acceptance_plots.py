"""One figure per acceptance step, drawn from what the run stored (streams + results).

Each builder takes ``(store, run_id, results, out_dir)`` and returns ``(title, png file name,
caption)`` or None when the run holds nothing for that step (e.g. an aborted run).  New
steps register here in :data:`SECTIONS`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
from matplotlib.figure import Figure

Section = tuple[str, str, str]


def _save(fig: Figure, path: Path) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path.name


def tumble_section(store, run_id: str, results: dict[str, Any], out: Path) -> Section | None:
    fit = results.get("tumble.fit")
    if not fit or "tumble" not in store.streams(run_id):
        return None
    data = store.load(run_id, "tumble")
    res_ug = np.asarray(fit["residuals_g"]) * 1e6
    inner, outer = data["inner_deg"], data["outer_deg"]
    fig = Figure(figsize=(9, 3.8))
    ax = fig.add_subplot()
    for plane, marker in ((0.0, "o"), (90.0, "s")):
        sel = np.isclose(inner, plane)
        if sel.any():
            ax.plot(outer[sel], res_ug[sel], marker, ls="-", lw=0.6,
                    label=f"inner {plane:g}° ({'IA–OA' if plane == 0 else 'IA–PA'} plane)")
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set(xlabel="outer axis angle (deg)", ylabel="fit residual (µg)",
           title="Tumble: residual of the IEEE 1293 fit per position")
    ax.legend(fontsize=8)
    name = _save(fig, out / "acceptance_tumble.png")
    dropped = fit.get("not_identifiable") or {}
    caption = (f"{len(res_ug)} positions, rms residual {fit['rms_g'] * 1e6:.3g} µg, "
               f"{fit['dof']} degrees of freedom, σ from {fit['sigma_source']}, local g "
               f"{fit['g_mps2']:.6f} m/s²." + (f" Not identifiable here: {', '.join(dropped)}."
                                                if dropped else ""))
    return "Tumble calibration", name, caption


#: step name → section builder
SECTIONS: dict[str, Callable[..., Section | None]] = {
    "tumble": tumble_section,
}
