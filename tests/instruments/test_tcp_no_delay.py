"""Resources opened by the bench send each message at once (TCP_NODELAY), as NI-VISA does by
default, also after a reconnect; the replies are the same either way."""

from __future__ import annotations

import socket

from instruments.base import open_resource
from instruments.multimeter import Keysight34465A


def _no_delay(resource) -> int:
    sock = resource.visalib.sessions[resource.session].interface
    return int(sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY))


def test_a_tcpip_socket_resource_has_no_delay_even_after_a_reconnect(served_station):
    res = open_resource(served_station.resources()["dmm"])
    try:
        assert _no_delay(res) == 1
        dmm = Keysight34465A(res, name="dmm")
        dmm.reconnect()
        assert _no_delay(res) == 1
        assert "34465A" in res.query("*IDN?")
    finally:
        res.close()
