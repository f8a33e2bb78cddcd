"""GNSS processing from raw observations: RTKLIB's engine (through the optional
``pyrtklib5`` binding) turned into the toolkit's GNSS solution, and raw receiver logs
(u-blox UBX) converted to RINEX on the way.

Sits between :mod:`ins.io` (it reads its solutions back with the ``.pos`` reader) and
:mod:`ins.estimation` (which may run it before the filter, and later take per-epoch
satellite positions, clocks and pseudoranges from it for tight coupling).
"""
