"""Typed interfaces per instrument kind.

A procedure asks for "a multimeter that can take a timed trace", not for a model
number: it annotates its parameters with these Protocols, and any driver (or test
double) with the same members fits.  Nothing here knows about clocks: drivers that
must let time pass take a :data:`Wait` callable from the caller (the bench clock).

Units are in the names (``_v``, ``_a``, ``_s``, ``_deg``, ``_dps``, ``_dps2``).

Every kind is also a :class:`SafeInstrument`: it knows how to bring itself to rest
(``make_safe``) and when, in a station's teardown, it should (``safe_order``: power sources
first, since what they feed goes quiet with them; then acquisitions; then motion).  A
teardown (``procedures.common.make_safe``) loops over the station's instruments in that
order and never names one.

The Protocols are deliberately not ``runtime_checkable``: on Python 3.11 an
``isinstance`` check reads every property, which would put queries on the wire.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Generator, Mapping, Sequence
from enum import IntEnum
from typing import Any, Protocol

import numpy as np

from .daq_types import ScanPlan, ScanReadings
from .fog_types import GyroConfig, GyroFrames

#: ``wait(seconds)``: let that much (bench-clock) time pass.  Drivers never sleep.
Wait = Callable[[float], None]


class SafeOrder(IntEnum):
    """When a station's teardown brings an instrument to rest: lower first, ties in station order."""

    #: power sources: what they feed stops with them (the station's gyro goes silent with its
    #: supply output), and nothing may stay powered because another instrument hung
    POWER = 0
    #: meters and data streams: acquisitions ended
    ACQUISITION = 1
    #: tables and shakers: brought to rest (after the rest, so a slow stop delays nothing else)
    MOTION = 2


class SafeInstrument(Protocol):
    """Anything a teardown brings to rest."""

    @property
    def safe_order(self) -> SafeOrder:
        """Its place in the teardown."""

    @property
    def safe_action(self) -> str:
        """What :meth:`make_safe` does, in a word or two (``off``, ``abort``, ``stop``): the
        teardown names a failure ``<instrument> <safe_action>: <error>``."""

    def make_safe(self) -> None:
        """Bring the instrument to rest; raise if it could not (naming what failed)."""


class TracePlanned(Protocol):
    """A configured timed trace (``instruments.multimeter.TracePlan``)."""

    @property
    def n_samples(self) -> int: ...

    @property
    def interval_s(self) -> float: ...

    @property
    def trigger_delay_s(self) -> float: ...

    @property
    def duration_s(self) -> float: ...


class TimedTraceMultimeter(SafeInstrument, Protocol):
    """A DC voltmeter that samples at a fixed interval and streams the readings."""

    @property
    def line_frequency_hz(self) -> float: ...

    @property
    def memory_depth(self) -> int: ...

    @property
    def aperture_range_s(self) -> tuple[float, float]: ...

    def configure_dc_voltage(
        self, range_v: float | None = ..., nplc: float | None = ...
    ) -> None: ...

    def measure_dc_voltage(self) -> float: ...

    def configure_timed_trace(
        self,
        n_samples: int,
        interval_s: float,
        *,
        nplc: float = ...,
        aperture_s: float | None = ...,
        range_v: float = ...,
        autozero: str = ...,
        trigger_delay_s: float = ...,
    ) -> TracePlanned: ...

    def initiate(self) -> None: ...

    def abort(self) -> None: ...

    def points_available(self) -> int: ...

    def fetch_all(self) -> np.ndarray: ...

    def read_and_remove(self, max_n: int) -> np.ndarray: ...

    def read_available(self, max_n: int | None = ...) -> np.ndarray: ...

    @property
    def trigger_delay_s(self) -> float: ...

    def reset(self) -> None: ...

    def snapshot(self) -> dict[str, Any]: ...

    def stream_trace(
        self, chunk_points: int = ..., *, wait: Wait, initiate: bool = ...,
        min_poll_s: float = ..., stall_timeout_s: float | None = ...,
    ) -> Generator[np.ndarray, None, None]: ...


class ScanningMultimeter(SafeInstrument, Protocol):
    """A data-acquisition unit scanning DC volts over multiplexer channels (test sockets)."""

    @property
    def line_frequency_hz(self) -> float: ...

    @staticmethod
    def channel_time_s(nplc: float, line_hz: float = ..., channel_delay_s: float | None = ...,
                       autozero: bool = ...) -> float: ...

    def configure_scan(self, channels: Sequence[int], *, interval_s: float, sweeps: int,
                       nplc: float = ..., range_v: float = ..., line_hz: float = ...,
                       channel_delay_s: float | None = ..., autozero: bool = ...) -> ScanPlan: ...

    def initiate(self) -> None: ...

    def abort(self) -> None: ...

    def points_available(self) -> int: ...

    def read_available(self, max_n: int | None = ...) -> ScanReadings: ...

    def stream_scan(self, wait: Wait, poll_s: float = ...,
                    timeout_s: float | None = ...) -> Generator[ScanReadings, None, None]: ...

    def snapshot(self) -> dict[str, Any]: ...


class SupplyChannel(Protocol):
    """One output of a DC supply."""

    voltage_setpoint_v: float
    current_limit_a: float
    output_enabled: bool

    @property
    def measured_voltage_v(self) -> float: ...

    @property
    def measured_current_a(self) -> float: ...

    def apply(self, voltage_v: float, current_a: float) -> None: ...


class PowerSupply(SafeInstrument, Protocol):
    """A multi-output DC supply with outputs addressed ``ch[1]``, ``ch[2]``, ..."""

    @property
    def ch(self) -> Mapping[int, SupplyChannel]: ...

    def set_outputs(self, channels: Any, enabled: bool) -> None: ...

    def outputs_off(self) -> None: ...

    def snapshot(self) -> dict[str, Any]: ...


class RateTableAxis(Protocol):
    """One axis of a position/rate table."""

    mode: str
    position_demand_deg: float
    rate_demand_dps: float
    rate_limit_dps: float
    accel_limit_dps2: float

    @property
    def position_deg(self) -> float: ...

    @property
    def rate_dps(self) -> float: ...

    @property
    def accel_dps2(self) -> float: ...

    @property
    def status(self) -> Any: ...

    def move_to(self, position_deg: float) -> None: ...

    def set_rate(self, rate_dps: float) -> None: ...

    def stop(self) -> None: ...

    def wait_in_position(self, wait: Wait, timeout_s: float, poll_s: float = ...) -> Any: ...

    def wait_at_rate(self, wait: Wait, timeout_s: float, poll_s: float = ...) -> Any: ...


class PositionRateTable(SafeInstrument, Protocol):
    """A table of numbered axes behind one interlock."""

    @property
    def axis(self) -> Mapping[int, RateTableAxis]: ...

    @property
    def interlock_closed(self) -> bool: ...

    def interlock_close(self) -> None: ...

    def interlock_open(self) -> None: ...

    def interlock_reset(self) -> None: ...

    def stop_all(self) -> list[Any]: ...

    def snapshot(self) -> dict[str, Any]: ...


class FrameGyro(SafeInstrument, Protocol):
    """A gyro streaming angle-increment frames (counts, temperature, status) on a line."""

    streaming: bool

    @property
    def rate_hz(self) -> int: ...

    @property
    def config(self) -> GyroConfig: ...

    def identify(self) -> Any: ...

    def configure(self, *, rate_hz: int | None = ..., baud: int | None = ...,
                  scale_factor_pulses_per_arcsec: float | None = ...,
                  polarity: int | None = ...) -> None: ...

    def start(self) -> None: ...

    def stop(self) -> GyroFrames: ...

    def read_frames(self, n: int, timeout_s: float = ..., *, wait: Wait | None = ...) -> GyroFrames: ...

    def snapshot(self) -> dict[str, Any]: ...


class RandomVibrationTable(SafeInstrument, Protocol):
    """A shaker with its vibration controller: profile, level, start/stop, control level."""

    level_db: float
    ramp_time_s: float

    @property
    def state(self) -> str: ...

    @property
    def level_grms(self) -> float: ...

    @property
    def target_grms(self) -> float: ...

    def set_random_profile(self, freqs_hz: Any = ..., asd_g2hz: Any = ..., *,
                           grms: float | None = ..., f_lo_hz: float = ...,
                           f_hi_hz: float = ...) -> Any: ...

    def set_sine(self, freq_hz: float, peak_g: float) -> Any: ...

    def configuring(self) -> contextlib.AbstractContextManager[Any]: ...

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def wait_running(self, wait: Wait, timeout_s: float, poll_s: float = ...) -> str: ...

    def wait_idle(self, wait: Wait, timeout_s: float, poll_s: float = ...) -> str: ...

    def snapshot(self) -> dict[str, Any]: ...


class AngularLimited(Protocol):
    """An angular vibration table's peak angle (°), rate (°/s) and angular acceleration (°/s²)
    (``instruments.angular_table.AngularLimits``)."""

    @property
    def angle_deg(self) -> float: ...

    @property
    def rate_dps(self) -> float: ...

    @property
    def accel_dps2(self) -> float: ...


class AngularTable(SafeInstrument, Protocol):
    """An angular vibration table and its controller: tones, start/stop, a reference capture
    (encoder angle and reference rate) on the table's own clock."""

    ramp_time_s: float

    @property
    def state(self) -> str: ...

    def limits(self) -> AngularLimited: ...

    def set_tones(self, tones: Sequence[Sequence[float]]) -> Any: ...

    def configure_sweep(self, start_hz: float, stop_hz: float, duration_s: float, amplitude_dps: float,
                        spacing: str = ...) -> Any: ...

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def wait_running(self, wait: Wait, timeout_s: float, poll_s: float = ...) -> str: ...

    def wait_idle(self, wait: Wait, timeout_s: float, poll_s: float = ...) -> str: ...

    def configure_reference(self, rate_hz: float, count: int) -> None: ...

    def start_reference(self) -> None: ...

    def abort_reference(self) -> None: ...

    def read_reference(self, max_points: int | None = ...) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def snapshot(self) -> dict[str, Any]: ...


class ThermalChamber(SafeInstrument, Protocol):
    """A temperature test chamber's controller (``instruments.chamber.WatlowF4TChamber``).

    Temperatures in °C; the air temperature is the process value.  Settings are checked
    against the controller's ranges before anything goes on the wire; waits take the bench
    clock's ``wait`` and raise ``ChamberFaultError`` when the limit trips or an alarm is
    active.  ``make_safe``: standby at the lab-ambient set point.
    """

    @property
    def set_point_range_c(self) -> tuple[float, float]: ...

    @property
    def set_point_c(self) -> float: ...

    def set_set_point(self, set_point_c: float) -> None: ...

    @property
    def working_set_point_c(self) -> float: ...

    @property
    def process_value_c(self) -> float: ...

    @property
    def ramp_rate_c_per_min(self) -> float | None: ...

    def set_ramp(self, rate_c_per_min: float | None) -> None: ...

    @property
    def running(self) -> bool: ...

    def run(self) -> None: ...

    def standby(self) -> None: ...

    def alarms(self) -> tuple[Any, ...]: ...

    def clear_alarms(self) -> None: ...

    @property
    def limit_state(self) -> str: ...

    def clear_limit(self) -> None: ...

    def status(self) -> Any: ...

    def check(self) -> Any: ...

    def wait_for_temperature(self, wait: Wait, target_c: float, tolerance_c: float, hold_s: float,
                             timeout_s: float, poll_s: float = ...) -> Any: ...

    def wait_until_settled(self, wait: Wait, tolerance_c: float = ..., hold_s: float = ...,
                           timeout_s: float = ..., poll_s: float = ...) -> Any: ...

    def identify(self) -> Any: ...

    def snapshot(self) -> dict[str, Any]: ...
