"""Estimators run on a log beside the filter: Allan variance
(:mod:`~ins.estimation.tools.allan`), the IMU-GNSS time offset
(:mod:`~ins.estimation.tools.time_offset`), the vehicle mounting
(:mod:`~ins.estimation.tools.vehicle`) and the noise identification by maximum
likelihood (:mod:`~ins.estimation.tools.noise_identification`).

Imports :mod:`ins.estimation.core`, :mod:`~ins.estimation.alignment` and
:mod:`~ins.estimation.coupling`.
"""
