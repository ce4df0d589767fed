"""The documented command vocabularies (docs/vocabulary/*.md) against the command trees the
simulators register, and the pyvisa-sim YAML vocabularies against both.

A row ``implemented`` or ``ignored`` must be a registered pattern with the same set/query
forms, every registered pattern must be a row (the IEEE 488.2 common commands in the
README's table), and a row ``refused -113`` must be unknown to the simulator: sent, it
leaves ``-113,"Undefined header"`` and no reply."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs" / "vocabulary"
YAML_DIR = ROOT / "sim" / "visa_yaml"
_CELL_SPLIT = re.compile(r"(?<!\\)\|")
_MNEMONIC = re.compile(r"([A-Z][A-Z0-9]*)[a-z0-9]*(#)?")


def read_table(path: Path) -> dict[str, tuple[frozenset[str], str]]:
    """``{pattern: (forms, status)}`` from every table row of a vocabulary file."""
    rows: dict[str, tuple[frozenset[str], str]] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in _CELL_SPLIT.split(line.strip())[1:-1]]
        if len(cells) != 4 or not cells[0].startswith("`"):
            continue
        pattern = cells[0].strip("`")
        forms = frozenset(f.strip() for f in cells[1].split(","))
        assert forms <= {"set", "query"} and forms, f"{path.name}: {pattern}: forms {cells[1]!r}"
        assert re.fullmatch(r"implemented|ignored|refused -1\d\d", cells[2]), \
            f"{path.name}: {pattern}: status {cells[2]!r}"
        assert pattern not in rows, f"{path.name}: {pattern} listed twice"
        rows[pattern] = (forms, cells[2])
    return rows


def short_header(pattern: str, optional_nodes: bool = False) -> str:
    """``[SENSe:]VOLTage[:DC]:NPLCycles`` -> ``VOLT:NPLC`` (or ``SENS:VOLT:DC:NPLC`` with the
    optional nodes); a ``#`` suffix becomes 2."""
    text = re.sub(r"[\[\]]", "", pattern) if optional_nodes else re.sub(r"\[[^\]]*\]", "", pattern)
    if text.startswith("*"):
        return text
    lead = ":" if text.startswith(":") else ""
    parts = []
    for word in text.strip(":").split(":"):
        m = _MNEMONIC.fullmatch(word)
        assert m, f"{pattern}: mnemonic {word!r}"
        parts.append(m.group(1) + ("2" if m.group(2) else ""))
    return lead + ":".join(parts)


@pytest.fixture(scope="module")
def station(station_factory):
    return station_factory(seed=3)  # devices driven directly, not served


COMMON = read_table(DOCS / "README.md")
#: vocabulary file -> the station's devices that speak it
INSTRUMENTS = {
    "keysight_34465a.md": lambda s: [s.dmm, s.dmm_temp, s.angular.dmm],
    "keysight_e36312a.md": lambda s: [s.supply],
    "turntable.md": lambda s: [s.turntable],
    "shaker.md": lambda s: [s.shaker_controller],
    "angular_table.md": lambda s: [s.angular.controller],
    "keysight_daq970a.md": lambda s: [s.fixture.daq],
}


def test_every_vocabulary_file_is_checked():
    assert {p.name for p in DOCS.glob("*.md")} - {"README.md"} == set(INSTRUMENTS)


@pytest.mark.parametrize("filename", sorted(INSTRUMENTS))
def test_table_and_command_tree_agree(station, filename):
    table = read_table(DOCS / filename)
    accepted = {p: forms for p, (forms, status) in {**COMMON, **table}.items()
                if not status.startswith("refused")}
    for device in INSTRUMENTS[filename](station):
        tree = {p: frozenset(kinds) for p, kinds in device.vocabulary().items()}
        assert sorted(set(tree) - set(accepted)) == [], f"registered but not in {filename}"
        assert sorted(set(accepted) - set(tree)) == [], f"in {filename} but not registered"
        wrong = {p: (sorted(tree[p]), sorted(accepted[p])) for p in tree if tree[p] != accepted[p]}
        assert wrong == {}, f"set/query forms differ (tree, table) in {filename}"


@pytest.mark.parametrize("filename", sorted(INSTRUMENTS))
def test_short_forms_of_the_rows_reach_their_patterns(station, filename):
    device = INSTRUMENTS[filename](station)[0]
    for pattern, (forms, status) in {**COMMON, **read_table(DOCS / filename)}.items():
        for form in forms:
            full = not status.startswith("refused")  # a refused header: its most general form
            header = short_header(pattern, full) + ("?" if form == "query" else "")
            reached = device.pattern_of(header)
            if status.startswith("refused"):
                assert reached is None, f"{header}: refused in {filename}, answered by {reached}"
            else:
                assert reached == pattern, f"{header}: {reached} instead of {pattern}"


@pytest.mark.parametrize("filename", sorted(INSTRUMENTS))
def test_refused_rows_leave_their_error_and_no_reply(station, filename):
    device = INSTRUMENTS[filename](station)[0]
    device.process(b"*CLS")
    for pattern, (forms, status) in read_table(DOCS / filename).items():
        if not status.startswith("refused"):
            continue
        code = int(status.split()[1])
        for form in forms:
            header = short_header(pattern) + ("?" if form == "query" else " 1")
            assert device.process(header.encode()) is None, header
            assert device.pop_error().startswith(f"{code:+d},"), header
    assert device.pop_error() == '+0,"No error"'


# -- the pyvisa-sim YAML vocabularies -----------------------------------------------------------
YAMLS = {"keysight_34465a.yaml": "keysight_34465a.md", "keysight_e36312a.yaml": "keysight_e36312a.md",
         "turntable.yaml": "turntable.md"}


def yaml_headers(path: Path) -> set[str]:
    """Every header the YAML vocabulary sends, format fields filled from the property's
    allowed values (``:MODE:{:s} 1`` -> ``:MODE:POS``, ``:MODE:RATE``, ...)."""
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    headers: set[str] = set()
    for device in doc["devices"].values():
        messages = [(d["q"], None) for d in device.get("dialogues", [])]
        for prop in device.get("properties", {}).values():
            valid = prop.get("specs", {}).get("valid")
            messages += [(prop[k]["q"], valid) for k in ("getter", "setter") if k in prop]
        for q, valid in messages:
            header = q.split(None, 1)[0]
            if "{" in header:
                assert valid, f"{path.name}: {q!r} has a format field but no allowed values"
                headers |= {header.replace("{:s}", str(v)) for v in valid}
            else:
                headers.add(header)
    return headers


def test_every_yaml_vocabulary_is_checked():
    assert {p.name for p in YAML_DIR.glob("*.yaml")} == set(YAMLS)


@pytest.mark.parametrize("yaml_name", sorted(YAMLS))
def test_yaml_vocabulary_is_implemented_by_the_simulator_and_its_table(station, yaml_name):
    table_name = YAMLS[yaml_name]
    table = {**COMMON, **read_table(DOCS / table_name)}
    device = INSTRUMENTS[table_name](station)[0]
    for header in sorted(yaml_headers(YAML_DIR / yaml_name)):
        pattern = device.pattern_of(header)
        assert pattern is not None, f"{yaml_name}: {header} unknown to the simulator"
        forms, status = table[pattern]
        assert not status.startswith("refused"), f"{yaml_name}: {header} is {status} in {table_name}"
