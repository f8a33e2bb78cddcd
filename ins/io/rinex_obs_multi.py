"""RINEX 3.04 observation files of several systems and signals (the writer of
``ins import-android``): a ``SYS / # / OBS TYPES`` record per system (``C L D S`` of
each of its signals, in the order first met), epoch records ``> yyyy mm dd hh mm
ss.sssssss  0 n`` in GPS time, satellite lines ``Xnn`` with F14.3 values, the
loss-of-lock indicator after each phase (bit 0: lost lock since the previous epoch).
Units of RINEX: pseudorange m, phase cycles, Doppler Hz, C/N0 dB-Hz.  Written
atomically (:func:`ins.common.fileio.atomic_open`)."""
import numpy as np

from ins.common.fileio import atomic_open
from ins.io.rinex_obs import _field, _hline, gps_calendar, header_start

__all__ = ["write_rinex3_multi"]

_SYSTEM_ORDER = "GRECJIS"


def write_rinex3_multi(path, week, time_s, epochs, program="ins import-android",
                       marker="ANDROID", receiver="ANDROID", comments=(), leap_seconds=None,
                       glonass_fcn=None):
    """Write observations of any systems as RINEX 3.04.

    Parameters
    ----------
    path : str or os.PathLike
    week : int
        GPS week of ``time_s``.
    time_s : array_like, shape (n,)
        Epochs, GPS s of ``week``.
    epochs : list of dict, length n
        ``{(system letter, prn, signal code e.g. "1C"): (C m, L cycles, D Hz, S dB-Hz,
        lli)}``; NaN values are left blank.
    comments : sequence of str
        ``COMMENT`` lines.
    glonass_fcn : dict, optional
        ``{GLONASS slot: frequency channel -7..6}``: the ``GLONASS SLOT / FRQ #``
        record (RINEX 3.04 asks it of a file with GLONASS observations).

    Returns
    -------
    int
        Epochs written (those with at least one value).
    """
    codes = {}
    for ep in epochs:
        for sys, _, code in ep:
            codes.setdefault(sys, [])
            if code not in codes[sys]:
                codes[sys].append(code)
    systems = [s for s in _SYSTEM_ORDER if s in codes]
    types = {s: [q + c for c in codes[s] for q in "CLDS"] for s in systems}
    first = next((i for i, ep in enumerate(epochs) if ep), 0)
    y, mo, d, h, mi, s = gps_calendar(week, time_s[first] if len(time_s) else 0.0)
    head = header_start("M", (y, mo, d, h, mi, s), marker, comments, program=program,
                        observer=("", ""), receiver=receiver, antenna="ANDROID")
    for sname in systems:
        t = types[sname]
        for k in range(0, len(t), 13):
            lead = f"{sname}{len(t):5d}" if k == 0 else " " * 6
            head.append(_hline(lead + "".join(f" {x}" for x in t[k:k + 13]),
                               "SYS / # / OBS TYPES"))
    head.append(_hline(f"{y:6d}{mo:6d}{d:6d}{h:6d}{mi:6d}{s:13.7f}     GPS",
                       "TIME OF FIRST OBS"))
    for sname in systems:
        head += [_hline(f"{sname} {x}", "SYS / PHASE SHIFT") for x in types[sname]
                 if x.startswith("L")]
    if "R" in systems and glonass_fcn:
        slots = sorted(glonass_fcn.items())
        for k in range(0, len(slots), 8):
            lead = f"{len(slots):3d} " if k == 0 else " " * 4
            head.append(_hline(lead + "".join(f"R{p:02d} {c:2d} " for p, c in
                                              slots[k:k + 8]), "GLONASS SLOT / FRQ #"))
    if "R" in systems:
        head.append(_hline(" C1C    0.000 C1P    0.000 C2C    0.000 C2P    0.000",
                           "GLONASS COD/PHS/BIS"))
    if leap_seconds is not None:
        head.append(_hline(f"{int(leap_seconds):6d}", "LEAP SECONDS"))
    head.append(_hline("", "END OF HEADER"))
    written = 0
    with atomic_open(path, "w") as f:
        f.write("".join(head))
        for ti, ep in zip(time_s, epochs):
            sats = sorted({(s, p) for s, p, _ in ep},
                          key=lambda sp: (_SYSTEM_ORDER.index(sp[0]), sp[1]))
            lines = []
            for sname, prn in sats:
                vals = []
                for x in types[sname]:
                    v = ep.get((sname, prn, x[1:]))
                    if v is None:
                        vals.append(" " * 16)
                        continue
                    k = "CLDS".index(x[0])
                    lli = int(v[4]) if x[0] == "L" else 0
                    vals.append(_field(float(v[k]) if np.isfinite(v[k]) else np.nan, lli, 0))
                body = "".join(vals).rstrip()
                if body:
                    lines.append(f"{sname}{prn:02d}{body}\n")
            if not lines:
                continue
            y, mo, d, h, mi, s = gps_calendar(week, ti)
            f.write(f"> {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d}{s:11.7f}  0{len(lines):3d}\n")
            f.write("".join(lines))
            written += 1
    return written
