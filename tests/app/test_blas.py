"""bench.app.blas: the loaded OpenBLAS libraries' thread count, set for a block and restored."""

import numpy as np
import pytest
import scipy.linalg  # noqa: F401 — scipy's own OpenBLAS, loaded beside numpy's

from bench.app.blas import blas_threads, loaded_openblas, set_blas_threads


def test_blas_threads_sets_every_openblas_and_restores_it():
    libs = loaded_openblas()
    assert libs, "numpy and scipy ship OpenBLAS: both should be found"
    before = [int(get()) for _, get in libs]
    with blas_threads(1):
        assert [int(get()) for _, get in libs] == [1] * len(libs)
        a = np.random.default_rng(0).standard_normal((300, 300))
        assert np.allclose(a @ np.linalg.inv(a), np.eye(300), atol=1e-8)  # BLAS still computes
    assert [int(get()) for _, get in libs] == before
    with pytest.raises(ValueError, match="BLAS threads 0"):
        set_blas_threads(0)
