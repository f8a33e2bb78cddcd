"""Structure-from-motion projects in and out: OpenSfM/ODM reconstructions and COLMAP
models and databases.

Imports :mod:`ins.common`, :mod:`ins.nav` and :mod:`photogrammetry.orientation`.
"""
