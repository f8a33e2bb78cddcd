"""The coplanarity adjustment: stereo pairs and blocks of exposure angles, their sparse
algebra and covariance, the quality rules, the INS assessment and boresight (REML), the
batch and tiled runs and the Markdown report.

Imports :mod:`ins.common`, :mod:`ins.nav` and :mod:`photogrammetry.orientation`.
"""
