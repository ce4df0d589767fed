"""Simulated supply (current limit, rails → unit power) and turntable controller semantics."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def station(station_factory):
    return station_factory(seed=1)  # not served: devices driven directly


def ask(dev, text):
    out = dev.process(text.encode())
    return None if out is None else out.decode().strip()


def test_unit_is_powered_only_with_both_rails_in_range(station):
    s, accel, now = station.supply, station.accel, lambda: station.world.now
    ask(s, "APPL CH2,15,0.1")
    ask(s, "APPL CH3,15,0.1")
    ask(s, "OUTP ON,(@2)")
    assert not bool(accel.powered(now()))
    ask(s, "OUTP ON,(@3)")
    assert bool(accel.powered(now()))
    assert accel.power_on_time_s == 0.0
    station.world.advance(5)
    ask(s, "VOLT 20,(@3)")           # outside the unit's ±13..18 V range
    assert not bool(accel.powered(now()))
    ask(s, "VOLT 12.5,(@3)")
    assert not bool(accel.powered(now()))
    ask(s, "VOLT 14,(@3)")
    assert bool(accel.powered(now()))


def test_current_limit_below_the_draw_collapses_the_rail(station):
    s = station.supply
    ask(s, "APPL CH2,15,0.1;APPL CH3,15,0.005")  # 5 mA limit < 16 mA quiescent draw
    ask(s, ":OUTP ON,(@2,3)")
    assert [ask(s, f"STAT:OPER:INST:ISUM{n}:COND?") for n in (1, 2, 3)] == ["0", "2", "1"]  # off, CV, CC
    volts = [float(v) for v in ask(s, "MEAS:VOLT? (@2,3)").split(",")]
    assert volts[0] == pytest.approx(15.0) and volts[1] < 13.0
    assert not bool(station.accel.powered(station.world.now))


def test_supply_refuses_bad_channels_and_values_with_standard_codes(station):
    s = station.supply
    ask(s, "VOLT 5,(@4)")
    assert ask(s, "SYST:ERR?").startswith("-222")
    ask(s, "APPL CH9,1,1")
    assert ask(s, "SYST:ERR?").startswith("-224")
    ask(s, "OUTP MAYBE")
    assert ask(s, "SYST:ERR?").startswith("-224")
    assert ask(s, "SYST:ERR?") == '+0,"No error"'


def test_rate_mode_ramps_at_the_acceleration_limit(station):
    t = station.turntable
    ask(t, ":LIM:ACC 1,10;:LIM:RATE 1,100")
    ask(t, ":MODE:RATE 1;:DEM:RATE 1,50")
    assert ask(t, "SYST:ERR?") == '+0,"No error"'
    station.world.advance(2.0)
    assert float(ask(t, ":READ:RATE? 1")) == pytest.approx(20.0, abs=0.5)  # 10 °/s² × 2 s
    station.world.advance(10.0)
    assert float(ask(t, ":READ:RATE? 1")) == pytest.approx(50.0, abs=0.01)
    assert int(ask(t, ":STAT? 1")) & 4  # at rate
    ask(t, ":DEM:RATE 1,500")                  # above the user rate limit
    assert ask(t, "SYST:ERR?").startswith("-222")


def test_turntable_position_demand_requires_position_mode_and_closed_interlock(station):
    t = station.turntable
    ask(t, ":DEM:POS 1,10")
    assert ask(t, "SYST:ERR?").startswith("-221")
    ask(t, ":INT:OPEN")
    assert ask(t, ":INT?") == "0"
    ask(t, ":MODE:POS 1")
    assert ask(t, "SYST:ERR?").startswith("-221")
    assert int(ask(t, ":STAT? 1")) & 16
    ask(t, ":INT:CLOS")
    ask(t, ":MODE:POS 1;:DEM:POS 1,-45")
    station.world.advance(30)
    assert float(ask(t, ":READ:POS? 1")) == pytest.approx(-45.0, abs=1e-3)
    f = station.specific_force_iapo_g(np.array([station.world.now]))
    assert f[0, 0] == pytest.approx(station.g_mps2 / 9.80665, rel=1e-9)  # IA still vertical


def test_a_channel_list_with_one_bad_value_changes_nothing(station):
    s = station.supply
    ask(s, "VOLT 10,(@2,1)")  # 10 V is fine for CH2, too much for CH1 (6 V)
    assert ask(s, "SYST:ERR?").startswith("-222")
    assert ask(s, "VOLT? (@1,2)") == "+0.00000000E+00,+0.00000000E+00"


def test_limit_queries_answer_per_channel_and_per_axis(station):
    assert ask(station.supply, "VOLT? MAX,(@1,2)") == "+6.00000000E+00,+2.50000000E+01"
    assert ask(station.supply, "CURR? MAX,(@3)") == "+1.00000000E+00"
    assert ask(station.supply, "APPL? P25V") == '"+0.00000000E+00,+1.00000000E+00"'
    t = station.turntable
    assert float(ask(t, ":LIM:RATE? 1,MAX")) == station.table.axes[0].rate_max_dps
    ask(t, ":MODE:POS 3")
    assert ask(t, "SYST:ERR?").startswith("-222")  # two axes
    ask(t, ":MODE:POS 1.6")  # SCPI rounds decimal data for integer parameters: axis 2
    assert ask(t, ":MODE? 2") == "POS" and ask(t, ":MODE? 1") == "OFF"
