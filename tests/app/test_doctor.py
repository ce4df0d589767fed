"""`bench doctor`: a healthy simulated station passes; a wrong address, queued errors or a
missing option fail the instrument concerned; a station that cannot be opened exits 2."""

from __future__ import annotations

import json
import socket

import pytest

from bench.app.cli import main
from sim.station import INSTRUMENTS

#: what doctor checks on the built-in station: every instrument of its table, then its clock
CHECKED = [row.name for row in INSTRUMENTS] + ["clock"]


@pytest.fixture(scope="module")
def sim(served_station):
    return served_station


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed on exit: nothing listens there


def _station_file(tmp_path, sim, *, dmm_address=None, dmm_options=None) -> str:
    res = sim.resources()
    dmm = dmm_address or res["dmm"]
    options = "" if dmm_options is None else f"options = {json.dumps(dmm_options)}\n"
    text = (f'[station]\nname = "doctor-test"\n\n'
            f'[instruments.dmm]\ndriver = "keysight_34465a"\naddress = "{dmm}"\n'
            f'timeout_ms = 2000\n{options}\n'
            f'[instruments.supply]\ndriver = "keysight_e36312a"\naddress = "{res["supply"]}"\n\n'
            f'[instruments.gyro]\ndriver = "fog_serial"\naddress = "{res["gyro"]}"\n'
            f'timeout_ms = 2000\n')
    path = tmp_path / "station.toml"
    path.write_text(text)
    return str(path)


def test_builtin_sim_station_is_healthy(capsys):
    assert main(["doctor"]) == 0
    out = capsys.readouterr().out
    assert len(CHECKED) == len(INSTRUMENTS) + 1  # and the clock
    for name in CHECKED:
        assert f"\n{name} " in out
    assert "all healthy" in out and "FAIL" not in out


def test_json_shape(capsys):
    assert main(["doctor", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["station"] == "sim" and doc["healthy"] is True
    rows = {r["name"]: r for r in doc["instruments"]}
    assert list(rows) == CHECKED  # in table order
    assert {r["driver"] for r in doc["instruments"][:-1]} == {row.driver for row in INSTRUMENTS}
    for row in rows.values():
        assert set(row) >= {"driver", "address", "identity", "errors", "status", "reason",
                            "round_trip_ms", "options", "expected_options"}
    assert rows["dmm"]["status"] == "OK" and rows["dmm"]["errors"] == []
    assert rows["dmm"]["identity"].startswith("Keysight Technologies,34465A,")
    assert rows["dmm"]["round_trip_ms"] > 0
    assert rows["gyro"]["status"] == "OFF" and "CH1" in rows["gyro"]["reason"]


def test_wrong_address_fails_that_instrument_only(tmp_path, sim, capsys):
    path = _station_file(tmp_path, sim, dmm_address=f"TCPIP::127.0.0.1::{_closed_port()}::SOCKET")
    assert main(["doctor", "--station", path, "--json"]) == 1
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)["instruments"]}
    assert rows["dmm"]["status"] == "FAIL" and "cannot open instrument 'dmm'" in rows["dmm"]["reason"]
    assert rows["supply"]["status"] == "OK"
    assert rows["gyro"]["status"] == "OFF"
    assert "clock" not in rows  # a wall-clock station has no sim-control endpoint


def test_expected_options_checked(tmp_path, sim, capsys):
    assert main(["doctor", "--station", _station_file(tmp_path, sim, dmm_options=["dig", "MEM"]),
                 "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)["instruments"]}
    assert rows["dmm"]["options"] == ["DIG", "MEM"]
    assert main(["doctor", "--station", _station_file(tmp_path, sim, dmm_options=["DIG", "GPIB"])]) == 1
    out = capsys.readouterr().out
    assert "FAIL (options ['GPIB'] missing" in out


def test_queued_error_fails_and_powered_gyro_is_asked(tmp_path, sim, capsys):
    sim.server.call(sim.dmm.push_error, -222, "left over")
    sim.server.call(sim.supply.process, b"APPL CH1,5,1;:OUTP ON,(@1)")
    try:
        assert main(["doctor", "--station", _station_file(tmp_path, sim), "--json"]) == 1
        rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)["instruments"]}
        assert rows["dmm"]["status"] == "FAIL"
        assert rows["dmm"]["errors"] == ['-222,"Data out of range;left over"']
        assert rows["gyro"]["status"] == "OK" and ",SFOG-2K," in rows["gyro"]["identity"]
        # the queue was drained by the first check: the next one is clean
        assert main(["doctor", "--station", _station_file(tmp_path, sim)]) == 0
    finally:
        sim.server.call(sim.supply.process, b"OUTP OFF,(@1)")


@pytest.mark.parametrize("content,fragment", [
    (None, "not found"),
    ("[station\n", "not valid TOML"),
    ('[station]\nname = "empty"\n', "configures no instruments"),
    ('[instruments.dmm]\ndriver = "keysight_34465a"\naddress = "x"\noptions = "DIG"\n',
     "must be a list of option codes"),
])
def test_station_that_cannot_be_opened_exits_2(tmp_path, capsys, content, fragment):
    path = tmp_path / "s.toml"
    if content is not None:
        path.write_text(content)
    assert main(["doctor", "--station", str(path)]) == 2
    assert fragment in capsys.readouterr().err
