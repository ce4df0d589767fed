"""Empirical mode decomposition and the non-random terms it separates (Document C, step 1).

What a user calls::

    emd, EmdResult, StopRule, STOP_RULES
    nonrandom_terms, NonRandomTerms, Component

The modules behind it are private: import from ``bench.analysis.emd``.
"""

from bench.analysis.emd._emd import STOP_RULES, EmdResult, StopRule, emd
from bench.analysis.emd._nonrandom import Component, NonRandomTerms, nonrandom_terms

__all__ = ["Component", "EmdResult", "NonRandomTerms", "STOP_RULES", "StopRule", "emd", "nonrandom_terms"]
