"""The batch fixture of the simulated station: up to eight accelerometers on the turntable,
each in a test socket wired to a channel of the scanning DAQ (``daq``, a DAQ970A with a
DAQM901A multiplexer in slot 1).

Wiring (what the fixture's harness does):

* socket ``n`` (1..8) → its unit's output current → its own sampling resistor
  (the station's ``sampling_resistor_ohm``) → DAQ channel ``fixture_first_channel + n − 1``
  (101 + n − 1 by default);
* every socket's unit on the station's accelerometer rails (supply CH2 / CH3 inverted), in
  parallel: the supply sees the sum of their quiescent currents;
* every unit fixed to the turntable platform with the station's mount (IA along platform
  z), in the chamber air with the table: a turntable position is one position for the whole
  batch;
* ``open_sockets``: sockets whose unit's output lead is open (a connector not seated): the
  channel reads the fixture filter's 0 V.

``fixture_units`` (overrides) and ``fixture_open`` describe sockets; they apply to the unit a
batch puts in that socket, and to nothing while it is empty.

Each unit is drawn by its serial (``draw_accelerometer``), with its own noise stream
(``world.rng("accelerometer:<serial>")``, as the single unit of the same serial): the same
serial is the same unit in any socket.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from sim.devices.daq import ScanningDaq
from sim.devices.dmm_model import LinePickup
from sim.physics.accelerometer import QuartzAccelerometer, draw_accelerometer
from sim.physics.thermal_unit import AmbientSource
from sim.world import World

MAX_SOCKETS = 8
FIRST_CHANNEL = 101  # socket 1's DAQ channel by default
LAST_FIRST_CHANNEL = 120 - MAX_SOCKETS + 1  # eight sockets must fit on the DAQM901A (101..120)

#: specific force along (IA, PA, OA) at the given times, g
SpecificForce = Callable[[np.ndarray], np.ndarray]


def _socket_number(key, where: str) -> int:
    try:
        n = int(key)
    except (TypeError, ValueError):
        raise ValueError(f"{where} socket {key!r} not in 1..{MAX_SOCKETS}") from None
    if isinstance(key, bool) or not 1 <= n <= MAX_SOCKETS:
        raise ValueError(f"{where} socket {key!r} not in 1..{MAX_SOCKETS}")
    return n


def check_fixture(sockets: Mapping, overrides: Mapping, open_sockets, tau_s: float) -> dict[int, str]:
    """The fixture's sockets as ``{socket: serial}``; ValueError naming a bad entry."""
    if not isinstance(sockets, Mapping):
        raise ValueError(f"fixture = {sockets!r} must be a table socket = serial")
    out: dict[int, str] = {}
    for key, serial in sockets.items():
        n = _socket_number(key, "fixture")
        if not isinstance(serial, str) or not 0 < len(serial) <= 64:
            raise ValueError(f"fixture socket {n}: serial {serial!r} must be text of 1..64 characters")
        if serial in out.values():
            raise ValueError(f"fixture socket {n}: serial {serial!r} is already in another socket")
        out[n] = serial
    # overrides and open leads describe the fixture's sockets; they apply to a socket's unit
    # when the batch puts one there (a station file names them before any serial is known)
    if not isinstance(overrides, Mapping):
        raise ValueError(f"fixture_units = {overrides!r} must be a table socket = {{parameters}}")
    for key, table in overrides.items():
        n = _socket_number(key, "fixture_units")
        draw_accelerometer(out.get(n, "QA-SIM-0001"), dict(table))
    if not isinstance(open_sockets, (list, tuple)):
        raise ValueError(f"fixture_open = {open_sockets!r} must be a list of sockets")
    for key in open_sockets:
        _socket_number(key, "fixture_open")
    if isinstance(tau_s, bool) or not isinstance(tau_s, (int, float)) or not 1e-7 <= tau_s <= 1.0:
        raise ValueError(f"fixture_settling_tau_s = {tau_s!r} not in 1e-07..1 s")
    return out


class Fixture:
    """The sockets' units and the DAQ that reads them."""

    def __init__(self, world: World, sockets: Mapping[int, str], *, overrides: Mapping,
                 open_sockets, specific_force: SpecificForce, sampling_resistor_ohm: float,
                 line_pickup: LinePickup, settling_tau_s: float, ideal_meters: bool,
                 ambient: AmbientSource | None = None, first_channel: int = FIRST_CHANNEL) -> None:
        """``ambient``: the air the fixture stands in (the station's chamber air);
        ``first_channel``: socket 1's DAQ channel (socket n on ``first_channel + n − 1``)."""
        if isinstance(first_channel, bool) or not isinstance(first_channel, int) \
                or not FIRST_CHANNEL <= first_channel <= LAST_FIRST_CHANNEL:
            raise ValueError(f"fixture_first_channel = {first_channel!r} not in "
                             f"{FIRST_CHANNEL}..{LAST_FIRST_CHANNEL} (8 sockets on channels 101..120)")
        self.first_channel = first_channel
        self.sockets = dict(sockets)
        self.open_sockets = {int(n) for n in open_sockets}
        by_socket = {int(k): dict(v) for k, v in overrides.items()}
        self.units = {n: QuartzAccelerometer(draw_accelerometer(serial, by_socket.get(n, {})),
                                             world.rng(f"accelerometer:{serial}"), ambient=ambient,
                                             turn_on_rng=world.rng(f"accelerometer-turn-on:{serial}"))
                      for n, serial in sorted(self.sockets.items())}
        self._force = specific_force
        self._ohm = float(sampling_resistor_ohm)
        inputs = {first_channel + n - 1: self._output(n) for n in self.units
                  if n not in self.open_sockets}
        self.daq = ScanningDaq(world, "daq", inputs, line_pickup=line_pickup,
                               settling_tau_s=settling_tau_s, ideal=ideal_meters)

    def _output(self, socket: int) -> Callable[[np.ndarray, float], np.ndarray]:
        unit = self.units[socket]

        def volts(t_start: np.ndarray, aperture_s: float) -> np.ndarray:
            # evaluated at mid-aperture, or just after a power change inside the aperture
            t_mid = np.maximum(t_start + aperture_s / 2, unit.last_supply_change_s)
            return unit.output_current_a(t_mid, self._force(t_mid), aperture_s) * self._ohm
        return volts

    def set_rails(self, t: float, v_pos: float, v_neg: float) -> None:
        for unit in self.units.values():
            unit.set_supply(t, v_pos, v_neg)

    def quiescent_current_a(self, volts: float) -> float:
        """What the fixture draws from one rail at ``volts``."""
        return sum(u.params.quiescent_current_a for u in self.units.values()
                   if u.params.supply_min_v <= volts <= u.params.supply_max_v)

    def truth(self) -> dict[int, dict]:
        """Each socket's true unit parameters (for recovery tests, never for procedures)."""
        return {n: {"serial": self.sockets[n], **u.truth()} for n, u in self.units.items()}


__all__ = ["Fixture", "MAX_SOCKETS", "FIRST_CHANNEL", "check_fixture"]
