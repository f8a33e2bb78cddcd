"""GNSS/INS estimation, in five subpackages, lowest first (each imports only those
before it):

- :mod:`ins.estimation.core`: the error-state model, the measurements and their update,
  the forward Kalman filter (compiled kernels), its stores and the RTS smoother;
- :mod:`ins.estimation.alignment`: the initial state (static coarse and fine alignment,
  in-air and in-motion starts, the at-rest test);
- :mod:`ins.estimation.coupling`: GNSS measurement models beyond the loose fixes
  (pseudoranges, Doppler and double differences) and the GNSS log's own diagnostics;
- :mod:`ins.estimation.tools`: estimators run on a log beside the filter (Allan variance,
  IMU-GNSS time offset, vehicle mounting, noise identification);
- :mod:`ins.estimation.pipeline`: ``ins process``: its configuration and presets, the GNSS
  source, the run, the trust checks, the outputs, plots and report.

Imports :mod:`ins.common`, :mod:`ins.nav`, :mod:`ins.io` and :mod:`ins.gnss`.
"""
