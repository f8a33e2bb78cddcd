"""Signals of the multi-constellation raw observations: frequencies, RINEX codes, clocks.

Each system's signals in the order of the observations (``RawSettings.signals`` names
them; the default is each system's first)::

    G  L1  1575.42 MHz  C1C L1C D1C S1C    (C/A)
       L2  1227.60 MHz  C2W L2W D2W S2W    (P(Y), semi-codeless)
       L5  1176.45 MHz  C5Q L5Q D5Q S5Q
    E  E1  1575.42 MHz  C1C L1C D1C S1C
       E5a 1176.45 MHz  C5Q L5Q D5Q S5Q
    R  G1  1602 + 0.5625 k MHz  C1C L1C D1C S1C   (FDMA: channel k of the satellite)
       G2  1246 + 0.4375 k MHz  C2C L2C D2C S2C
    C  B1I 1561.098 MHz C2I L2I D2I S2I    (RINEX 3.04 calls B1 band 2)
       B2a 1176.45 MHz  C5P L5P D5P S5P    (BDS-3 pilot; given to every satellite here)
       B3I 1268.52 MHz  C6I L6I D6I S6I    (RTKLIB-EX 2.5.0 with NFREQ = 3 skips band 6)

Satellite clock of a signal (s, satellite minus system time): the broadcast clock for
every signal except GPS, whose ``tgd`` is the L1-L2 P(Y) group delay
(IS-GPS-200 20.3.3.3.3.2, ``gamma = (f_L1 / f_L2)^2 = (77/60)^2``)::

    dt_L1 = dt_sv - tgd,   dt_L2 = dt_sv - gamma tgd,   dt_L5 = dt_sv - tgd
    (L5: IS-GPS-705 20.3.3.3.1.2 with the inter-signal correction ISC_L5 = 0)

so that the L1/L2 ionosphere-free combination carries ``dt_sv``.  The ionospheric group
delay of a signal is the L1 delay times ``(f_L1 / f)^2``, the phase advance the same.
"""
import numpy as np

from ins.common.errors import InputError
from ins.simulate.glonass_orbit import glonass_frequencies

__all__ = ["SIGNALS", "SYSTEMS", "F_L1", "signal_table", "frequency_hz", "clock_offset",
           "obs_types"]

#: GPS L1, the frequency of the Klobuchar delay, Hz.
F_L1 = 1575.42e6
#: system -> ((name, frequency Hz or None for FDMA, RINEX band + attribute), ...).
SIGNALS = {
    "G": (("L1", 1575.42e6, "1C"), ("L2", 1227.60e6, "2W"), ("L5", 1176.45e6, "5Q")),
    "E": (("E1", 1575.42e6, "1C"), ("E5a", 1176.45e6, "5Q")),
    "R": (("G1", None, "1C"), ("G2", None, "2C")),
    "C": (("B1I", 1561.098e6, "2I"), ("B2a", 1176.45e6, "5P"), ("B3I", 1268.52e6, "6I")),
}
#: The systems in RINEX order of this simulator.
SYSTEMS = ("G", "R", "E", "C")
_GAMMA_L2 = (77.0 / 60.0) ** 2


def signal_table(systems, signals=()):
    """Per system the indices into :data:`SIGNALS` of the simulated signals.

    Parameters
    ----------
    systems : sequence of str
        Of ``G R E C``.
    signals : sequence of str
        Signal names (``L1 L2 L5 E1 E5a G1 G2 B1I B2a B3I``); empty: each system's first.

    Returns
    -------
    dict
        system -> tuple of indices (a system with none of the named signals: its first).
    """
    bad = [s for s in systems if s not in SIGNALS]
    if bad or not systems or len(set(systems)) != len(systems):
        raise InputError(f"[gnss_raw] systems: expected distinct systems of {list(SYSTEMS)}, "
                         f"got {list(systems)}")
    names = {n for sys in SIGNALS.values() for n, _, _ in sys}
    unknown = [s for s in signals if s not in names]
    if unknown:
        raise InputError(f"[gnss_raw] signals: unknown {unknown}; known: {sorted(names)}")
    out = {}
    for sys in systems:
        idx = tuple(i for i, (n, _, _) in enumerate(SIGNALS[sys]) if n in signals)
        out[sys] = idx or (0,)
    return out


def frequency_hz(system, index, k=0):
    """Carrier frequency of signal ``index`` of ``system`` (GLONASS: channel ``k``), Hz."""
    f = SIGNALS[system][index][1]
    if f is None:
        return float(glonass_frequencies(k)[index])
    return f


def clock_offset(system, index, tgd):
    """Signal clock minus the broadcast L1 clock of the orbit model, s (``tgd``: GPS's,
    s; the orbits' L1 clock is ``dt_sv - tgd``)."""
    if system == "G" and index == 1:
        return -(_GAMMA_L2 - 1.0) * np.asarray(tgd, dtype=float)
    return np.zeros_like(np.asarray(tgd, dtype=float))


def obs_types(system, indices):
    """RINEX 3 observation codes ``C L D S`` of each signal, in order."""
    return tuple(f"{t}{SIGNALS[system][i][2]}" for i in indices for t in "CLDS")
