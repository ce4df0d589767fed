"""Reference copy of the pure-numpy EMD (bench.analysis.emd._emd before numba): tests only."""
