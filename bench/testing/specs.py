"""A short acceptance spec of the simulated QA-2000 accelerometer: minutes of station time.

``bench/specs/qa2000-sim.toml`` is the shipped spec; :data:`SHORT_ACCEPTANCE_SPEC` keeps its
three procedures and its limits on bias, scale factor and noise density, with short records (a
2-minute turn-on, a 4-position tumble in one plane, a 2-minute noise record), for end-to-end
tests of batches, reports and the operator page. Write it to a file and pass its path where a
spec is asked for.
"""

from __future__ import annotations

#: TOML: unit QA-2000-SIM (serials QA-SIM-*), turn-on, tumble and noise with their limits
SHORT_ACCEPTANCE_SPEC = """
[unit]
model = "QA-2000-SIM"
kind = "accelerometer"
serial_pattern = "QA-SIM-*"

[procedures.turn_on]
duration_s = 120.0
rate_hz = 2.0
off_wait_s = 10.0
smooth_s = 10.0
settled_window_s = 30.0

[procedures.tumble]
positions = 4
planes = 1
warmup_s = 30.0
settle_s = 1.0
average_s = 2.0
nplc = 1.0

[procedures.accelerometer_noise]
duration_s = 120.0
rate_hz = 10.0
warmup_s = 0.0
chunk_s = 30.0

[[measurements]]
name = "k0"
procedure = "tumble"
unit = "mg"
low = -4.0
high = 4.0

[[measurements]]
name = "k1"
procedure = "tumble"
unit = "mA/g"
low = 1.20
high = 1.46

[[measurements]]
name = "noise_density"
procedure = "accelerometer_noise"
unit = "ug/rtHz"
high = 2.2
"""
