"""The library a user imports: every exported name documented (numpydoc), every example run.

Each subpackage of ``bench.analysis`` exports what a user calls in ``__all__``. Every exported
function carries Parameters, Returns and Examples sections; every exported class its
Parameters or Attributes; the Examples of every public docstring in the library (and in
``bench.values``) run here as doctests, so an example that drifts from the code fails.
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import pkgutil
import re
from types import ModuleType

import numpy as np
import pytest

import bench.analysis
import bench.values

SUBPACKAGES = sorted(m.name for m in pkgutil.iter_modules(bench.analysis.__path__) if m.ispkg)


def _package(name: str) -> ModuleType:
    return importlib.import_module(f"bench.analysis.{name}")


def _sections(doc: str) -> set[str]:
    """numpydoc section titles: a line followed by a line of dashes as long."""
    lines = inspect.cleandoc(doc).splitlines()
    return {a.strip() for a, b in zip(lines, lines[1:]) if b.strip() and set(b.strip()) == {"-"}
            and len(b.strip()) == len(a.strip())}


def _exported() -> list[tuple[str, str]]:
    return [(pkg, name) for pkg in SUBPACKAGES for name in _package(pkg).__all__]


def test_every_subpackage_exports_a_curated_api_and_documents_itself():
    assert SUBPACKAGES, "bench.analysis holds no method subpackage"
    for pkg in SUBPACKAGES:
        module = _package(pkg)
        assert module.__doc__ and module.__doc__.strip(), f"bench.analysis.{pkg} has no docstring"
        assert module.__all__, f"bench.analysis.{pkg} exports nothing"
        for name in module.__all__:
            assert hasattr(module, name), f"bench.analysis.{pkg}.__all__ names {name!r}, which it lacks"


@pytest.mark.parametrize(("pkg", "name"), _exported(), ids=lambda v: str(v))
def test_exported_name_has_a_numpydoc_docstring(pkg, name):
    obj = getattr(_package(pkg), name)
    if not (inspect.isfunction(obj) or inspect.isclass(obj)):
        return  # a constant: documented in its module and the package docstring
    doc = inspect.getdoc(obj) or ""
    where = f"bench.analysis.{pkg}.{name}"
    assert doc, f"{where} has no docstring"
    found = _sections(doc)
    if inspect.isfunction(obj):
        missing = {"Parameters", "Returns", "Examples"} - found
        assert not missing, f"{where}: no {', '.join(sorted(missing))} section"
    else:
        assert found & {"Parameters", "Attributes"}, f"{where}: no Parameters or Attributes section"


def _library_modules() -> list[str]:
    names = ["bench.values"]
    for info in pkgutil.walk_packages(bench.analysis.__path__, "bench.analysis."):
        names.append(info.name)
    return sorted(names)


@pytest.mark.parametrize("module_name", _library_modules())
def test_docstring_examples_run(module_name):
    module = importlib.import_module(module_name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    with np.printoptions(precision=6, suppress=True, legacy="1.25"):
        for test in finder.find(module, module_name, globs={"np": np}):
            if test.examples:
                runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) of {module_name} failed (output above)"


def test_examples_are_examples_not_decoration():
    """Every exported function's Examples section holds at least one ``>>>`` line that runs."""
    for pkg, name in _exported():
        obj = getattr(_package(pkg), name)
        if inspect.isfunction(obj):
            doc = inspect.getdoc(obj) or ""
            examples = doc.split("Examples\n--------", 1)[-1]
            assert re.search(r"^>>> ", examples, re.M), f"bench.analysis.{pkg}.{name}: Examples has no >>> line"
