"""The initial state: static coarse alignment, in-air start from GNSS or a given state
(:mod:`.initial`), fine alignment at rest (:mod:`.fine`), the start from a moving log
(:mod:`.motion`) and the at-rest test (:mod:`.static_check`).

Imports :mod:`ins.estimation.core`.
"""
