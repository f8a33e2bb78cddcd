"""Navigation: the Earth model, rotations, the IMU model, strapdown mechanization and its
compiled kernels, trajectories (no file format), interpolation and trajectory
comparison.

Imports :mod:`ins.common` only.
"""
