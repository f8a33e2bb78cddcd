"""File formats of navigation data: IMU logs (text, binary, CSV, in blocks), GNSS logs
(KF-GINS text, RTKLIB ``.pos`` with its quality flags), trajectories (KF-GINS ``.nav``,
Applanix SBET/SMRMSG), mount angles and ROS bags.

Imports :mod:`ins.common` and :mod:`ins.nav`.
"""
