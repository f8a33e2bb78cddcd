"""GNSS measurements beyond the loose fixes: pseudoranges and Doppler with the receiver
clock (:mod:`.pseudorange`), double differences against a base
(:mod:`.double_difference`), and what the GNSS log says of itself (the fixes' agreement,
:mod:`.gnss_consistency`; the velocities' lag, :mod:`.velocity_lag`).

Imports :mod:`ins.estimation.core`.
"""
