"""Two drivers on one meter at once, as two scripts (or a script and a logger) share a bench
instrument: QCoDeS's ``Keysight34465A`` over HiSLIP and PyMeasure's ``HP34401A`` over the raw
socket, both open for the whole module.  They share the instrument — a setting made through
one is read through the other, and both fetch the same readings — but each connection is its
own I/O session: an error one of them makes is in its own ``SYST:ERR?``, never the other's
(docs/vocabulary/README.md, "Sessions").

Two connections are ordered only by a round trip: before the other session looks, the one
that wrote waits for an answer of its own (``*OPC?``), as a user's script must."""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from pymeasure.instruments.hp import HP34401A
from qcodes.instrument_drivers.Keysight import Keysight34465A

from tests.compat.serving import pymeasure_options

NO_ERROR = (0, "No error")


@pytest.fixture(scope="module")
def pair(served):
    """(QCoDeS over HiSLIP, PyMeasure over the socket), the same simulated 34465A."""
    qcodes_dmm = Keysight34465A("compat_dmm_shared", served[("dmm", "hislip")], visalib="@py", timeout=10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # HP34401A: SCPI support "unknown"
        pymeasure_dmm = HP34401A(served[("dmm", "scpi")], **pymeasure_options("scpi"))
    yield qcodes_dmm, pymeasure_dmm
    pymeasure_dmm.adapter.close()
    qcodes_dmm.close()


@pytest.fixture
def both(pair):
    qcodes_dmm, pymeasure_dmm = pair
    qcodes_dmm.reset()      # *RST: the instrument's, for both
    qcodes_dmm.write("*CLS")
    pymeasure_dmm.clear()   # *CLS: each session clears its own queue
    yield pair
    assert qcodes_dmm.error() == NO_ERROR
    assert pymeasure_dmm.check_errors() == []


def _parsed(qcodes_dmm, pymeasure_dmm) -> None:
    """A round trip on each session (``*OPC?``): what either wrote has been parsed."""
    assert (qcodes_dmm.ask("*OPC?"), pymeasure_dmm.complete) == ("1", "1")


def test_a_setting_made_through_one_driver_is_read_through_the_other(both):
    qcodes_dmm, pymeasure_dmm = both
    qcodes_dmm.NPLC(0.2)
    _parsed(*both)
    assert pymeasure_dmm.nplc == pytest.approx(0.2)
    pymeasure_dmm.nplc = 100
    _parsed(*both)
    assert qcodes_dmm.NPLC() == 100.0
    qcodes_dmm.autorange("OFF")
    qcodes_dmm.range(100)
    _parsed(*both)
    assert pymeasure_dmm.range_ == 100.0 and pymeasure_dmm.autorange is False
    pymeasure_dmm.sample_count = 250
    pymeasure_dmm.trigger_source = "BUS"
    _parsed(*both)
    assert (qcodes_dmm.sample.count(), qcodes_dmm.trigger.source()) == (250, "BUS")
    qcodes_dmm.display.text("FROM QCODES")
    _parsed(*both)
    assert pymeasure_dmm.displayed_text == "FROM QCODES"
    pymeasure_dmm.reset()   # *RST through the socket resets what QCoDeS set too
    _parsed(*both)
    assert (qcodes_dmm.NPLC(), qcodes_dmm.range(), qcodes_dmm.display.text()) == (10.0, 10.0, "")


def test_both_fetch_the_readings_one_of_them_started(both, powered):
    qcodes_dmm, pymeasure_dmm = both
    qcodes_dmm.NPLC(0.02)
    qcodes_dmm.sample.count(200)
    qcodes_dmm.init_measurement()           # INIT through HiSLIP
    assert qcodes_dmm.error() == NO_ERROR   # parsed (SYST:ERR?: *OPC? would wait for the end)
    assert pymeasure_dmm.complete == "1"    # *OPC? through the socket waits for the end
    assert pymeasure_dmm.stored_readings_count == 200
    through_socket = np.asarray(pymeasure_dmm.stored_reading)
    through_hislip = qcodes_dmm.fetch()     # FETC? leaves the readings in memory
    assert through_socket.shape == through_hislip.shape == (200,)
    np.testing.assert_array_equal(through_socket, through_hislip)
    assert np.mean(through_hislip) == pytest.approx(6.6, rel=0.05)


def test_an_error_made_on_one_session_stays_in_that_sessions_queue(both):
    qcodes_dmm, pymeasure_dmm = both
    pymeasure_dmm.write("VOLT:NPLC 7e3")    # out of range, through the socket
    assert pymeasure_dmm.complete == "1"    # it has been parsed
    assert qcodes_dmm.error() == NO_ERROR
    code, message = pymeasure_dmm.next_error
    assert code == -222 and "NPLC 7000 not in 0.001..100" in message

    qcodes_dmm.write("SENS:BOGUS 1")        # an unknown header, through HiSLIP
    assert qcodes_dmm.ask("*OPC?") == "1"
    assert pymeasure_dmm.check_errors() == []
    code, _ = qcodes_dmm.error()
    assert code == -113
    assert qcodes_dmm.error() == NO_ERROR


def test_clearing_one_sessions_status_leaves_the_others_errors(both):
    qcodes_dmm, pymeasure_dmm = both
    pymeasure_dmm.write("DISP:BOGUS")
    qcodes_dmm.write("SENS:BOGUS 1")
    assert (pymeasure_dmm.complete, qcodes_dmm.ask("*OPC?")) == ("1", "1")
    qcodes_dmm.write("*CLS")                # clears QCoDeS's session only
    assert qcodes_dmm.ask("SYST:ERR:COUN?") == "+0"
    assert pymeasure_dmm.ask("SYST:ERR:COUN?").strip() == "+1"
    assert pymeasure_dmm.next_error[0] == -113


def test_queries_from_both_at_once_each_get_their_own_answers(both):
    """Two threads, one driver each, querying as fast as they can: the server interleaves the
    sessions, and no reply reaches the wrong one."""
    qcodes_dmm, pymeasure_dmm = both
    qcodes_dmm.sample.count(250)
    qcodes_dmm.NPLC(0.2)
    _parsed(*both)

    def through_qcodes():
        return [qcodes_dmm.sample.count() for _ in range(60)]

    def through_pymeasure():
        return [pymeasure_dmm.nplc for _ in range(60)]

    with ThreadPoolExecutor(2) as pool:
        counts, nplcs = pool.submit(through_qcodes), pool.submit(through_pymeasure)
        assert counts.result(60) == [250] * 60
        assert nplcs.result(60) == [pytest.approx(0.2)] * 60
