"""Estimators run on a log beside the filter: Allan variance (:mod:`.allan`), the IMU-GNSS
time offset (:mod:`.time_offset`), the vehicle mounting (:mod:`.vehicle`) and the noise
identification by maximum likelihood (:mod:`.noise_identification`).

Imports :mod:`ins.estimation.core`, :mod:`~ins.estimation.alignment` and
:mod:`~ins.estimation.coupling`.
"""
