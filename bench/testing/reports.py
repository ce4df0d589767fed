"""Reports as a quality department files them: one HTML file that needs nothing outside it, an
approval block and the record's identity at its foot, and a PDF of it that renders."""

from __future__ import annotations

import re
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

_RESOURCE = re.compile(r"""(?:src|srcset)=(['"])(?!data:)([^'"]+)\1|<link\b[^>]*\bhref=|<script\b[^>]*\bsrc=""",
                       re.IGNORECASE)
_INLINE_PNG = re.compile(r"""src=(['"])data:image/png;base64,[A-Za-z0-9+/=]{100,}\1""")


def assert_self_contained(page: str, figures: int = 1) -> int:
    """``page`` loads no resource from outside itself (every image inline, no stylesheet or script
    by address) and shows at least ``figures`` inline PNG figures; returns how many it shows."""
    outside = [m.group(0)[:80] for m in _RESOURCE.finditer(page)]
    assert not outside, f"the report loads resources from outside itself: {outside}"
    shown = len(_INLINE_PNG.findall(page))
    assert shown >= figures, f"{shown} inline figures, at least {figures} expected"
    return shown


_FOOT = re.compile(r"""<div id="foot">(.*?)</div>""", re.DOTALL)
_SHA256 = re.compile(r"\b[0-9a-f]{64}\b")


def assert_signable(page: str, digest: str | None = None) -> str:
    """``page`` carries what a signature needs: the approval block (tested by / reviewed by) and,
    at its foot, the record's identity — a SHA-256 (``digest`` when given). Returns the foot's text."""
    assert "tested by" in page and "reviewed by" in page, "no approval block"
    foot = _FOOT.search(page)
    assert foot, "no identity at the page's foot"
    text = foot.group(1)
    assert _SHA256.search(text), f"no SHA-256 at the foot: {text[:200]}"
    if digest is not None:
        assert digest in text, f"the foot does not name {digest}"
    return text


def assert_pdf(path: str | Path, pages: int = 1, text: Sequence[str] = ()) -> int:
    """The PDF at ``path`` renders (poppler's ``pdftoppm``) to at least ``pages`` pages, none of
    them blank, and its text (``pdftotext``) holds each of ``text``; returns the page count."""
    path = Path(path)
    assert path.read_bytes()[:5] == b"%PDF-", f"{path} is not a PDF"
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["pdftoppm", "-r", "30", "-png", str(path), f"{tmp}/page"], check=True,
                       capture_output=True)
        rendered = sorted(Path(tmp).glob("page-*.png"))
        assert len(rendered) >= pages, f"{len(rendered)} pages rendered, at least {pages} expected"
        for png in rendered:
            grey = np.asarray(Image.open(png).convert("L"))
            assert (grey < 128).mean() > 1e-3, f"{png.name} of {path.name} renders blank"
    words = subprocess.run(["pdftotext", "-layout", str(path), "-"], check=True, capture_output=True,
                           text=True).stdout
    flat = " ".join(words.split())
    for t in text:
        assert t in flat, f"{path.name} does not show {t!r}"
    return len(rendered)
