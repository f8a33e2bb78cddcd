"""LiDAR direct georeferencing: the scanner model and file, laser returns into LAS/LAZ with
each point's sigma, and the strip-overlap boresight check.

Imports :mod:`ins.common`, :mod:`ins.nav` and :mod:`ins.io`.
"""
