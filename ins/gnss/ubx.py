"""u-blox raw receiver logs (UBX: RXM-RAWX observations, RXM-SFRBX navigation subframes)
converted to RINEX 3.04 with RTKLIB's ``convrnx`` (the engine of ``convbin``), through the
optional ``pyrtklib5`` binding, on the way to :func:`ins.gnss.rtklib_engine.solve`.

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
import struct

from ins.common.errors import InputError
from ins.io.ublox import ubx_checksum

__all__ = ["is_ubx", "convert_ubx", "first_rawx_time", "UBX_SYNC", "RINEX_VERSION"]

UBX_SYNC = b"\xb5\x62"
#: RINEX version of the converted files (x100, RTKLIB's rnxopt_t.rnxver).
RINEX_VERSION = 304
_N_OUTPUT_FILES = 9          # convbin: obs, nav, gnav, hnav, qnav, lnav, cnav, inav, sbas


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
    """Convert a u-blox log into RINEX files in ``folder``.

    Parameters
    ----------
    path : str or os.PathLike
        The UBX log (RXM-RAWX, optionally RXM-SFRBX).
    folder : str
        An existing folder for the converted files (``<stem>.obs``, ``<stem>.nav``).
    rtk : module
        The imported ``pyrtklib5``.
    stem : str
        Name of the converted files.

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
    path = os.fspath(path)
    obs_path = os.path.join(folder, stem + ".obs")
    nav_path = os.path.join(folder, stem + ".nav")
    opt = rtk.rnxopt_t()
    opt.rnxver = RINEX_VERSION
    opt.navsys = rtk.SYS_ALL
    opt.obstype = rtk.OBSTYPE_ALL
    opt.freqtype = rtk.FREQTYPE_ALL
    opt.ttol = 0.005                     # s, convbin's default epoch tolerance
    for i in range(7):                   # mask[7][64]: every signal of every system
        for j in range(64):
            opt.mask[i, j] = "1"
    ofile = [obs_path, nav_path] + [""] * (_N_OUTPUT_FILES - 2)
    first = first_rawx_time(path)
    if first is not None:
        rtk.timeset(rtk.gpst2utc(rtk.gpst2time(*first)))
    try:
        status = rtk.convrnx(rtk.STRFMT_UBX, opt, path, ofile)
    finally:
        if first is not None:
            rtk.timereset()
    if status <= 0 or not _has_observation(obs_path):
        raise InputError(f"RTKLIB's convrnx converts no observation from this u-blox log "
                         f"(status {status}; expected UBX RXM-RAWX messages: enable them "
                         f"on the receiver, e.g. with u-center)", path=path)
    if not _has_ephemeris(nav_path):
        nav_path = None
    return obs_path, nav_path


def first_rawx_time(path, limit_bytes=1 << 22):
    """``(week, tow_s)`` of the first RXM-RAWX message (with a valid checksum) in the
    first ``limit_bytes`` of a UBX log, or None."""
    with open(path, "rb") as f:
        data = f.read(limit_bytes)
    k = data.find(b"\xb5\x62\x02\x15")
    while 0 <= k and k + 8 + 16 <= len(data):
        length = struct.unpack_from("<H", data, k + 4)[0]
        end = k + 6 + length
        if end + 2 <= len(data) and data[end:end + 2] == ubx_checksum(data[k + 2:end]):
            tow, week = struct.unpack_from("<dH", data, k + 6)
            if week > 0:
                return int(week), float(tow)
        k = data.find(b"\xb5\x62\x02\x15", k + 2)
    return None


def _has_observation(path):
    """A RINEX 3 observation file with at least one epoch record (``>``)."""
    if not os.path.isfile(path):
        return False
    with open(path, "rb") as f:
        return any(line.startswith(b">") for line in f)


def _has_ephemeris(path):
    """A RINEX navigation file with a data record after its header."""
    if not os.path.isfile(path):
        return False
    with open(path, "rb") as f:
        body = f.read().split(b"END OF HEADER", 1)
    return len(body) == 2 and bool(body[1].strip())
