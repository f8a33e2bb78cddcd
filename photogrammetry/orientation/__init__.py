"""Exterior orientation: photogrammetric angle systems, the camera and its mounting, the
exposures and their EO files, mapping frames, and the EO of drone images from their
EXIF/XMP.

Imports :mod:`ins.common`, :mod:`ins.nav` and :mod:`photogrammetry.imagery`.
"""
