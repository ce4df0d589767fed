"""The compiled EMD (numba kernels in bench.analysis.emd._kernel / emd_spline) against the
previous pure-numpy implementation kept in tests/analysis/emd_numpy_ref: same extrema, knots,
splines and IMFs.

The numpy path merged both envelopes into one mean spline when knot intervals were long
(a rounding-level difference); with that merge off, every number is the same: the
compiled kernels repeat its operations in the same order (and LAPACK's ``dptsv``
recurrences), so the IMFs must be identical bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from bench.analysis.emd._emd import count_zero_crossings, emd, find_extrema
from bench.analysis.emd._kernel import envelope_knots
from bench.analysis.emd._spline import Spline, not_a_knot_slopes
from tests.analysis.emd_numpy_ref import kernel as ref_kernel
from tests.analysis.emd_numpy_ref import reference
from tests.analysis.emd_numpy_ref.spline import Spline as RefSpline


def _signal(n: int, seed: int, quant: bool, tone: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n) + tone * np.sin(np.arange(n) / 17.0) + 0.3 * np.linspace(0, 1, n)
    return np.round(x * 4) / 4 if quant else x  # quantised: flat runs and exact zeros


@settings(max_examples=25, deadline=None)
@given(st.integers(16, 6000), st.integers(0, 2**31), st.booleans(), st.sampled_from(["sd", "rilling", "s-number"]))
def test_same_imfs_as_the_numpy_path_bit_for_bit(n, seed, quant, stop):
    x = _signal(n, seed, quant)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(reference, "MERGE_MEAN", False)
        ref = reference.emd(x, stop=stop, max_sifts=60)
    res = emd(x, stop=stop, max_sifts=60)
    assert res.sifts == ref.sifts and res.converged == ref.converged
    np.testing.assert_array_equal(res.imfs, ref.imfs)
    np.testing.assert_array_equal(res.residue, ref.residue)


@pytest.mark.parametrize("seed", [1, 2])
def test_same_imfs_as_the_numpy_path_with_its_merged_mean(seed):
    """The numpy path as it was (merged mean spline on long intervals), over several of its
    blocks: the same siftings, IMFs equal to rounding, reconstruction exact."""
    x = _signal(40000, seed, False)
    res, ref = emd(x), reference.emd(x)
    assert res.sifts == ref.sifts
    np.testing.assert_allclose(res.imfs, ref.imfs, rtol=0, atol=1e-10)
    assert np.max(np.abs(res.reconstruct() - x)) <= 1e-10 * np.max(np.abs(x))


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 400), st.integers(0, 2**31), st.integers(1, 8))
def test_extrema_zero_crossings_and_knots_as_the_numpy_path(n, seed, levels):
    """Quantised noise: many flat runs (also at the ends) and exact zeros."""
    x = np.round(np.random.default_rng(seed).normal(size=n) * levels / 2) / levels
    imax, imin = find_extrema(x)
    rmax, rmin = ref_kernel.find_extrema(x)
    np.testing.assert_array_equal(imax, rmax)
    np.testing.assert_array_equal(imin, rmin)
    assert count_zero_crossings(x) == ref_kernel.count_zero_crossings(x)
    if imax.size and imin.size:
        for nbsym in (1, 2, 3):
            for a, b in zip(envelope_knots(x, imax, imin, nbsym), ref_kernel.envelope_knots(x, rmax, rmin, nbsym)):
                np.testing.assert_array_equal(a, b)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31), st.integers(4, 300))
def test_spline_as_the_numpy_path_bit_for_bit(seed, m):
    rng = np.random.default_rng(seed)
    pos = np.unique(np.r_[-2, np.cumsum(rng.integers(1, 9, m))])
    val = rng.normal(size=pos.size)
    n = int(pos[-1]) + 1
    np.testing.assert_array_equal(Spline.through(pos, val)(n), RefSpline.through(pos, val)(n))


@pytest.mark.parametrize("m", [2, 3])
def test_two_and_three_knots_are_scipy_line_and_parabola(m):
    pos = np.array([-3, 4, 11][:m])
    val = np.array([1.0, -2.0, 0.5][:m])
    n = int(pos[-1]) + 1
    ref = CubicSpline(pos.astype(float), val)
    np.testing.assert_allclose(Spline.through(pos, val)(n), ref(np.arange(n)), atol=1e-12)
    np.testing.assert_allclose(not_a_knot_slopes(pos, val), ref.derivative()(pos), atol=1e-12)


def test_bad_knots_name_the_problem():
    with pytest.raises(ValueError, match="increasing"):
        Spline.through(np.array([0, 2, 2, 5]), np.zeros(4))
    with pytest.raises(ValueError, match="2 knots"):
        Spline.through(np.array([0]), np.zeros(1))
    with pytest.raises(ValueError, match="integers"):
        not_a_knot_slopes(np.array([0.0, 1.5, 3.0, 4.0]), np.zeros(4))
