"""Test infrastructure shared by the bench's tests, its benchmarks and users writing drivers.

As ``pymeasure.test``: what a user needs to test a driver of their own instrument is exported
here (``from bench.testing import expected_protocol``); the rest is imported from its module.
Nothing here needs pytest or hypothesis. Nothing in the library, the framework, the drivers,
the procedures or the application imports it (an import-linter contract in
``pyproject.toml``); it may import all of them and the simulator ``sim``.

Drivers (exported here)
    :mod:`bench.testing.visa` — :func:`~bench.testing.visa.expected_protocol` (a driver held to
    an exact exchange of messages), :class:`~bench.testing.visa.FakeResource` (a VISA resource
    answering from a table), :func:`~bench.testing.visa.pack_real64_block`, the pyvisa-sim YAML
    folder. :mod:`bench.testing.conformance` — :func:`~bench.testing.conformance.assert_conforms`:
    a driver has every member of an instrument kind's ``typing.Protocol``.
Wire protocols
    :mod:`bench.testing.fuzz_wire` — fuzz clients for a SCPI server and the FOG line over TCP,
    each message's expected fate from a reference framer, and message generators.
Steps and procedures
    :mod:`bench.testing.steps` — a bare station with a manual clock and a counting step, to run
    the framework without instruments. :mod:`bench.testing.specs` — a short acceptance spec of
    the simulated accelerometer.
Documentation
    :mod:`bench.testing.docs` — the Markdown pages' fenced blocks, the runnable shell blocks
    (marked ``<!-- runnable -->``) run as a reader would, every ``bench`` command line shown,
    the links into the repository.
Reports
    :mod:`bench.testing.reports` — a report is one file: every figure inline, no resource outside it.
Operator page
    :mod:`bench.testing.operator_station` — the operator station served on loopback for a
    browser (chromium and Playwright, the ``test`` extra, drive it).
Estimators
    :mod:`bench.testing.generators` — independent generators with a known truth, written apart
    from the code they grade (fusion pairs, thermal units, discovery effects and shapes).
    :mod:`bench.testing.references` — the straightforward code a fast path replaced, its
    oracle. :mod:`bench.testing.discovery_cases` — records with hidden effects as the
    discovery scorecard draws them. :mod:`bench.testing.discovery_nulls` — null records
    (Gaussian or Student-t white noise), isolated spikes and the binomial allowance a count at
    a stated rate is judged by.
"""

from bench.testing.conformance import assert_conforms
from bench.testing.visa import (
    NO_ERROR,
    SIM_YAML_DIR,
    FakeResource,
    ProtocolResource,
    expected_protocol,
    pack_real64_block,
)

__all__ = ["NO_ERROR", "SIM_YAML_DIR", "FakeResource", "ProtocolResource", "assert_conforms", "expected_protocol",
           "pack_real64_block"]
