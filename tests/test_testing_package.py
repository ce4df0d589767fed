"""``bench.testing``, the helpers tests, benchmarks and users share: importable without the test
tools (the package itself light: a driver's test loads no analysis), its examples run, and its
generators written apart from the code they grade."""

from __future__ import annotations

import ast
import doctest
import importlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import bench.testing

MODULES = sorted(m.name for m in pkgutil.walk_packages(bench.testing.__path__, "bench.testing."))

#: what each independent generator may import beyond the standard library and numpy/scipy: a
#: data container, the model whose parameters it realises, the simulator's physics — never the
#: estimator it grades
GENERATOR_IMPORTS = {
    "bench.testing.generators.fusion_pairs": set(),
    "bench.testing.generators.thermal_truth": set(),
    "bench.testing.generators.discovery_effects": {"bench.discovery.data", "bench.discovery.model", "sim.physics"},
    "bench.testing.generators.discovery_shapes": {"bench.discovery.data", "bench.discovery.effects_linalg"},
}


def test_every_module_imports_without_pytest_or_hypothesis_and_the_package_stays_light():
    code = ("import sys, importlib\n"
            "import bench.testing\n"
            "heavy = {'bench.analysis', 'bench.discovery', 'bench.app', 'sim.station'} & set(sys.modules)\n"
            "assert not heavy, f'import bench.testing loads {heavy}'\n"
            f"for name in {MODULES!r}:\n"
            "    importlib.import_module(name)\n"
            "print(sorted({'pytest', 'hypothesis', '_pytest'} & set(sys.modules)))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_the_package_docstring_names_every_module():
    doc = bench.testing.__doc__ or ""
    tops = {".".join(name.split(".")[:3]) for name in MODULES}
    assert all(f":mod:`{top}`" in doc for top in tops), sorted(t for t in tops if f":mod:`{t}`" not in doc)


@pytest.mark.parametrize("name", MODULES)
def test_the_examples_run(name):
    module = importlib.import_module(name)
    failed, _ = doctest.testmod(module, optionflags=doctest.ELLIPSIS, verbose=False)
    assert failed == 0, f"{name}: {failed} example(s) failed"


@pytest.mark.parametrize("name", sorted(GENERATOR_IMPORTS))
def test_a_generator_imports_nothing_of_the_estimators_it_grades(name):
    module = importlib.import_module(name)
    tree = ast.parse(Path(module.__file__ or "").read_text(encoding="utf-8"))
    imported = {node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    ours = {m for m in imported if m.split(".")[0] in ("bench", "instruments", "procedures", "sim")}
    allowed = GENERATOR_IMPORTS[name]
    assert all(any(m == a or m.startswith(a + ".") for a in allowed) for m in ours), sorted(ours - allowed)
