"""What every report shares: thinning long traces for plotting, saving a figure, inlining the
figures a page shows (the page itself: ``layout``)."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

MAX_POINTS = 20_000


def thin(*arrays: np.ndarray, max_points: int = MAX_POINTS) -> list[np.ndarray]:
    """Every k-th sample of each array, k chosen so the first keeps ≤ ``max_points``."""
    step = max(1, arrays[0].size // max_points)
    return [a[::step] for a in arrays]


def save_figure(fig: Figure, path: Path, dpi: int = 110) -> str:
    """Lay out and write ``fig``; return the file name (reports link it relatively)."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    return path.name


_IMAGE_SRC = re.compile(r"""src=(['"])([^'"/:]+\.png)\1""")


def inline_figures(page: str, folder: Path) -> str:
    """``page`` with every figure it shows from ``folder`` inlined (``src`` as a data URI)."""
    def inline(m: re.Match[str]) -> str:
        png = folder / m.group(2)
        if not png.is_file():
            return m.group(0)
        return f"src={m.group(1)}data:image/png;base64,{base64.b64encode(png.read_bytes()).decode()}{m.group(1)}"
    return _IMAGE_SRC.sub(inline, page)
