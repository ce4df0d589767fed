"""Discrepancy workflow (issue 7): where a sensor model and a logged record disagree, and which
physical effect the model lacks. Pure: arrays and frozen results, no I/O beyond the model file.

The modules, in the order the workflow uses them (``docs/ARCHITECTURE.md``, "Discovery"):

* ``data`` — :class:`Record`, a logged experiment; ``experiments`` — realistic stimuli per kind;
* ``effects`` — ``CATALOGUE``, the one registry of effects; the effects themselves in
  ``effects_terms`` (additive), ``effects_transforms`` (input path and output), ``effects_noise``
  (random processes), on the machinery and hooks of ``effects_base`` (``effects_linalg``:
  projections);
* ``model`` — a base model plus effects, simulated and stored as TOML;
* ``workflow.discover`` — calibrate (``calibration``) → localize (``localize``, ``findings``)
  → name (``naming``: ``fitting`` for waveforms, ``stochastic`` / ``whittle`` for random
  processes, ``lattice`` for the quantizer's histogram; ``significance`` for held-out scores,
  the bootstrap null and the gap; ``choosing``, ``separating``; results in ``candidates``) →
  add → repeat, then ``localize.unexplained_structure`` (on ``whiten``'s innovations);
  ``mapping`` — how the candidates' fits and the nulls' realisations are mapped, in this
  process or side by side in the caller's workers or threads, with the same answer.
"""
