"""One layout for every report: a Jinja2 template per report on one base page, written as a
self-contained HTML file with a PDF of it beside it.

Every report carries the same parts (``templates/base.html.j2``): a title, a verdict when there
is one, the **record header** (what was tested or analysed, where, by whom, against which spec,
with which code and seed, when), the report's own body, an **approval block** (tested by /
reviewed by: name, signature, date) and, at the foot of the page and of every PDF page, the
**record's identity**: the stored run's digest (``bench runs show ID`` prints the same) or, for
an analysis of a file, the file's SHA-256 — so a printed copy can be matched to what it reports.

The PDF is made from the same HTML by xhtml2pdf (pure Python: no browser needed on the user's
machine); figures are inlined in both.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib
from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape

from bench.app.reports.common import inline_figures
from bench.core.version import code_version

_ENV = Environment(loader=PackageLoader("bench.app.reports", "templates"),
                   autoescape=select_autoescape(["html", "j2"]), undefined=StrictUndefined,
                   trim_blocks=True, lstrip_blocks=True)


def _g(x: Any, digits: int = 4) -> str:
    """A number to ``digits`` significant digits ("—" for None); anything else as text."""
    if x is None:
        return "—"
    if isinstance(x, bool | int) or not isinstance(x, float):
        return str(x)
    return f"{x:.{digits}g}"


_ENV.filters["g"] = _g


@dataclass(frozen=True)
class Identity:
    """What the foot of every page names: a label, the value and how a reader checks it."""

    label: str
    value: str
    how: str = ""


@dataclass
class Header:
    """The parts every report shares (see the module's docstring)."""

    title: str
    subject: Sequence[tuple[str, Any]]
    identity: Identity
    verdict: str | None = None
    reason: str | None = None
    approval: bool = True
    tested_by: str = ""
    numbers: str | None = None  # the file beside the report holding its numbers (JSON)
    code: str = field(default_factory=code_version)
    generated_utc: str = field(
        default_factory=lambda: dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z"))


def run_identity(digest: str, run_id: str) -> Identity:
    """The foot for a report of a stored run: the run's digest."""
    return Identity("Record digest", digest,
                    f"SHA-256 of the stored run's acquired content; bench runs show {run_id} prints it")


def digest_identity(digests: Iterable[tuple[str, str]]) -> Identity:
    """The foot for an analysis of files whose SHA-256 is known: (file name, digest) pairs."""
    return Identity("Input SHA-256", "; ".join(f"{name}: {digest}" for name, digest in digests) or "—",
                    "the analysed file's content; sha256sum prints it")


def file_identity(paths: Iterable[str | Path]) -> Identity:
    """The foot for an analysis of files: each file's SHA-256."""
    def sha256(path: Path) -> str:
        try:
            return hashlib.sha256(path.read_bytes()).hexdigest()
        except OSError:
            return "not readable"
    return digest_identity((Path(p).name, sha256(Path(p))) for p in paths)


def source_identity(context: dict[str, Any] | None) -> Identity:
    """The foot for an analysis described by ``context``: the stored run's digest when it names
    one (``digest``, ``run``), else the SHA-256 of its ``input`` file(s)."""
    context = context or {}
    if context.get("digest") and context.get("run"):
        return run_identity(str(context["digest"]), str(context["run"]))
    inputs = context.get("input")
    paths = [inputs] if isinstance(inputs, str | Path) else list(inputs or [])
    files = [p for p in paths if Path(p).is_file()]
    if files:
        return file_identity(files)
    return Identity("Record", "no stored run or file named", "the analysed data came from the caller")


def subject_rows(context: dict[str, Any] | None) -> list[tuple[str, Any]]:
    """``context`` as header rows (the digest goes to the foot, not the header)."""
    return [(k.replace("_", " "), v) for k, v in (context or {}).items() if k != "digest"]


def context_header(title: str, context: dict[str, Any] | None, **fields: Any) -> Header:
    """The header of an analysis described by ``context`` (where the data came from): its rows
    (:func:`subject_rows`), its foot (:func:`source_identity`), and "tested by" its ``operator``."""
    context = context or {}
    fields.setdefault("tested_by", str(context.get("operator") or ""))
    return Header(title=title, subject=subject_rows(context), identity=source_identity(context), **fields)


def render(template: str, header: Header, **context: Any) -> str:
    """The page of ``template`` (a name under ``templates/``) with ``header`` and ``context``."""
    return _ENV.get_template(template).render(h=header, **context)


def write_report(path: str | Path, template: str, header: Header, *, pdf: bool = True,
                 **context: Any) -> Path:
    """Render ``template`` into ``path`` (figures named by ``src`` inlined from ``path``'s
    folder) and, with ``pdf``, the same page as a PDF beside it (``path`` with ``.pdf``)."""
    path = Path(path)
    page = inline_figures(render(template, header, **context), path.parent)
    path.write_text(page, encoding="utf-8")
    if pdf:
        write_pdf(page, path.with_suffix(".pdf"))
    return path


class PdfError(RuntimeError):
    """The PDF could not be made from the page."""


def _font_dir() -> Path:
    return Path(matplotlib.get_data_path()) / "fonts" / "ttf"


def _pdf_fonts() -> str:
    """CSS embedding DejaVu Sans (shipped with matplotlib, so present wherever the bench is) in
    the PDF: the PDF's built-in Helvetica has no σ̂, x̄, K₁ or √ glyphs. The HTML page keeps the
    reader's fonts and loads no file."""
    ttf = _font_dir()
    faces = "".join(
        f"@font-face {{ font-family: benchsans; src: url('{(ttf / name).as_posix()}');"
        f"{' font-weight: bold;' if 'Bold' in name else ''}{' font-style: italic;' if 'Oblique' in name else ''} }}\n"
        for name in ("DejaVuSans.ttf", "DejaVuSans-Bold.ttf", "DejaVuSans-Oblique.ttf", "DejaVuSans-BoldOblique.ttf"))
    mono = f"@font-face {{ font-family: benchmono; src: url('{(ttf / 'DejaVuSansMono.ttf').as_posix()}'); }}\n"
    return (f"<style>{faces}{mono}body, td, th, p, li, h1, h2, h3 {{ font-family: benchsans; }}"
            " code, pre { font-family: benchmono; } td, th { font-size: 8pt; }</style>")


def write_pdf(page: str, path: Path) -> Path:
    """The HTML ``page`` (figures inline) as a PDF at ``path``, in DejaVu Sans."""
    from xhtml2pdf import pisa  # noqa: PLC0415 — lazy: reportlab costs ≈ 0.3 s of import
    from xhtml2pdf.config.resources import ResourceAccessPolicy  # noqa: PLC0415 — lazy, as above

    logging.getLogger("xhtml2pdf").setLevel(logging.ERROR)  # its notes on CSS it ignores
    buf = io.BytesIO()
    # the page reads nothing but the fonts: figures are inline, nothing remote
    policy = ResourceAccessPolicy(base_dir=_font_dir(), allow_remote=False)
    status = pisa.CreatePDF(page.replace("</head>", _pdf_fonts() + "</head>", 1), dest=buf, encoding="utf-8",
                            resource_policy=policy)
    if status.err:
        raise PdfError(f"the PDF of {path.name} could not be made ({status.err} errors)")
    path.write_bytes(buf.getvalue())
    return path
