"""Instrument drivers: one per instrument kind, speaking only through a pyvisa resource.

    from instruments import open_resource, Keysight34465A
    dmm = Keysight34465A(open_resource("TCPIP::127.0.0.1::5025::SOCKET"))
"""

from .base import (
    Identity,
    InstrumentChannel,
    InstrumentError,
    InstrumentReplyError,
    SCPIInstrument,
    UnsupportedInstrumentError,
    channel_list,
    open_resource,
)
from .multimeter import Keysight34465A, TracePlan
from .power_supply import CHANNEL_RATINGS, ChannelRating, KeysightE36312A, SupplyOutput
from .protocols import (
    PositionRateTable,
    PowerSupply,
    RateTableAxis,
    SupplyChannel,
    TimedTraceMultimeter,
    Wait,
)
from .turntable import (
    AxisFaultError,
    AxisLimits,
    AxisStatus,
    DualAxisTurntable,
    StopFailure,
    TableAxis,
)

__all__ = [
    "AxisFaultError",
    "AxisLimits",
    "AxisStatus",
    "CHANNEL_RATINGS",
    "ChannelRating",
    "DualAxisTurntable",
    "Identity",
    "InstrumentChannel",
    "InstrumentError",
    "InstrumentReplyError",
    "Keysight34465A",
    "KeysightE36312A",
    "PositionRateTable",
    "PowerSupply",
    "RateTableAxis",
    "SCPIInstrument",
    "StopFailure",
    "SupplyChannel",
    "SupplyOutput",
    "TableAxis",
    "TimedTraceMultimeter",
    "TracePlan",
    "UnsupportedInstrumentError",
    "Wait",
    "channel_list",
    "open_resource",
]
