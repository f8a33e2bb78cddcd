"""Shared utilities at the bottom of both packages, with no navigation in them: the
input errors and warnings (:mod:`~ins.common.errors`), atomic output files and folders
(:mod:`~ins.common.fileio`), Ctrl-C handling (:mod:`~ins.common.interrupts`), exact text
tables (:mod:`~ins.common.textparse`, :mod:`~ins.common.textformat`,
:mod:`~ins.common.textfiles`, :mod:`~ins.common.textrows`), strict TOML tables
(:mod:`~ins.common.tomlschema`) and the plot style (:mod:`~ins.common.plotstyle`).

Imports nothing of the toolkit.
"""
