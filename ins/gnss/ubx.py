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
"""
import os

from ins.common.errors import InputError

__all__ = ["is_ubx", "convert_ubx", "UBX_SYNC", "RINEX_VERSION"]

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
    status = rtk.convrnx(rtk.STRFMT_UBX, opt, path, ofile)
    if status <= 0 or not _has_observation(obs_path):
        raise InputError(f"RTKLIB's convrnx converts no observation from this u-blox log "
                         f"(status {status}; expected UBX RXM-RAWX messages: enable them "
                         f"on the receiver, e.g. with u-center)", path=path)
    if not _has_ephemeris(nav_path):
        nav_path = None
    return obs_path, nav_path


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
