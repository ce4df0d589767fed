"""``bench.discovery``'s fast paths as the straightforward code they replaced.

The oracles of the lattice visibility (``lattice.visibility``), the held-out linear scorer
(``significance.LinearScorer``) and the block bootstrap (``significance.block_bootstrap``):
tests ask the fast paths to agree with them to floating-point noise, and
``benchmarks/bench_discovery.py`` swaps them in to time the old code.
"""

from __future__ import annotations

import math

import numpy as np

from bench.discovery import significance as sig


def visibility_reference(y, s):
    """The original: one pass of n cos + n sin over all samples per step."""
    s = np.atleast_1d(np.asarray(s, float))
    out = np.empty(s.size)
    for k, sk in enumerate(s):
        ph = 2 * np.pi * y / sk
        out[k] = math.hypot(float(np.mean(np.cos(ph))), float(np.mean(np.sin(ph))))
    return out


class LinearScorerReference:
    """The original: per fold, fitted curves over every held-out sample for both models."""

    def __init__(self, x_nuis, x_cand, folds):
        self.parts = []
        for k in (0, 1):
            te = folds == k
            tr = ~te
            x = sig._unit_columns(np.hstack([x_nuis, x_cand[k]]))
            xb = sig._unit_columns(x_nuis)
            self.parts.append((tr, te, x[te], np.linalg.pinv(x[tr], rcond=sig.RCOND), xb[te],
                               np.linalg.pinv(xb[tr], rcond=sig.RCOND)))

    def scores(self, r):
        rt = np.ascontiguousarray((r[:, None] if r.ndim == 1 else r).T)
        sse_c = np.zeros(rt.shape[0])
        sse_b = np.zeros(rt.shape[0])
        for tr, te, xc_te, pc, xb_te, pb in self.parts:
            r_tr, r_te = rt[:, tr], rt[:, te]
            sse_c += np.sum((r_te - (r_tr @ pc.T) @ xc_te.T) ** 2, axis=1)
            sse_b += np.sum((r_te - (r_tr @ pb.T) @ xb_te.T) ** 2, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(sse_b > 0, 1.0 - sse_c / sse_b, 0.0)


def block_bootstrap_reference(r, block_len, n_rep, rng):
    """The original: the replicates' indices built in one array, blocks wrapping at the end."""
    n = r.size
    block_len = int(np.clip(block_len, 1, n))
    n_b = -(-n // block_len)
    starts = rng.integers(0, n, size=(n_rep, n_b))
    idx = (starts[:, :, None] + np.arange(block_len)[None, None, :]).reshape(n_rep, -1)[:, :n] % n
    return r[idx].T
