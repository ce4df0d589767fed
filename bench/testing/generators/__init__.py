"""Independent generators: data with a known truth, written apart from the code they grade.

An estimator graded only on records its own model made would share that model's mistakes
unseen. Each generator here realises the truth with different code and a different
discretisation, and imports nothing of the code it grades (a data container or a catalogue's
parameter draws at most, so the truth is the one the estimator is asked about):

* :mod:`~bench.testing.generators.fusion_pairs` — HF/LF rate-sensor pairs drawn over regimes
  (bilinear-transform digital filters at 16× the rate), and a judge against the exact rate;
  grades ``bench.analysis.fusion``;
* :mod:`~bench.testing.generators.thermal_truth` — a two-node thermal unit in a chamber
  integrated by RK4, ramps (branch flip or play hysteresis), soaked sweep points and chamber
  records on a rate table with the sensor on the case; grades ``bench.analysis.thermal`` and
  ``bench.analysis.turn_on``;
* :mod:`~bench.testing.generators.discovery_effects` — every discovery catalogue effect
  realised apart from the catalogue (the simulator's physics where it has the effect); grades
  ``bench.discovery``;
* :mod:`~bench.testing.generators.discovery_lines` — records of a few spectral lines in white
  noise (cosines on the record's own clock, frequencies, snr and phases drawn apart from the
  catalogue's ``draw``); grades how ``bench.discovery`` names several lines at once;
* :mod:`~bench.testing.generators.discovery_shapes` — structure no catalogue effect has
  (triangle and square waves, chirps, bursts, a supply dependence, a compression), sized
  against its closest look-alike; grades the discovery's "unexplained structure".
"""
