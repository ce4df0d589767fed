"""Run a 24-position tumble on the simulated station and print K0 and K1 with their uncertainties."""

from bench.app.session import read_run, run_step

outcome = run_step("tumble", station="sim", unit="QA-SIM-0003", seed=1, positions=12, planes=2)
print(f"run {outcome.run_id}: {outcome.status}")
for name in ("k0", "k1"):
    m = outcome.measurement(name)
    print(f"{name} = {m.value:.6g} ± {m.uncertainty:.2g} {m.unit}")

run = read_run(outcome.run_id)               # the stored run, every sample kept
positions = run.frame("tumble")              # mean output per position (pandas DataFrame)
print(positions[["inner_deg", "outer_deg", "voltage_v"]].head(4).to_string(index=False))
