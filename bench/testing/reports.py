"""Reports as a quality department files them: one HTML file that needs nothing outside it."""

from __future__ import annotations

import re

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
