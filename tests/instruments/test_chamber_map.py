"""docs/CHAMBER.md's register table is the one the simulator serves and the driver uses: a
change on any side that the others do not follow fails here."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import instruments.chamber as drv
from sim.devices import chamber_map as cm

DOC = Path(__file__).resolve().parents[2] / "docs" / "CHAMBER.md"


def doc_rows() -> dict[int, dict[str, str]]:
    rows = {}
    for line in DOC.read_text().splitlines():
        m = re.match(r"^\|\s*(\d+)\s*\|\s*(\w+)\s*\|\s*(\w+)\s*\|\s*(R|RW|W)\s*\|(.*)\|\s*([^|]+?)\s*\|$", line)
        if m:
            rows[int(m.group(1))] = {"name": m.group(2), "kind": m.group(3), "access": m.group(4),
                                     "source": m.group(6)}
    return rows


def test_the_documented_table_is_the_simulators_map():
    rows = doc_rows()
    assert len(rows) == len(cm.REGISTERS)
    for reg in cm.REGISTERS:
        row = rows[reg.address]
        assert (row["name"], row["kind"], row["access"]) == (reg.name, reg.kind, reg.access), reg
        assert row["source"].split()[0] == reg.source, reg


# the driver's register numbers, by the map's names
DRIVER = {
    "hardware_id": drv.HARDWARE_ID, "software_release": drv.SOFTWARE_RELEASE, "serial_number": drv.SERIAL_NUMBER,
    "part_number": drv.PART_NUMBER, "display_units": drv.DISPLAY_UNITS, "control_mode": drv.CONTROL_MODE,
    "control_mode_active": drv.CONTROL_MODE_ACTIVE, "set_point_low_c": drv.SET_POINT_LOW,
    "set_point_high_c": drv.SET_POINT_HIGH, "set_point_c": drv.SET_POINT,
    "working_set_point_c": drv.WORKING_SET_POINT, "ramp_action": drv.RAMP_ACTION, "ramp_scale": drv.RAMP_SCALE,
    "ramp_rate": drv.RAMP_RATE, "process_value_c": drv.PROCESS_VALUE, "alarm1_state": drv.ALARM_STATE[1],
    "alarm2_state": drv.ALARM_STATE[2], "alarm1_clear": drv.ALARM_CLEAR[1], "alarm2_clear": drv.ALARM_CLEAR[2],
    "limit_state": drv.LIMIT_STATE, "limit_low_c": drv.LIMIT_LOW, "limit_high_c": drv.LIMIT_HIGH,
    "limit_clear": drv.LIMIT_CLEAR,
}


@pytest.mark.parametrize("name", sorted(DRIVER))
def test_the_driver_uses_the_documented_numbers(name):
    rows = {row["name"]: address for address, row in doc_rows().items()}
    assert DRIVER[name] == rows[name]
    assert drv.REGISTER_NAMES[DRIVER[name]]  # every register it touches is named in its errors


def test_the_driver_and_the_simulator_agree_on_the_option_values():
    assert (drv.AUTO, drv.OFF, drv.RAMP_OFF, drv.RAMP_SET_POINT, drv.RAMP_BOTH, drv.PER_MINUTE, drv.CLEAR,
            drv.UNITS_C) == (cm.AUTO, cm.OFF, cm.RAMP_OFF, cm.RAMP_SET_POINT, cm.RAMP_BOTH, cm.PER_MINUTE,
                             cm.CLEAR, cm.UNITS_C)
    assert {v: k for k, v in drv.ALARM_STATES.items()} == {
        "startup": cm.ALARM_STARTUP, "none": cm.ALARM_NONE, "blocked": cm.ALARM_BLOCKED,
        "low": cm.ALARM_LOW, "high": cm.ALARM_HIGH, "error": cm.ALARM_ERROR}
    assert {v: k for k, v in drv.LIMIT_STATES.items()} == {
        "ok": cm.LIMIT_NONE, "high": cm.LIMIT_HIGH, "low": cm.LIMIT_LOW}
    assert drv.PART_NUMBER_WORDS == cm.BY_NAME["part_number"].words
