"""Empirical mode decomposition and the non-random terms it separates (Document C, step 1).

Empirical mode decomposition (Huang et al. 1998) splits a uniformly sampled series into
intrinsic mode functions — oscillations of decreasing frequency, fastest first — and a
residue, with exact reconstruction (``Σ imfs + residue = x``).  The entry point is
:func:`emd`, which returns an :class:`EmdResult`; :func:`nonrandom_terms` then labels the
residue and each IMF as trend, periodic or random (a :class:`NonRandomTerms` of
:class:`Component`), the random ones being the stationary part that AR models describe.
``StopRule`` is the type of ``emd``'s ``stop`` argument, :data:`STOP_RULES` its values.

What a user calls::

    emd, EmdResult, StopRule, STOP_RULES
    nonrandom_terms, NonRandomTerms, Component

The modules behind it are private: import from ``bench.analysis.emd``.
"""

from bench.analysis.emd._emd import STOP_RULES, EmdResult, StopRule, emd
from bench.analysis.emd._nonrandom import Component, NonRandomTerms, nonrandom_terms

__all__ = ["Component", "EmdResult", "NonRandomTerms", "STOP_RULES", "StopRule", "emd", "nonrandom_terms"]
