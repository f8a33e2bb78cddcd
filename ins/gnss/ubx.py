"""u-blox raw receiver logs (UBX: RXM-RAWX observations, RXM-SFRBX navigation subframes)
converted to RINEX 3.04 with RTKLIB's ``convrnx`` (the engine of ``convbin``), through the
optional ``pyrtklib5`` binding, on the way to :func:`ins.gnss.rtklib_engine.solve`: the
u-blox case of :mod:`ins.gnss.receiver_formats` (which converts every format RTKLIB
decodes, the same way).

The call (pyrtklib5 0.2.8, RTKLIB demo5 2.5.0): ``convrnx(STRFMT_UBX, opt, path,
ofile)`` with ``opt`` a fresh ``rnxopt_t`` (RINEX version x100, every system, every
observation type and frequency, the signal mask set to all signals: a zero mask, the
struct's default, writes no observation) and ``ofile`` the nine output names of
convbin (observations, navigation, then the per-system navigation files, empty: not
written).  It returns 1 when it wrote something.  The observation codes are RTKLIB's
(u-blox L2 CL/CM -> ``C2X``/``L2X`` unless demo5's ``-MULTICODE``); the navigation
file is written only when the log holds ephemerides (RXM-SFRBX); without them the
broadcast navigation must come from a RINEX navigation file (``--nav``).

The GPS navigation message gives the week modulo 1024; RTKLIB resolves it against the
computer's clock (``adjgpsweek``), which puts a log more than about ten years old in
the wrong 1024-week era.  The conversion therefore sets RTKLIB's clock (``timeset``) to
the first RXM-RAWX epoch of the log (whose week is complete) and resets it after
(``timereset``): callers serialize RTKLIB calls (:mod:`ins.gnss.rtklib_engine`).
"""
import os

from ins.gnss.receiver_formats import RINEX_VERSION, first_rawx_time  # noqa: F401  (re-exported)

__all__ = ["is_ubx", "convert_ubx", "first_rawx_time", "UBX_SYNC", "RINEX_VERSION"]

UBX_SYNC = b"\xb5\x62"


def is_ubx(path):
    """Whether ``path`` is a u-blox log: the extension ``.ubx``, or a file starting with
    the UBX sync characters ``B5 62`` (RINEX is text and never does)."""
    path = os.fspath(path)
    if os.path.splitext(path)[1].lower() == ".ubx":
        return True
    try:
        with open(path, "rb") as f:
            return f.read(2) == UBX_SYNC
    except OSError:
        return False


def convert_ubx(path, folder, rtk, stem="rover"):
    """Convert a u-blox log into RINEX files in ``folder``:
    :func:`ins.gnss.receiver_formats.convert_raw` with the format ``"ubx"``.

    Returns
    -------
    obs_path : str
        RINEX observations (GPS time of the receiver's RXM-RAWX epochs).
    nav_path : str or None
        RINEX navigation when the log held ephemerides (RXM-SFRBX), else None.

    Raises
    ------
    InputError
        Naming the log: RTKLIB converts no observation from it (no RXM-RAWX message, or
        not a u-blox log).
    """
    from ins.gnss.receiver_formats import convert_raw
    return convert_raw(path, folder, rtk, stem, fmt="ubx")
