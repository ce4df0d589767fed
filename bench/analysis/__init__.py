"""The analysis library: pure functions on arrays, one subpackage per method.

Arrays and numbers in, small frozen dataclasses out; no file, socket or instrument is read
here. Import the method you need — importing this package loads none of them::

    from bench.analysis import allan
    r = allan.overlapping_adev(rate_dps, 100.0, unit="dps")

=================  ==========================================================================
``allan``          Allan deviation and the IEEE Std 952 noise terms (N, B, K, Q, R)
``startup``        Document A's start-up model: wavelet denoising, trend, time-series model
``timeseries``     ACF/PACF identification, AR/ARMA fits, order selection, whiteness tests
``emd``            empirical mode decomposition and the non-random terms (Document C)
``vibration``      Document C's random-vibration model: EMD → AR per IMF → AR-Kalman fit
``tumble``         IEEE Std 1293 multi-position calibration of an accelerometer
``ratetable``      IEEE Std 952/647 rate-table calibration of a gyro
``turn_on``        turn-on time, warm-up drift, turn-on repeatability
``thermal``        calibration over temperature: soaks, ramps, polynomials, compensation
``frf``            stepped-sine frequency response and the time base between two records
``fusion``         Document B's HF/LF angular-rate fusion and its baselines
``quality``        yield intervals, control charts, decision risk of a limit
=================  ==========================================================================

The value with its uncertainty that every method returns is :class:`bench.values.Estimate`.
"""
