"""Multi-position (tumble) calibration of an accelerometer, IEEE Std 1293: K0, K1, K2, misalignment.

The accelerometer is set in several orientations on a dual-axis table so that gravity
projects onto its input, pendulous and output axes; the mean output per position is
fitted with the IEEE 1293 model (bias K0, scale factor K1, second- and third-order terms,
misalignments δo, δp, cross-coupling) by weighted linear least squares, and the parameters
the positions cannot separate are reported as not identifiable.  Plan the positions with
:func:`tumble_positions`, turn table angles into specific force with
:func:`specific_force_iapo_g`, and fit with :func:`fit_tumble`, which returns a
:class:`TumbleResult`.

What a user calls::

    fit_tumble, TumbleResult, tumble_positions, specific_force_iapo_g

The modules behind it are private: import from ``bench.analysis.tumble``.
"""

from bench.analysis.tumble._fit import TumbleResult, fit_tumble, specific_force_iapo_g, tumble_positions

__all__ = ["TumbleResult", "fit_tumble", "specific_force_iapo_g", "tumble_positions"]
