"""Reference copy of the pure-numpy EMD (bench.analysis.emd before numba): tests only."""
