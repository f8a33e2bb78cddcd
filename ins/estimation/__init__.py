"""GNSS/INS estimation: the error-state model and its measurements, the Kalman filter and
RTS smoother, alignment, the clock offset, sensor presets, the processing pipeline with
its configuration, trust checks and outputs, the vehicle mounting, and Allan variance.

Imports :mod:`ins.common`, :mod:`ins.nav` and :mod:`ins.io`.
"""
