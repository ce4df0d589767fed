"""Multi-position (tumble) calibration of an accelerometer, IEEE Std 1293: K0, K1, K2, misalignment.

What a user calls::

    fit_tumble, TumbleResult, tumble_positions, specific_force_iapo_g

The modules behind it are private: import from ``bench.analysis.tumble``.
"""

from bench.analysis.tumble._fit import TumbleResult, fit_tumble, specific_force_iapo_g, tumble_positions

__all__ = ["TumbleResult", "fit_tumble", "specific_force_iapo_g", "tumble_positions"]
