"""Discrepancy workflow (issue 7): where a sensor model and a logged record disagree, and which
physical effect the model lacks. Pure: arrays and frozen results, no I/O beyond the model file.

The modules, in the order the workflow uses them (``docs/ARCHITECTURE.md``, "Discovery"):

* ``data`` — :class:`Record`, a logged experiment; ``experiments`` — realistic stimuli per kind;
* ``effects`` — ``CATALOGUE``, the one registry of effects; the effects themselves in
  ``effects_terms`` (additive), ``effects_steps`` (jumps), ``effects_thermal``
  (temperature and its lag), ``effects_transforms`` (input path and output), ``effects_noise``
  (random processes), on the machinery and hooks of ``effects_base`` (``effects_linalg``:
  projections);
* ``model`` — a base model plus effects, simulated and stored as TOML;
* ``workflow.discover`` — outliers set aside (``contamination``), the starting model calibrated
  (``calibration``), then one search (``search``: add, drop and swap moves, a small beam) under
  one criterion (``criterion``: the exact likelihood through ``whiten``'s Kalman filter, one
  penalty per effect from the false-name rate); waveforms fitted by ``fitting``, random
  processes by ``stochastic`` / ``whittle``, the quantizer's histogram by ``lattice``; look-alikes
  told with ``separating``; each named random process tested against the model's own driving
  noise (``adequacy``, on ``whiten``'s smoother); what the model leaves tested on its
  innovations (``localize.unexplained_structure``, findings in ``findings``); ``significance``
  the gap tables; results in ``candidates``. ``mapping`` — how the add moves are mapped, in this
  process or side by side in the caller's workers, with the same answer.
"""
