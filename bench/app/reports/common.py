"""What every report shares: thinning long traces for plotting, saving a figure, an HTML table,
writing the page as one self-contained file."""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Collection, Sequence
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


def html_table(header: Sequence[str], rows: Sequence[Sequence[object]],
               bold_rows: Collection[int] = frozenset()) -> str:
    """An escaped HTML table; rows whose index is in ``bold_rows`` get class ``best``."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = []
    for i, row in enumerate(rows):
        cells = "".join(f"<td>{html.escape(str(v))}</td>" for v in row)
        body.append(f"<tr class='best'>{cells}</tr>" if i in bold_rows else f"<tr>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


_IMAGE_SRC = re.compile(r"""src=(['"])([^'"/:]+\.png)\1""")


def inline_figures(page: str, folder: Path) -> str:
    """``page`` with every figure it shows from ``folder`` inlined (``src`` as a data URI)."""
    def inline(m: re.Match[str]) -> str:
        png = folder / m.group(2)
        if not png.is_file():
            return m.group(0)
        return f"src={m.group(1)}data:image/png;base64,{base64.b64encode(png.read_bytes()).decode()}{m.group(1)}"
    return _IMAGE_SRC.sub(inline, page)


def write_page(path: Path, page: str) -> Path:
    """Write the HTML ``page`` to ``path`` with every figure it shows from its own folder inlined
    (``src`` as a data URI): the report is one file that opens, prints and files on its own, with
    no resource outside it. The figures stay beside it as PNG files too."""
    path.write_text(inline_figures(page, path.parent), encoding="utf-8")
    return path
