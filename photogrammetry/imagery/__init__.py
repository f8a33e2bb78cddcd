"""Images and their tie points: grey levels of large frames in bounded memory, features and
their cache, matching, tie points from images, and the tie-point file.

Imports :mod:`ins.common` only.
"""
