"""Example-based tests of the shared IEEE 488.2 / SCPI engine (sim.scpi)."""

from __future__ import annotations

import pytest

from sim.scpi import (
    Args,
    MessageFramer,
    Oversize,
    ScpiDevice,
    ScpiError,
    format_block,
    format_bool,
    format_int,
    format_number,
    format_numbers,
    format_string,
)
from sim.scpi.errors import ERROR_MESSAGES, error_text

IDN = ("Keysight Technologies", "34465A", "MY59000001", "A.03.01-03.15-03.01-00.52-03-02")


class FakeDmm(ScpiDevice):
    """A small DMM-like tree exercising every parameter type."""

    def __init__(self, **kw):
        kw.setdefault("options", "DIG,MEM")
        kw.setdefault("error_queue_size", 5)
        super().__init__(IDN, **kw)
        self.calls: list[tuple[str, tuple, list[str]]] = []
        self.nplc = 10.0
        self.range_v = 10.0
        self.trigger_source = "IMMEDIATE"
        self.outputs: dict[int, bool] = {}
        self.data = b""
        self.text = ""
        self.closed: list[int] = []
        self.freq_hz = 0.0
        self.count = 1
        self.resets = self.waits = 0
        c = self.command
        c("[SENSe:]VOLTage[:DC]:NPLCycles", set=self._set_nplc,
          query=lambda a: format_number(self.nplc))
        c("[SENSe:]VOLTage[:DC]:RANGe", set=self._set_range)
        c("[SENSe:]VOLTage[:DC]:RANGe", query=lambda a: format_number(self.range_v))
        c("TRIGger:SOURce", set=lambda a: setattr(self, "trigger_source", a.choice(
            0, ["IMMediate", "BUS", "EXTernal", "TIMer"])),
          query=lambda a: self.trigger_source[:3] if self.trigger_source != "IMMEDIATE" else "IMM")
        c("TRIGger:COUNt", set=lambda a: setattr(self, "count", a.integer(0, min=1, max=1000, default=1)),
          query=lambda a: format_int(self.count))
        c("OUTPut#[:STATe]", set=self._set_output,
          query=lambda a: format_bool(self.outputs.get(a.suffixes[0], False)), max_suffix=3)
        c("DATA:BLOCk", set=lambda a: setattr(self, "data", a.block(0)),
          query=lambda a: format_block(self.data))
        c("DISPlay:TEXT", set=lambda a: setattr(self, "text", a.string(0)),
          query=lambda a: format_string(self.text))
        c("ROUTe:CLOSe", set=lambda a: setattr(self, "closed", a.channel_list(0, min=1, max=8)))
        c("SOURce#:FREQuency", set=lambda a: setattr(
            self, "freq_hz", a.number(0, min=0, max=1e7, units="HZ")))
        c("SYSTem:BEEPer", set=self._record)
        c("MEASure:VOLTage[:DC]?", query=lambda a: format_number(1.5))
        c("DIAGnostic:CRASh", set=lambda a: 1 / 0)
        c("DIAGnostic:NONE", query=lambda a: None)

    def _record(self, a: Args) -> None:
        self.calls.append((a.header, a.suffixes, a.raw))

    def _set_nplc(self, a: Args) -> None:
        a.require_count(1)
        self.nplc = a.number(0, min=0.001, max=100, default=10)

    def _set_range(self, a: Args) -> None:
        a.require_count(1)
        self.range_v = a.number(0, min=0.1, max=1000, default=10, units="V")

    def _set_output(self, a: Args) -> None:
        self.outputs[a.suffixes[0]] = a.boolean(0)

    def reset(self) -> None:
        self.resets += 1
        self.nplc = 10.0

    def wait_complete(self) -> None:
        self.waits += 1


@pytest.fixture
def dmm() -> FakeDmm:
    return FakeDmm()


def err(dev: ScpiDevice) -> str:
    reply = dev.ask("SYST:ERR?")
    assert reply is not None  # a query always answers
    return reply


# ---------------------------------------------------------------- common commands
def test_idn_opt_and_compound_queries(dmm):
    assert dmm.process(b"*IDN?") == (",".join(IDN) + "\n").encode()
    assert dmm.process(b"*OPT?") == b"DIG,MEM\n"
    assert dmm.process(b"*IDN?;*OPT?") == (",".join(IDN) + ";DIG,MEM\n").encode()
    assert dmm.process(b"*idn?") == (",".join(IDN) + "\n").encode()


def test_rst_calls_device_reset_but_keeps_error_queue(dmm):
    dmm.process(b"VOLT:NPLC 1;:FOO")
    assert dmm.nplc == 1.0
    assert dmm.process(b"*RST") is None
    assert dmm.resets == 1 and dmm.nplc == 10.0
    assert err(dmm) == '-113,"Undefined header"'


def test_cls_clears_queue_and_esr(dmm):
    dmm.process(b"FOO;BAR")
    assert dmm.ask("SYST:ERR:COUN?") == "+2"
    dmm.process(b"*CLS")
    assert dmm.ask("SYST:ERR:COUN?") == "+0"
    assert dmm.ask("*ESR?") == "+0"
    assert err(dmm) == '+0,"No error"'


def test_esr_bits_per_error_class_and_read_clears(dmm):
    assert dmm.ask("*ESR?") == "+128"  # PON after construction
    assert dmm.ask("*ESR?") == "+0"
    dmm.process(b"FOO")  # -113 -> CME bit 5
    assert dmm.ask("*ESR?") == "+32"
    dmm.process(b"VOLT:NPLC 1000")  # -222 -> EXE bit 4
    assert dmm.ask("*ESR?") == "+16"
    dmm.process(b"DIAG:CRAS")  # -300 -> DDE bit 3
    assert dmm.ask("*ESR?") == "+8"
    dmm.push_error(-410)  # QYE bit 2
    assert dmm.ask("*ESR?") == "+4"
    dmm.push_error(42, "device code")  # positive -> DDE
    assert dmm.ask("*ESR?") == "+8"
    dmm.process(b"*OPC")
    assert dmm.ask("*ESR?") == "+1"


def test_stb_eav_esb_mss_and_enable_registers(dmm):
    dmm.process(b"*CLS")
    assert dmm.ask("*STB?") == "+0"
    dmm.process(b"FOO")
    assert dmm.ask("*STB?") == "+4"  # EAV
    dmm.process(b"*ESE 32")
    assert dmm.ask("*ESE?") == "+32"
    assert dmm.ask("*STB?") == "+36"  # EAV + ESB
    dmm.process(b"*SRE 32")
    assert dmm.ask("*STB?") == "+100"  # + MSS
    dmm.process(b"*SRE 255")
    assert dmm.ask("*SRE?") == "+191"  # bit 6 cannot be enabled
    dmm.process(b"*ESE 256")
    assert err(dmm) == '-113,"Undefined header"'
    assert err(dmm).startswith('-222,"Data out of range;')


def test_opc_wai_trg_tst(dmm):
    assert dmm.process(b"*OPC?") == b"1\n"
    dmm.process(b"*WAI;*OPC")
    assert dmm.waits == 3
    assert dmm.ask("*TST?") == "+0"
    dmm.process(b"*TRG")
    assert err(dmm) == '-211,"Trigger ignored;no trigger armed for BUS"'


def test_trigger_hook_override():
    class Armed(FakeDmm):
        fired = 0

        def trigger(self):
            self.fired += 1

    dev = Armed()
    dev.process(b"*TRG;*TRG")
    assert dev.fired == 2 and err(dev) == '+0,"No error"'


def test_common_command_parameter_counts(dmm):
    dmm.process(b"*IDN? 1")
    assert err(dmm) == '-108,"Parameter not allowed"'
    dmm.process(b"*ESE")
    assert err(dmm) == '-109,"Missing parameter"'
    dmm.process(b"*FOO")
    assert err(dmm) == '-113,"Undefined header"'
    dmm.process(b"*RST?")
    assert err(dmm) == '-113,"Undefined header"'


def test_system_subsystem(dmm):
    assert dmm.ask("SYST:VERS?") == "1999.0"
    assert dmm.ask(":system:error:next?") == '+0,"No error"'
    dmm.process(b"FOO;VOLT:NPLC 0")
    assert dmm.ask("SYST:ERR:COUN?") == "+2"
    assert dmm.ask("SYST:ERR:ALL?") == ('-113,"Undefined header",'
                                        '-222,"Data out of range;NPLC 0 not in 0.001..100"')
    assert dmm.ask("SYST:ERR:COUN?") == "+0"


# ---------------------------------------------------------------- error queue
def test_error_texts_exact():
    for code, text in [(-113, "Undefined header"), (-222, "Data out of range"),
                       (-350, "Queue overflow"), (-410, "Query INTERRUPTED"),
                       (-420, "Query UNTERMINATED"), (-101, "Invalid character"),
                       (-124, "Too many digits"), (-230, "Data corrupt or stale")]:
        assert ERROR_MESSAGES[code] == text
        assert ScpiError(code).entry == f'{code:+d},"{text}"'
    assert ScpiError(-222, "NPLC 7 not in 0.001..100").entry == \
        '-222,"Data out of range;NPLC 7 not in 0.001..100"'
    assert ScpiError(-300, 'say "hi"').entry == '-300,"Device-specific error;say ""hi"""'
    assert error_text(-115) == "Command error" and error_text(7) == "Device-specific error"


def test_queue_fifo_and_overflow_replaces_last(dmm):
    for k in range(7):
        dmm.push_error(-200 - k)
    assert dmm.errors == ['-200,"Execution error"', '-201,"Execution error"',
                          '-202,"Execution error"', '-203,"Execution error"',
                          '-350,"Queue overflow"']
    assert [err(dmm) for _ in range(6)][-2:] == ['-350,"Queue overflow"', '+0,"No error"']


def test_handler_exception_becomes_minus_300(dmm):
    assert dmm.process(b"DIAG:CRAS;*OPT?") == b"DIG,MEM\n"
    assert err(dmm) == '-300,"Device-specific error;ZeroDivisionError: division by zero"'
    assert dmm.process(b"DIAG:NONE?") is None
    assert err(dmm).startswith("-300,")


def test_set_only_and_query_only_headers(dmm):
    dmm.process(b"SYST:BEEP?")
    assert err(dmm) == '-113,"Undefined header"'
    dmm.process(b"MEAS:VOLT")
    assert err(dmm) == '-113,"Undefined header"'
    assert dmm.ask("MEAS:VOLT?") == "+1.50000000E+00"
    dmm.process(b"SENS:VOLT?")  # an interior node only
    assert err(dmm) == '-113,"Undefined header"'


def test_detailed_command_errors_switch(dmm):
    dmm.detailed_command_errors = True
    dmm.process(b"VOLT:FOO 1")
    assert err(dmm) == '-113,"Undefined header;FOO not under VOLTAGE"'


# ---------------------------------------------------------------- headers and paths
@pytest.mark.parametrize("header", [
    "SENS:VOLT:DC:NPLC", "SENSE:VOLTAGE:DC:NPLCYCLES", "VOLT:NPLC", "volt:dc:nplc",
    ":SeNsE:vOlT:nPlCyClEs", "sens:voltage:nplc", "VOLTAGE:DC:NPLC"])
def test_header_forms_dispatch(dmm, header):
    dmm.process(f"{header} 2".encode())
    assert dmm.nplc == 2.0
    assert dmm.ask(f"{header}?") == "+2.00000000E+00"


@pytest.mark.parametrize("header", ["VOLTA:NPLC", "SENSEX:VOLT:NPLC", "VOL:NPLC", "VOLT:NPLCY",
                                    "VOLT:DC:DC:NPLC", "NPLC"])
def test_partial_forms_are_undefined(dmm, header):
    dmm.process(f"{header} 2".encode())
    assert dmm.nplc == 10.0 and err(dmm) == '-113,"Undefined header"'


@pytest.mark.parametrize("header", ["VOLT::NPLC", "VOLT:NPLC:", "VOLT:?NPLC", "VOLT:1X", "VOLT*:NPLC"])
def test_malformed_headers_are_syntax_errors(dmm, header):
    dmm.process(f"{header} 2".encode())
    assert err(dmm) == '-102,"Syntax error"'


def test_path_rules(dmm):
    dmm.process(b"SENS:VOLT:NPLC 1;RANG 100")  # RANG resolves under SENS:VOLT
    assert (dmm.nplc, dmm.range_v) == (1.0, 100.0)
    assert dmm.process(b"VOLT:DC:NPLC?;RANG?;NPLC?") == b"+1.00000000E+00;+1.00000000E+02;+1.00000000E+00\n"
    dmm.process(b"SENS:VOLT:NPLC 2;*OPC;RANG 20")  # a common command keeps the path
    assert (dmm.nplc, dmm.range_v) == (2.0, 20.0)
    dmm.process(b"VOLT:NPLC 3;:TRIG:SOUR BUS;COUN 5")  # ':' resets to the root
    assert (dmm.nplc, dmm.trigger_source, dmm.count) == (3.0, "BUS", 5)
    assert err(dmm) == '+0,"No error"'
    dmm.process(b"VOLT:NPLC 4;TRIG:SOUR EXT")  # relative: VOLT:TRIG:SOUR does not exist
    assert (dmm.nplc, dmm.trigger_source) == (4.0, "BUS")
    assert err(dmm) == '-113,"Undefined header"'
    dmm.process(b"OUTP ON;VOLT:NPLC 5")  # OUTP[:STAT]: path stays at the root
    assert dmm.outputs[1] is True and dmm.nplc == 5.0
    dmm.process(b"VOLT:NPLC 1\nRANG 1")  # LF is not a separator inside process()
    assert dmm.nplc == 5.0 and err(dmm) == '-101,"Invalid character"'


def test_path_resets_at_each_message(dmm):
    dmm.process(b"SENS:VOLT:NPLC 1")
    dmm.process(b"RANG 1")
    assert err(dmm) == '-113,"Undefined header"'


def test_error_in_compound_keeps_going(dmm):
    assert dmm.process(b"FOO 1;VOLT:NPLC 7;BAR?;NPLC?;*OPT?") == b"+7.00000000E+00;DIG,MEM\n"
    assert dmm.errors == ['-113,"Undefined header"', '-113,"Undefined header"']
    assert dmm.process(b"*RST;;  ;") is None  # empty units are ignored
    assert dmm.errors == ['-113,"Undefined header"', '-113,"Undefined header"']


def test_numeric_suffixes(dmm):
    dmm.process(b"OUTP2 ON;:OUTP3:STAT 1;:OUTP OFF")
    assert dmm.outputs == {1: False, 2: True, 3: True}
    assert dmm.process(b"OUTP2?;:OUTPUT1:STATE?") == b"1;0\n"
    for bad, code in [(b"OUTP4 ON", -114), (b"OUTP0 ON", -114), (b"VOLT2:NPLC 1", -113),
                      (b"OUTP99999999999 ON", -114)]:
        dmm.process(bad)
        assert err(dmm).startswith(f"{code},"), bad
    dmm.process(b"SOUR2:FREQ 1 KHZ;:SOUR:FREQ?")
    assert dmm.freq_hz == 1000.0


def test_suffix_carries_along_the_path():
    seen = []
    dev = ScpiDevice(IDN)
    dev.command("OUTPut#:PROTection:CLEar", set=lambda a: seen.append(a.suffixes))
    dev.command("OUTPut#:STATe", set=lambda a: seen.append(a.suffixes))
    dev.process(b"OUTP2:STAT ON;PROT:CLE")
    assert seen == [(2,), (2,)]


# ---------------------------------------------------------------- parameters
def test_min_max_def(dmm):
    dmm.process(b"VOLT:NPLC MIN")
    assert dmm.nplc == 0.001
    dmm.process(b"VOLT:NPLC maximum")
    assert dmm.nplc == 100.0
    dmm.process(b"VOLT:NPLC DEF")
    assert dmm.nplc == 10.0
    dmm.process(b"TRIG:COUN MAX;COUN?")
    assert dmm.count == 1000
    dmm.process(b"VOLT:NPLC MINI")
    assert err(dmm) == '-104,"Data type error"'


def test_numbers_and_units(dmm):
    for text, value in [("100 mV", 0.1), ("100MV", 0.1), ("1.5e2", 150.0), ("+.5 kV", 500.0),
                        ("2 V", 2.0), ("1 E 2", 100.0), ("#H64", 100.0), ("#B11", 3.0)]:
        dmm.process(f"VOLT:RANG {text}".encode())
        assert dmm.range_v == pytest.approx(value), text
    assert err(dmm) == '+0,"No error"'
    dmm.process(b"SOUR:FREQ 2 MHZ")
    assert dmm.freq_hz == 2e6
    dmm.process(b"TRIG:COUN 2.5")  # integers round half away from zero
    assert dmm.count == 3


@pytest.mark.parametrize("param, code", [
    ("abc", -104), ("'1'", -104), ("1.2.3", -121), ("1e99999", -123), ("1" * 300, -124),
    ("1 KOHM", -131), ("1 A", -131), ("1e400", -123), ("#HXYZ", -121), ("2000", -222),
    ("(@1)", -104), ("#15hello", -104)])
def test_number_errors(dmm, param, code):
    dmm.process(f"VOLT:RANG {param}".encode())
    assert dmm.range_v == 10.0
    assert err(dmm).startswith(f"{code},"), param


def test_suffix_not_allowed_and_missing(dmm):
    dmm.process(b"VOLT:NPLC 1 V")
    assert err(dmm) == '-138,"Suffix not allowed"'
    dmm.process(b"VOLT:NPLC")
    assert err(dmm) == '-109,"Missing parameter"'
    dmm.process(b"VOLT:NPLC 1,2")
    assert err(dmm) == '-108,"Parameter not allowed"'
    dmm.process(b"VOLT:NPLC 7")
    assert dmm.ask("SYST:ERR?") == '+0,"No error"'
    dmm.process(b"VOLT:NPLC 700")
    assert err(dmm) == '-222,"Data out of range;NPLC 700 not in 0.001..100"'


def test_boolean(dmm):
    for text, value in [("ON", True), ("off", False), ("1", True), ("0", False), ("1.0", True)]:
        dmm.process(f"OUTP {text}".encode())
        assert dmm.outputs[1] is value
    for text in ["2", "TRUE", "-1"]:
        dmm.process(f"OUTP {text}".encode())
        assert err(dmm).startswith("-224,"), text
    dmm.process(b"OUTP 'ON'")
    assert err(dmm) == '-104,"Data type error"'


def test_choice(dmm):
    for text, value in [("bus", "BUS"), ("IMM", "IMMEDIATE"), ("Immediate", "IMMEDIATE"),
                        ("TIM", "TIMER")]:
        dmm.process(f"TRIG:SOUR {text}".encode())
        assert dmm.trigger_source == value
    dmm.process(b"TRIG:SOUR IMMED")
    assert err(dmm) == '-224,"Illegal parameter value;SOUR \'IMMED\' not one of IMMediate|BUS|EXTernal|TIMer"'


def test_strings(dmm):
    dmm.process(b"DISP:TEXT 'it''s; a, test'")
    assert dmm.text == "it's; a, test"
    assert dmm.ask("DISP:TEXT?") == '"it\'s; a, test"'
    dmm.process(b'DISP:TEXT "say ""hi"""')
    assert dmm.text == 'say "hi"'
    dmm.process(b"DISP:TEXT 'open")
    assert err(dmm) == '-151,"Invalid string data"'
    dmm.process(b"DISP:TEXT 'a'b")
    assert err(dmm) == '-151,"Invalid string data"'


def test_channel_lists(dmm):
    dmm.process(b"ROUT:CLOS (@1,2:4)")
    assert dmm.closed == [1, 2, 3, 4]
    dmm.process(b"ROUT:CLOS ( @ 6:4 , 8 )")
    assert dmm.closed == [6, 5, 4, 8]
    for bad, code in [(b"(@1,x)", -171), (b"(1,2)", -171), (b"(@1,9)", -222), (b"1", -104),
                      (b"(@1", -170)]:
        dmm.process(b"ROUT:CLOS " + bad)
        assert err(dmm).startswith(f"{code},"), bad
    assert dmm.closed == [6, 5, 4, 8]


def test_blocks_in_and_out(dmm):
    payload = bytes(range(256)) + b";,'\"\n"
    dmm.process(b"DATA:BLOC " + format_block(payload) + b";:VOLT:NPLC 3")
    assert dmm.data == payload and dmm.nplc == 3.0
    assert dmm.process(b"DATA:BLOC?") == format_block(payload) + b"\n"
    assert dmm.process(b"DATA:BLOC?;*OPT?") == format_block(payload) + b";DIG,MEM\n"
    dmm.process(b"DATA:BLOC #0tail;with;separators")
    assert dmm.data == b"tail;with;separators"
    dmm.process(b"DATA:BLOC #19abc")
    assert err(dmm) == '-161,"Invalid block data"'
    dmm.process(b"DATA:BLOC #1x")
    assert err(dmm) == '-161,"Invalid block data"'
    dmm.process(b"DATA:BLOC#13abc")
    assert err(dmm) == '-102,"Syntax error"'
    dmm.process(b"DATA:BLOC 1")
    assert err(dmm) == '-104,"Data type error"'
    assert format_block(b"") == b"#10" and format_block(b"x" * 12) == b"#212" + b"x" * 12


def test_raw_params_and_separators(dmm):
    dmm.process(b"SYST:BEEP  1 , 'a,b' ,(@1,2), MIN,#13xyz")
    assert dmm.calls == [("SYST:BEEP", (), ["1", "'a,b'", "(@1,2)", "MIN", "#13xyz"])]
    for bad, code in [(b"SYST:BEEP 1,,2", -102), (b"SYST:BEEP 1,", -102), (b"SYST:BEEP,1", -103),
                      (b"SYST:BEEP $", -101), (b"SYST:BEEP$ 1", -101), (b",", -103),
                      (b"'x'", -102), (b"SYST:BEEP \xb5", -101)]:
        dmm.process(bad)
        assert err(dmm).startswith(f"{code},"), bad
    assert len(dmm.calls) == 1


def test_oversize_message_and_non_bytes_input():
    dev = FakeDmm(max_message_bytes=64)
    assert dev.process(b"DISP:TEXT '" + b"x" * 100 + b"'") is None
    assert err(dev) == '-223,"Too much data;message of 112 bytes exceeds 64"'
    assert dev.process("*OPT?") == b"DIG,MEM\n"  # str is tolerated
    assert dev.process(None) is None  # nonsense input is an error, not an exception
    assert err(dev).startswith("-310,")


def test_feed_frames_and_answers():
    dev = FakeDmm(max_message_bytes=64)
    assert dev.feed(b"*IDN?\r\n*OPT") == (",".join(IDN) + "\n").encode()
    assert dev.feed(b"?\nDISP:TEXT 'a b'\n") == b"DIG,MEM\n"
    assert dev.text == "a b"
    # an LF inside an open string ends the message: -151, and the next command is served
    assert dev.feed(b"DISP:TEXT 'a\n*OPT?\n") == b"DIG,MEM\n"
    assert err(dev).startswith("-15")
    assert dev.feed(b"DISP:TEXT '" + b"y" * 100 + b"'\n*OPT?\n") == b"DIG,MEM\n"
    assert err(dev) == '-223,"Too much data;message longer than 64 bytes"'


def test_registration_errors():
    dev = ScpiDevice(IDN)
    dev.command("STATus:PRESet", set=lambda a: None)
    with pytest.raises(ValueError, match="ambiguous"):
        dev.command("STATe", set=lambda a: None)  # STAT is already STATus
    with pytest.raises(ValueError, match="conflicts"):
        dev.command("STATus#:OPERation", query=lambda a: "0")
    for bad in ["volt", "VOLT[:DC", "VOLT]", "[A:[B]]C", "VOL-T", "*1", "[OPT]"]:
        with pytest.raises(ValueError):
            dev.command(bad, set=lambda a: None)
    with pytest.raises(ValueError):
        dev.command("VOLTage")
    with pytest.raises(ValueError):
        ScpiDevice(("a,b", "c", "d", "e"))
    with pytest.raises(ValueError):
        ScpiDevice(IDN, error_queue_size=0)


def test_reregistration_overrides_builtin():
    dev = ScpiDevice(IDN)
    dev.command("*TST", query=lambda a: "+1")
    dev.command("SYSTem:VERSion", query=lambda a: "1999.0 (sim)")
    assert dev.process(b"*TST?;:SYST:VERS?") == b"+1;1999.0 (sim)\n"


# ---------------------------------------------------------------- formatting and framing
def test_number_formatting():
    assert format_number(1) == "+1.00000000E+00"
    assert format_number(-0.00123456789) == "-1.23456789E-03"
    assert format_number(float("inf")) == "+9.90000000E+37"
    assert format_number(float("nan")) == "+9.91000000E+37"
    assert format_int(100) == "+100" and format_int(-3) == "-3"
    assert format_numbers([1, 2]) == "+1.00000000E+00,+2.00000000E+00"
    assert format_string('a"b') == '"a""b"' and format_bool(True) == "1"


def test_framer_basic_and_crlf():
    f = MessageFramer()
    assert f.feed(b"*IDN?\n*RST\r\nVOLT 1") == [b"*IDN?", b"*RST"]
    assert f.pending == 6
    assert f.feed(b"\n\n") == [b"VOLT 1", b""]


def test_framer_lf_in_an_open_string_ends_the_message_and_resyncs():
    f = MessageFramer()
    assert f.feed(b'DISP:TEXT "abc\n*IDN?\n') == [b'DISP:TEXT "abc', b"*IDN?"]
    assert f.feed(b"DATA #9999999999\n*OPC?\n") == [Oversize(1 << 20), b"*OPC?"]


def test_framer_lf_in_blocks():
    f = MessageFramer()
    msg1 = b"DISP:TEXT 'line1 line2';\"a \"\"b\""
    msg2 = b"DATA " + format_block(b"\n\r\n'#") + b";X"
    msg3 = b"DATA " + format_block(b"ends with CR\r")
    msg4 = b"DATA #0indefinite 'quote\r"
    msg5 = b"VAL #H0A;#3x"  # not block headers
    stream = b"\n".join([msg1, msg2, msg3, msg4, msg5]) + b"\n"
    assert f.feed(stream) == [msg1, msg2, msg3, msg4, msg5]
    assert [m for i in range(len(stream)) for m in f.feed(stream[i:i + 1])] == [msg1, msg2, msg3, msg4, msg5]


def test_framer_oversize_reported_once_and_resyncs():
    f = MessageFramer(max_message_bytes=10)
    out = f.feed(b"A" * 25)
    assert out == [Oversize(10)]
    assert f.feed(b"B" * 25 + b"\nOK\n") == [b"OK"]
    # a block declared past the limit is reported at once; the stream resyncs at the next LF
    assert f.feed(b"D " + format_block(b"x" * 20) + b"\n*OPC?\n") == [Oversize(10), b"*OPC?"]
    # an unbalanced quote past the limit no longer hides the terminator
    assert f.feed(b"T '" + b"z" * 20 + b"\nNEXT\n") == [Oversize(10), b"NEXT"]
    with pytest.raises(ValueError):
        MessageFramer(0)
