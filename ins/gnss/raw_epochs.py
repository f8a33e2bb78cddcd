"""Per-epoch satellite data for tight coupling from RINEX observations and broadcast
navigation, all through RTKLIB (``pyrtklib5``; nothing of RTKLIB's algorithms written
again): ``readrnx`` reads the files, ``satposs`` gives each satellite's position,
velocity, clock bias and drift at the transmit time (broadcast ephemerides),
``satazel`` its elevation and azimuth, ``ionmodel`` the Klobuchar delay (the nav file's
coefficients) and ``tropmodel`` the Saastamoinen delay.  The result is a
:class:`RawEpochs` with corrected pseudoranges
(``P - c TGD + c dt_s - I - T``, m) and range rates (``-lambda D + c ddt_s``, m/s).

The ionospheric and tropospheric delays need the receiver's position: ``receiver_ecef``
is one position (a static receiver, or a flight over a small area at a roughly known
height) or a callable of time (s) giving it (e.g. from the loose solution).  A position
wrong by 1 km moves the delays by millimetres horizontally; by about 0.3 m per km of
height error at zenith (troposphere).

The constellations of ``systems`` (GPS by default; GLONASS, Galileo, BeiDou, QZSS),
each satellite's first frequency as RTKLIB keeps it (GPS L1 C/A, GLONASS G1 of its
channel, Galileo E1, BeiDou B1I; RINEX 2 ``C1``/``P1`` and ``D1``) with its own
wavelength (``sat2freq``; the Klobuchar delay scaled by ``(f_L1 / f)^2``), and the
carrier phase of the first and second frequencies corrected like the code but for the
ionosphere's sign (``lambda L + c dt_s + I - T``, m: the carrier is advanced by what
delays the code) with their loss-of-lock indicators (RINEX LLI, bit 0 a possible cycle
slip).  The filter gives each system other than the first its own clock offset
(:mod:`ins.estimation.coupling.pseudorange`) or forms double differences within each
system (:mod:`ins.estimation.coupling.double_difference`).
Times are GPS seconds of the week (the IMU's convention).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

__all__ = ["RawEpochs", "read_raw_epochs", "GPS_L1_HZ", "GPS_L2_HZ", "SYSTEMS",
           "SYSTEM_NAMES"]

#: Constellations tight coupling reads: RINEX letters.
SYSTEMS = ("G", "R", "E", "C", "J")
#: Their names as ``[rtklib] systems`` spells them.
SYSTEM_NAMES = {"gps": "G", "glonass": "R", "galileo": "E", "beidou": "C", "qzss": "J"}

#: GPS L1 carrier frequency, Hz.
GPS_L1_HZ = 1575.42e6
#: GPS L2 carrier frequency, Hz.
GPS_L2_HZ = 1227.60e6


@dataclass
class RawEpochs:
    """Corrected raw observations per epoch (:mod:`ins.estimation.coupling.pseudorange`'s notes), ragged over epochs.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Receive time of each epoch, s (the IMU's time scale: GPS seconds of week).
    sats : list of ndarray (k_i,) of int
        Satellite numbers (RTKLIB's, or any id) of each epoch.
    sat_pos_e, sat_vel_e : list of ndarray (k_i, 3)
        Satellite position (m) and velocity (m/s), ECEF at the transmit time.
    range_m : list of ndarray (k_i,)
        Corrected pseudoranges, m (``nan``: none).
    range_rate_mps : list of ndarray (k_i,)
        Corrected range rates, m/s (``nan``: no Doppler).
    snr_dbhz : list of ndarray (k_i,), optional
        Carrier-to-noise density, dB-Hz.
    names : list of list of str, optional
        Satellite names (``G05``) for the innovation file.
    phase_m : list of ndarray (k_i,), optional
        Corrected L1 carrier phase, m (``nan``: none; its ambiguity ``lambda N`` and the
        receiver's phase offset left in).
    lli : list of ndarray (k_i,) of int, optional
        Loss-of-lock indicators (bit 0: a cycle slip may have happened since the last
        epoch).
    wavelength_m : float
        The carrier's wavelength, m.
    phase2_m, lli2 : list of ndarray (k_i,), optional
        The same for the second frequency (RTKLIB's index 1: GPS L2, GLONASS G2, Galileo
        E5b, BeiDou B2I; else index 2: GPS L5, Galileo E5a, BeiDou B2a; the Klobuchar
        advance scaled by ``(f_L1 / f)^2``), when observed.
    wavelength2_m : float
        Its wavelength, m.
    lam_m, lam2_m : list of ndarray (k_i,), optional
        The wavelength of each satellite's first and second frequency, m (GLONASS: its
        channel's; ``None``: ``wavelength_m`` / ``wavelength2_m`` for all).
    """

    time: np.ndarray
    sats: list
    sat_pos_e: list
    sat_vel_e: list
    range_m: list
    range_rate_mps: list
    snr_dbhz: list = None
    names: list = None
    phase_m: list = None
    lli: list = None
    wavelength_m: float = 299792458.0 / 1575.42e6
    phase2_m: list = None
    lli2: list = None
    wavelength2_m: float = 299792458.0 / 1227.60e6
    lam_m: list = None
    lam2_m: list = None

    def __post_init__(self):
        self.time = np.asarray(self.time, dtype=float)
        if self.names is None:
            self.names = [[f"S{int(s):03d}" for s in ids] for ids in self.sats]
        self.has_velocity = False          # what the loose updater asks of a GNSS log

    def __len__(self):
        return len(self.time)

    def update_events(self, use_velocity=True):
        """One update event per epoch: ``(time, epoch, kind = 1)``."""
        n = len(self.time)
        return self.time.copy(), np.arange(n), np.ones(n, dtype=np.int64)

    def select(self, keep):
        """A copy with, per epoch ``i``, only the satellites where ``keep(i, sats)`` is
        True (a boolean array over the epoch's satellites): masking for tests."""
        out = {k: [] for k in ("sats", "sat_pos_e", "sat_vel_e", "range_m",
                               "range_rate_mps", "names")}
        opt = {k: [] for k in ("snr_dbhz", "phase_m", "lli", "phase2_m", "lli2", "lam_m",
                               "lam2_m")
               if getattr(self, k) is not None}
        for i in range(len(self.time)):
            m = np.asarray(keep(i, self.sats[i]), dtype=bool)
            for k in out:
                v = getattr(self, k)[i]
                out[k].append(np.asarray(v)[m] if k != "names" else
                              [n for n, f in zip(v, m) if f])
            for k in opt:
                opt[k].append(np.asarray(getattr(self, k)[i])[m])
        return RawEpochs(self.time, wavelength_m=self.wavelength_m,
                         wavelength2_m=self.wavelength2_m, **opt, **out)


def _arr(rtk, values):
    a = rtk.Arr1Ddouble(len(values))
    for i, v in enumerate(values):
        a[i] = float(v)
    return a


def read_raw_epochs(obs_path, nav_paths, receiver_ecef, elevation_min_deg=0.0, rtk=None,
                    systems=("G",)):
    """Read and correct a receiver's observations of ``systems`` (module notes).

    Parameters
    ----------
    obs_path : str
        RINEX 2/3 observation file.
    nav_paths : str or sequence of str
        Broadcast navigation file(s) (GPS ephemerides and Klobuchar coefficients).
    receiver_ecef : array_like (3,) or callable
        Receiver position for the atmospheric delays, ECEF m, or ``f(t_gps_s) -> (3,)``.
    elevation_min_deg : float
        Satellites below are left out here (the filter applies its own mask), deg.
    rtk : module, optional
        The binding (default: :func:`ins.gnss.rtklib_engine.binding`).
    systems : sequence of str
        The constellations read, letters of :data:`SYSTEMS` (``G`` GPS, ``R``
        GLONASS, ``E`` Galileo, ``C`` BeiDou, ``J`` QZSS).

    Returns
    -------
    RawEpochs
        Epochs with at least one GPS satellite with a healthy broadcast ephemeris.

    Raises
    ------
    InputError
        A file RTKLIB reads nothing from (named), or no usable epoch.
    """
    from ins.gnss.rtklib_engine import binding
    rtk = binding() if rtk is None else rtk
    nav_paths = [nav_paths] if isinstance(nav_paths, (str, bytes)) or hasattr(
        nav_paths, "__fspath__") else list(nav_paths)
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    try:
        if not rtk.readrnx(str(obs_path), 1, "", obs, nav, sta) or obs.n <= 0:
            raise InputError("RTKLIB reads no observation from this file (expected RINEX "
                             "2.x/3.x observations)", path=str(obs_path))
        for p in nav_paths:
            if not rtk.readrnx(str(p), 1, "", obs, nav, sta):
                raise InputError("RTKLIB reads nothing from this navigation file",
                                 path=str(p))
        unknown = [s for s in systems if s not in SYSTEMS]
        if unknown:
            raise ValueError(f"systems: unknown {unknown} (known: {', '.join(SYSTEMS)})")
        if nav.n + nav.ng <= 0:
            raise InputError("no broadcast ephemeris in the navigation file(s)",
                             path=str(nav_paths[0]))
        rtk.sortobs(obs)
        rtk.uniqnav(nav)
        return RawEpochs(**_epochs(rtk, obs, nav, receiver_ecef, elevation_min_deg,
                                   tuple(systems)))
    finally:
        rtk.freeobs(obs)
        rtk.freenav(nav, 0xFF)


def _systems(rtk):
    """RTKLIB's system flags -> the letters of :data:`SYSTEMS`."""
    return {rtk.SYS_GPS: "G", rtk.SYS_GLO: "R", rtk.SYS_GAL: "E", rtk.SYS_CMP: "C",
            rtk.SYS_QZS: "J"}


def _epochs(rtk, obs, nav, receiver_ecef, el_min_deg, systems=SYSTEMS):
    fixed = None if callable(receiver_ecef) else np.asarray(receiver_ecef, float)
    out = {k: [] for k in ("time", "sats", "sat_pos_e", "sat_vel_e", "range_m",
                           "range_rate_mps", "snr_dbhz", "names", "phase_m", "lli",
                           "phase2_m", "lli2", "lam_m", "lam2_m")}
    letters = _systems(rtk)
    week = rtk.Arr1Dint(1)
    rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                         rtk.Arr1Dint(1))
    e, azel, pos = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(3)
    name, prn = rtk.Arr1Dchar(8), rtk.Arr1Dint(1)
    tgd = _group_delays(nav)
    c = rtk.CLIGHT
    data, n = obs.data, obs.n
    i = 0
    while i < n:
        t0 = data[i].time
        j = i
        while j < n and abs(rtk.timediff(data[j].time, t0)) < 1e-6:
            j += 1
        t_s = rtk.time2gpst(t0, week)
        r = np.asarray(fixed if fixed is not None else receiver_ecef(t_s), float)
        rr = _arr(rtk, r)
        rtk.ecef2pos(rr, pos)
        ep = {k: [] for k in out if k != "time"}
        for k in range(i, j):
            d = data[k]
            if letters.get(rtk.satsys(d.sat, prn)) not in systems or d.P[0] == 0.0:
                continue
            f1 = rtk.sat2freq(d.sat, d.code[0], nav)
            if not f1 > 0.0:                  # a GLONASS satellite without its channel
                continue
            rtk.satposs(d.time, d, 1, nav, rtk.EPHOPT_BRDC, rs, dts, var, svh)
            if svh[0] != 0 or (rs[0] == 0.0 and rs[1] == 0.0 and rs[2] == 0.0):
                continue
            rtk.geodist(rs, rr, e)
            el = rtk.satazel(pos, e, azel)
            if el < np.deg2rad(el_min_deg):
                continue
            # Klobuchar's L1 delay, scaled to the signal's frequency (1/f^2)
            klob = rtk.ionmodel(d.time, nav.ion_gps, pos, azel)
            trop = rtk.tropmodel(d.time, pos, azel, 0.7)
            lam1, iono1 = c / f1, klob * (GPS_L1_HZ / f1) ** 2
            rng = d.P[0] - c * tgd.get(d.sat, 0.0) + c * dts[0] - iono1 - trop
            rate = (-lam1 * d.D[0] + c * dts[1]) if d.D[0] != 0.0 else np.nan
            rtk.satno2id(d.sat, name)
            ep["sats"].append(int(d.sat))
            ep["sat_pos_e"].append([rs[0], rs[1], rs[2]])
            ep["sat_vel_e"].append([rs[3], rs[4], rs[5]])
            ep["range_m"].append(rng)
            ep["range_rate_mps"].append(rate)
            ep["snr_dbhz"].append(d.SNR[0] * 0.001 if d.SNR[0] > 1000 else float(d.SNR[0]))
            ep["names"].append(_name(name))
            ep["phase_m"].append(lam1 * d.L[0] + c * dts[0] + iono1 - trop
                                 if d.L[0] != 0.0 else np.nan)
            ep["lli"].append(int(d.LLI[0]))
            ep["lam_m"].append(lam1)
            # the second frequency: RTKLIB's index 1 (GPS L2, GLONASS G2, Galileo E5b,
            # BeiDou B2I), else index 2 (GPS L5, Galileo E5a, BeiDou B2a)
            j2 = next((j for j in range(1, min(int(rtk.NFREQ), 3)) if d.L[j] != 0.0), None)
            f2 = rtk.sat2freq(d.sat, d.code[j2], nav) if j2 is not None else 0.0
            lam2 = c / f2 if f2 > 0.0 else np.nan
            ep["phase2_m"].append(lam2 * d.L[j2] + c * dts[0] + klob * (GPS_L1_HZ / f2) ** 2
                                  - trop if f2 > 0.0 else np.nan)
            ep["lli2"].append(int(d.LLI[j2]) if j2 is not None else 0)
            ep["lam2_m"].append(lam2)
        i = j
        if not ep["sats"]:
            continue
        out["time"].append(t_s)
        for k, v in ep.items():
            out[k].append(v if k == "names" else np.array(
                v, dtype=int if k in ("sats", "lli", "lli2") else float).reshape(
                    (len(v), 3) if k in ("sat_pos_e", "sat_vel_e") else (len(v),)))
    if not out["time"]:
        raise InputError(f"no epoch with a satellite of {', '.join(systems)} that has a "
                         f"broadcast ephemeris")
    out["time"] = np.array(out["time"])
    if not any(np.any(np.isfinite(p)) for p in out["phase2_m"]):
        out["phase2_m"] = out["lli2"] = out["lam2_m"] = None   # no second frequency
    return out


def _group_delays(nav):
    """Broadcast group delay of the first frequency (s) per satellite from the
    ephemerides (the last one read; it changes rarely), applied to its pseudorange as
    RTKLIB's single-frequency code does (``P1 - c TGD``): GPS and QZSS TGD, Galileo
    BGD(E1, E5a), BeiDou TGD1 (B1I); GLONASS none (its broadcast clock is the G1
    user's)."""
    out = {}
    for k in range(nav.n):
        e = nav.eph[k]
        out[int(e.sat)] = float(e.tgd[0])
    return out


def _name(arr):
    """The text of an ``Arr1Dchar`` (the binding gives the C string from an index on)."""
    c = arr[0]
    if isinstance(c, str):
        return c
    chars = []
    for k in range(len(arr)):
        if not arr[k]:
            break
        chars.append(chr(arr[k]))
    return "".join(chars)
