"""Property-based tests of the shared SCPI engine: header forms, robustness against
arbitrary bytes, stream framing and block round trips."""

from __future__ import annotations

import os
import re

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim.scpi import Args, MessageFramer, Oversize, ScpiDevice, format_block, format_number
from sim.scpi.errors import ERROR_MESSAGES

IDN = ("Sim", "PROP-1", "0001", "1.0")
# SCPI_EXAMPLES=5000 for a deeper local fuzz run; the default keeps the file a few seconds.
FAST = settings(max_examples=int(os.environ.get("SCPI_EXAMPLES", "200")), deadline=None,
                suppress_health_check=[HealthCheck.too_slow])

# Each pattern as (mnemonic, optional, has_suffix) nodes, written out independently of
# the engine's own pattern parser.
TREE = [
    [("SENSe", True, False), ("VOLTage", False, False), ("DC", True, False), ("NPLCycles", False, False)],
    [("SENSe", True, False), ("VOLTage", False, False), ("DC", True, False), ("RANGe", False, False),
     ("UPPer", True, False)],
    [("SOURce", True, True), ("CURRent", False, False), ("LEVel", True, False),
     ("IMMediate", True, False), ("AMPLitude", True, False)],
    [("OUTPut", False, True), ("STATe", True, False)],
    [("TRIGger", False, False), ("SEQuence", True, True), ("SOURce", False, False)],
    [("CALCulate", False, True), ("LIMit", False, True), ("LOWer", False, False), ("DATA", True, False)],
    [("INITiate", False, False), ("IMMediate", True, False)],
    [("SYSTem", False, False), ("COMMunicate", False, False), ("LAN", False, False),
     ("IPADdress", False, False)],
]


def pattern_text(nodes) -> str:
    out = ""
    for name, optional, suffix in nodes:
        text = name + ("#" if suffix else "")
        out += f"[:{text}]" if optional else f":{text}"
    return out.lstrip(":")


def short_form(name: str) -> str:
    return "".join(ch for ch in name if not ch.islower())


class Recorder(ScpiDevice):
    def __init__(self, **kw):
        super().__init__(IDN, **kw)
        self.calls: list[tuple] = []
        for index, nodes in enumerate(TREE):
            self.command(pattern_text(nodes), set=self._make(index, "set"),
                         query=self._make(index, "query"))
        self.command("DATA", set=self._data)
        self.command("DATA", query=lambda a: format_block(self.calls[-1][1][0]))

    def _make(self, index: int, kind: str):
        def handler(args: Args):
            self.calls.append((index, kind, args.suffixes, args.raw))
            return "0" if kind == "query" else None
        return handler

    def _data(self, args: Args) -> None:
        values: list[bytes | str | int] = []
        for i in range(args.count):
            raw = args.raw[i]
            if raw.startswith("#"):
                values.append(args.block(i))
            elif raw[0] in "'\"":
                values.append(args.string(i))
            else:
                values.append(args.integer(i, min=None, max=None))
        self.calls.append(("DATA", values))


def case_mix(draw, text: str) -> str:
    flips = draw(st.lists(st.booleans(), min_size=len(text), max_size=len(text)))
    return "".join(ch.lower() if f else ch.upper() for ch, f in zip(text, flips))


@st.composite
def header_for(draw, index: int):
    """A valid spelling of TREE[index] and the suffixes the handler must see."""
    parts, suffixes = [], []
    for name, optional, has_suffix in TREE[index]:
        if optional and not draw(st.booleans()):
            if has_suffix:
                suffixes.append(1)
            continue
        form = draw(st.sampled_from([short_form(name), name.upper()]))
        token = case_mix(draw, form)
        if has_suffix:
            value = draw(st.none() | st.integers(1, 40))
            token += "" if value is None else str(value)
            suffixes.append(1 if value is None else value)
        parts.append(token)
    lead = draw(st.sampled_from(["", ":"]))
    return lead + ":".join(parts), tuple(suffixes)


@st.composite
def unit_for(draw):
    index = draw(st.integers(0, len(TREE) - 1))
    header, suffixes = draw(header_for(index))
    query = draw(st.booleans())
    params = [str(v) for v in draw(st.lists(st.integers(-10**6, 10**6), max_size=3))]
    text = header + ("?" if query else "")
    if params:
        text += draw(st.sampled_from([" ", "\t", "  "])) + ",".join(params)
    return text, (index, "query" if query else "set", suffixes, params)


# (1) every spelling of a header reaches the same handler with the same arguments
@FAST
@given(st.lists(unit_for(), min_size=1, max_size=4))
def test_any_valid_spelling_dispatches_identically(units):
    dev = Recorder()
    # every unit after the first starts with ':' so the path rules cannot interfere
    text = ";".join(u if k == 0 or u.startswith(":") else ":" + u
                    for k, (u, _) in enumerate(units))
    response = dev.process(text.encode())
    assert dev.errors == []
    assert dev.calls == [expected for _, expected in units]
    n_queries = sum(1 for _, exp in units if exp[1] == "query")
    assert response == (b";".join([b"0"] * n_queries) + b"\n" if n_queries else None)


@FAST
@given(st.data())
def test_relative_headers_follow_the_path(data):
    # "<prefix>:NPLC p;RANG[:UPP] q" - RANGe resolves under the prefix as sent
    header, _ = data.draw(header_for(0))
    leaf = data.draw(st.sampled_from(["RANG", "range", "RANG:UPP", "Range:Upper"]))
    dev = Recorder()
    dev.process(f"{header} 1;{leaf} 2".encode())
    assert dev.errors == []
    assert dev.calls == [(0, "set", (), ["1"]), (1, "set", (), ["2"])]


# (2) arbitrary bytes never raise and always leave standard error codes
SCPI_ALPHABET = "*?:;,'\"#()@ \t\r\n0123456789.+-eE" + "VOLTSENSNPLCIDNOPTRSRCURDATminaxH"
scpi_like = st.text(alphabet=SCPI_ALPHABET, max_size=80).map(str.encode)
fragments = st.lists(st.sampled_from(
    [b"*IDN?", b"*RST", b"VOLT:NPLC", b" 1", b"MIN", b";", b",", b"'a\n'", b"#15ab\ncd", b"#0",
     b"#2", b"\xff", b"OUTP2", b":", b"?", b"(@1:3)", b"\r\n", b"DATA "]), max_size=12).map(b"".join)
garbage = st.binary(max_size=200) | scpi_like | fragments
ENTRY = re.compile(r'(-\d+),"(.*)"\Z', re.S)
BLANK = set(bytes(range(0x21))) - {0x0A} | {ord(";")}


def standard_codes(entries: list[str]) -> list[int]:
    codes = []
    for entry in entries:
        m = ENTRY.match(entry)
        assert m, entry
        code = int(m.group(1))
        assert code in ERROR_MESSAGES and code < 0, entry
        assert m.group(2).startswith(ERROR_MESSAGES[code]), entry
        codes.append(code)
    return codes


class Bare(ScpiDevice):
    """No commands at all: every non-blank program message unit is an error."""

    def _register_builtins(self) -> None:
        pass


@FAST
@given(st.lists(garbage, min_size=1, max_size=5))
def test_process_survives_any_bytes(messages):
    dev, bare = Recorder(error_queue_size=1000), Bare(IDN, error_queue_size=1000)
    for msg in messages:
        response = dev.process(msg)
        assert response is None or (isinstance(response, bytes) and response.endswith(b"\n"))
        standard_codes(dev.errors)
        before = len(bare.errors)
        assert bare.process(msg) is None
        new = standard_codes(bare.errors[before:])
        if not set(msg) <= BLANK:
            assert new, msg


@FAST
@given(st.lists(garbage, max_size=5), st.lists(st.integers(0, 1000), max_size=8))
def test_stream_handling_is_split_invariant(messages, cuts):
    stream = b"\n".join(messages) + b"\n"
    points = sorted({c % (len(stream) + 1) for c in cuts})
    chunks = [stream[a:b] for a, b in zip([0] + points, points + [len(stream)])]
    whole, split = MessageFramer(max_message_bytes=64), MessageFramer(max_message_bytes=64)
    expected = whole.feed(stream)
    assert [m for chunk in chunks for m in split.feed(chunk)] == expected
    assert all(isinstance(m, Oversize) or len(m) <= 64 for m in expected)
    dev_whole, dev_split = Recorder(max_message_bytes=64), Recorder(max_message_bytes=64)
    assert b"".join(dev_split.feed(c) for c in chunks) == dev_whole.feed(stream)
    assert dev_split.errors == dev_whole.errors
    standard_codes(dev_split.errors)


# (3) framing a stream of messages with binary blocks and strings, split anywhere
quoted = st.text(alphabet="ab ;,\r'\"#\t", max_size=12)  # an LF ends a message, even in a string
param = st.one_of(
    st.integers(-10**9, 10**9),
    st.tuples(st.sampled_from("'\""), quoted),
    st.binary(max_size=40),
)


def encode_param(p) -> bytes:
    if isinstance(p, int):
        return str(p).encode()
    if isinstance(p, tuple):
        q, text = p
        return (q + text.replace(q, q + q) + q).encode()
    return format_block(p)


@FAST
@given(st.lists(st.lists(param, min_size=1, max_size=4), min_size=1, max_size=5),
       st.lists(st.integers(0, 10**6), max_size=10), st.booleans())
def test_framer_recovers_messages_split_anywhere(message_params, cuts, crlf):
    messages = [b"DATA " + b",".join(encode_param(p) for p in ps) for ps in message_params]
    stream = b"".join(m + (b"\r\n" if crlf else b"\n") for m in messages)
    points = sorted({c % (len(stream) + 1) for c in cuts})
    chunks = [stream[a:b] for a, b in zip([0] + points, points + [len(stream)])]
    framer = MessageFramer()
    assert [m for chunk in chunks for m in framer.feed(chunk)] == messages
    assert framer.pending == 0
    dev = Recorder()
    for chunk in chunks:
        assert dev.feed(chunk) == b""
    assert dev.errors == []
    assert dev.calls == [("DATA", [p[1] if isinstance(p, tuple) else p for p in ps])
                         for ps in message_params]


# (4) blocks round trip through format_block, Args.block and the response path
@FAST
@given(st.binary(max_size=3000), st.booleans())
def test_block_round_trip(payload, indefinite):
    dev = Recorder()
    block = b"#0" + payload if indefinite else format_block(payload)
    assert dev.process(b"DATA " + block) is None
    assert dev.errors == [] and dev.calls[-1] == ("DATA", [payload])
    response = dev.process(b"DATA?")
    assert response == format_block(payload) + b"\n"
    # decode the definite-length block independently
    n = int(response[1:2])
    length = int(response[2:2 + n])
    assert response[2 + n:2 + n + length] == payload and len(response) == 3 + n + length


@FAST
@given(st.floats(allow_nan=False, allow_infinity=False, width=64))
def test_format_number_round_trip(x):
    text = format_number(x)
    assert re.fullmatch(r"[+-]\d\.\d{8}E[+-]\d{2,3}", text)
    assert abs(float(text) - x) <= 5e-9 * abs(x)
