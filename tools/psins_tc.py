"""PSINS's tight-coupling set (``../shared/real/psins_vehicle/insgpseo_tc.mat``) through
``ins process``: loose (RTKLIB single point) against tight (pseudoranges and Doppler).

The set (PSINS ``gnss/test/test_SINS_GPS_tightly_coupled.m``): ``imu`` (n x 7) increments
dtheta x/y/z (rad), dv x/y/z (m/s) in PSINS's body axes right-forward-up, time (s) from
0 at 200 Hz; ``t0`` the GPS second of week of the IMU's time 0; ``ephs`` (32 x 31) one
broadcast ephemeris per PRN (row = PRN; an empty row has sqrtA 0 and health 255) in the
columns of PSINS's ``ggpsvars`` (``ggps.ephs``, 1-based)::

    PRN Toc af0 af1 af2 IODE Crs Deltan M0 Cuc e Cus sqrtA Toe Cic OMEGA0 Cis
    i0 Crc omega OMEGADot iDot L2Cd WN L2PF URA SatHl TGD IODC SOW FitI

in IS-GPS-200 units with angles in rad (not semicircles: i0 ~ 0.96, PSINS's
``satPosBatch`` uses them as rad), WN the continuous GPS week (2183), URA NaN, IODC and
SOW 0; ``obss`` (m x 6): GPS second of week (receiver time, whole seconds), PRN, C/A
pseudorange (m; ``findgpsobs`` -> ``CA = obsi(:,3)`` in the demo), accumulated carrier
phase in metres (column 4: it follows column 3 within metres over the 30 min, a drift of
the size of the ionosphere's code-carrier divergence), a quality figure (column 5,
0.03-12, not used by PSINS's GPS code), Doppler in m/s with RINEX's sign (column 6:
the change of the pseudorange over one second is minus it within 0.04 m/s; PSINS's
``lsVel`` takes ``PRDot`` "in meter"): written as RINEX ``D1C`` = column 6 / lambda_L1
(Hz), ``L1C`` = column 4 / lambda_L1 (cycles), ``C1C`` = column 3.

The tool writes ``imu.txt`` (KF-GINS text, FRD = (y, x, -z) of RFU), ``psins.nav`` (RINEX
3.04 from ``ephs``: :func:`ins.io.rinex_nav_write.write_gps_nav`; transmission time
toe - 2 h, the set has none), ``rover.obs`` (RINEX 3.04) and ``config.toml`` (raw GNSS,
RTKLIB single point, GPS L1), runs loose and tight (``ins.estimation.pipeline.process.process``,
what ``ins process --config config.toml [--coupling tight] --preset PRESET`` runs), and
prints the satellite positions of the RINEX file through RTKLIB against PSINS's columns
through the simulator's IS-GPS-200 code, the loose-tight differences, satellites used,
rejected fractions and processing times; then the same with all but 3, 2 and 1
satellites removed for 30 s (``--outage``), against the all-satellite tight smoothed
solution.

    .venv/bin/python tools/psins_tc.py [--data DIR] [--preset mems] [--keep DIR]

The same runs from the command line, in the folder the tool keeps (``--keep DIR``)::

    ins process --config DIR/all/config.toml -o OUT --preset mems [--coupling tight]

Preset: ``mems`` by default.  The gyros are better than that (the rest's mean rate less
the Earth's is 1-2 deg/h), but the alignment takes the rest's mean rate, Earth rate
included, as the initial gyro bias (``ins.estimation.alignment.motion``); with
``--preset tactical``'s 1 deg/h prior the vertical 8.4 deg/h of Earth rate stays in the
z bias and loose and tight end 2.8 deg apart in heading, with mems' wider priors 0.24.
The IMU's heading is 90 deg from the car's track (heading - course over ground, printed):
PSINS's y axis, our forward, points across this car.
"""
import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "real" / "psins_vehicle"
GPS_L1_WAVELENGTH_M = 299792458.0 / 1575.42e6

#: PSINS's ``ggps.ephs`` columns (0-based here).
PSINS_EPH_COLUMNS = {name: k for k, name in enumerate(
    "PRN Toc af0 af1 af2 IODE Crs Deltan M0 Cuc e Cus sqrtA Toe Cic OMEGA0 Cis i0 Crc "
    "omega OMEGADot iDot L2Cd WN L2PF URA SatHl TGD IODC SOW FitI".split())}


def load(data=DATA):
    """``(imu ImuLog FRD with GPS s of week, ephs (32, 31), obss (m, 6))``."""
    import scipy.io

    from ins.nav.imu import ImuLog
    m = scipy.io.loadmat(Path(data) / "insgpseo_tc.mat")
    imu = np.asarray(m["imu"], float)
    t0 = float(np.asarray(m["t0"]).ravel()[0])
    rfu2frd = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    log = ImuLog(t0 + imu[:, 6], imu[:, 0:3] @ rfu2frd.T, imu[:, 3:6] @ rfu2frd.T)
    return log, np.asarray(m["ephs"], float), np.asarray(m["obss"], float)


def ephemerides(ephs):
    """The non-empty rows of PSINS's ``ephs`` as ``GpsEphemeris`` (same numbers)."""
    from ins.io.rinex_nav import GpsEphemeris
    c = PSINS_EPH_COLUMNS
    out = []
    for row in ephs:
        if row[c["sqrtA"]] < 1000.0:
            continue
        g = {name: float(row[k]) for name, k in c.items()}
        week = int(g["WN"])
        out.append(GpsEphemeris(
            prn=int(g["PRN"]), week=week, toc=g["Toc"], toc_week=week, af0=g["af0"],
            af1=g["af1"], af2=g["af2"], iode=int(g["IODE"]), crs=g["Crs"],
            delta_n=g["Deltan"], m0=g["M0"], cuc=g["Cuc"], e=g["e"], cus=g["Cus"],
            sqrt_a=g["sqrtA"], toe=g["Toe"], cic=g["Cic"], omega0=g["OMEGA0"], cis=g["Cis"],
            i0=g["i0"], crc=g["Crc"], omega=g["omega"], omega_dot=g["OMEGADot"],
            idot=g["iDot"], sv_accuracy=0.0 if np.isnan(g["URA"]) else g["URA"],
            health=int(g["SatHl"]), tgd=g["TGD"], iodc=int(g["IODC"]),
            fit_interval=g["FitI"]))
    return out


def psins_spp(ephs_list, obs_t, week, x0=None, corrections=False):
    """PSINS's single point position of one epoch (its demo's GNSS for loose coupling,
    ``lspvt``), ECEF m and receiver clock m: C/A pseudoranges with the satellite clock
    (relativistic term included, no TGD), no ionosphere or troposphere, the Sagnac
    rotation by ``w_ie rho / c``, weights ``sin(el)^2`` with an elevation below 15 deg
    taken as 0.01 deg (a weight of 3e-8: left out in effect), 20 Gauss-Newton steps at
    most.  The orbits are IS-GPS-200's (PSINS uses WGS84's GM
    3.986004418e14 instead of 3.986005e14: see :func:`gm_effect_m`).  ``corrections``:
    less what our tight coupling takes off through RTKLIB (``c TGD``, RTKLIB's Klobuchar
    with its default coefficients, the set having none, and Saastamoinen), to tell
    PSINS's choice of leaving them in from the rest."""
    import pymap3d

    from ins.simulate.gps_orbit import C_LIGHT, OMEGA_E_GPS, eph_state
    by = {e.prn: e for e in ephs_list}
    rows = [r for r in obs_t if int(r[1]) in by]
    sat = []
    for r in rows:
        e = by[int(r[1])]
        p, _, dt, _ = eph_state(e, week, [r[0] - r[2] / C_LIGHT])
        sat.append((p[0], r[2] + C_LIGHT * dt[0] - (C_LIGHT * e.tgd if corrections else 0.0)))
    x = np.zeros(4) if x0 is None else np.array(x0, float)
    for _ in range(20):
        lat, lon, _h = pymap3d.ecef2geodetic(*x[:3], deg=False)
        up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
        A, dz, w = [], [], []
        for p, pr in sat:
            a = OMEGA_E_GPS * (pr - x[3]) / C_LIGHT
            p = np.array([[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0],
                          [0, 0, 1]]) @ p
            rho = np.linalg.norm(p - x[:3])
            los = (p - x[:3]) / rho
            el = np.arcsin(los @ up) if np.any(x[:3]) else np.pi / 2
            A.append(np.r_[-los, 1.0])
            delay = 0.0
            if corrections and np.any(x[:3]):
                delay = _rtklib_delays(week, obs_t[0][0], (lat, lon, _h), los, el)
            dz.append(pr - delay - rho - x[3])
            w.append(np.sin(el if el >= np.deg2rad(15.0) else np.deg2rad(0.01)) ** 2)
        A, W = np.array(A), np.diag(w)
        dx = np.linalg.solve(A.T @ W @ A, A.T @ W @ np.array(dz))
        x = x + dx
        if dx @ dx < 1e-6:
            break
    return x


def _rtklib_delays(week, t, lla, los_e, el):
    """RTKLIB's Klobuchar (default coefficients) + Saastamoinen delay, m."""
    import pyrtklib5 as rtk
    lat, lon, h = lla
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    north = np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    pos, azel, ion = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(8)
    for i, v in enumerate((lat, lon, h)):
        pos[i] = float(v)
    azel[0], azel[1] = float(np.arctan2(los_e @ east, los_e @ north) % (2 * np.pi)), float(el)
    tt = rtk.gpst2time(week, float(t))
    return rtk.ionmodel(tt, ion, pos, azel) + rtk.tropmodel(tt, pos, azel, 0.7)


def gm_effect_m(ephs_list, week, t):
    """Largest satellite position change (m) at GPS time ``t`` from PSINS's GM
    (3.986004418e14, WGS84) in place of IS-GPS-200's 3.986005e14: the mean motion
    changes by ``n0 (sqrt(GM'/GM) - 1)``, the satellite moves along its orbit by
    ``a dn (t - toe)``."""
    out = 0.0
    for e in ephs_list:
        n0 = np.sqrt(3.986005e14 / e.sqrt_a ** 6)
        dn = n0 * (np.sqrt(3.986004418e14 / 3.986005e14) - 1.0)
        out = max(out, abs(e.sqrt_a ** 2 * dn * (t + (week - e.week) * 604800.0 - e.toe)))
    return out


def elevations(ephs_list, week, t, receiver_e):
    """{prn: elevation rad} at GPS time ``t`` seen from ``receiver_e`` (ECEF m)."""
    import pymap3d

    from ins.simulate.gps_orbit import eph_state
    lat, lon, _ = pymap3d.ecef2geodetic(*receiver_e, deg=False)
    up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    out = {}
    for e in ephs_list:
        d = eph_state(e, week, [t])[0][0] - receiver_e
        out[e.prn] = float(np.arcsin(d @ up / np.linalg.norm(d)))
    return out


def write_case(folder, data=DATA, outage=None, keep_prns=None, start_s=None):
    """imu.txt, psins.nav, rover.obs, config.toml in ``folder``; returns a dict of facts.

    ``outage = (t_first, t_last)`` (GPS s) with ``keep_prns``: only those satellites'
    observations inside the span.  ``start_s``: the observations from this GPS second on
    (the default: the IMU's span less 10 s)."""
    from ins.io.imu_files import write_kfgins_text
    from ins.io.rinex_nav_write import write_gps_nav
    from ins.io.rinex_obs import write_rinex3_obs
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    imu, ephs, obss = load(data)
    eph_list = ephemerides(ephs)
    week = eph_list[0].week
    first = imu.time[0] - 10.0 if start_s is None else start_s
    obss = obss[(obss[:, 0] >= first) & (obss[:, 0] <= imu.time[-1] + 1.0)]
    obss = obss[np.isin(obss[:, 1], [e.prn for e in eph_list])]
    if outage is not None:
        inside = (obss[:, 0] >= outage[0]) & (obss[:, 0] <= outage[1])
        obss = obss[~inside | np.isin(obss[:, 1], list(keep_prns))]
    times = np.unique(obss[:, 0])
    prns = sorted({int(p) for p in obss[:, 1]})
    values = np.full((len(times), len(prns), 3), np.nan)
    i = np.searchsorted(times, obss[:, 0])
    j = np.searchsorted(prns, obss[:, 1].astype(int))
    values[i, j, 0] = obss[:, 2]
    values[i, j, 1] = obss[:, 3] / GPS_L1_WAVELENGTH_M
    values[i, j, 2] = obss[:, 5] / GPS_L1_WAVELENGTH_M
    approx = psins_spp(eph_list, obss[obss[:, 0] == times[0]], week)[:3]
    write_kfgins_text(folder / "imu.txt", imu)
    write_gps_nav(folder / "psins.nav", eph_list,
                  comments=["PSINS insgpseo_tc.mat ephs (tools/psins_tc.py)"])
    write_rinex3_obs(folder / "rover.obs", week, times, prns, values,
                     obs_types=("C1C", "L1C", "D1C"), approx_xyz_m=approx, interval_s=1.0,
                     marker="PSINS", receiver="UNKNOWN", antenna="UNKNOWN",
                     comments=["PSINS insgpseo_tc.mat obss (tools/psins_tc.py)"],
                     program="tools/psins_tc.py")
    (folder / "config.toml").write_text(
        '[files]\nimu = "imu.txt"\nrover = "rover.obs"\nnav = ["psins.nav"]\n'
        '[rtklib]\nmode = "single"\nsystems = ["gps"]\nfrequencies = 1\n'
        'elevation_mask_deg = 10.0\n'
        '[gnss]\nlever_arm_b_m = [0.0, 0.0, 0.0]\nelevation_mask_deg = 10.0\n')
    return {"week": week, "ephemerides": eph_list, "approx_e": approx, "imu": imu}


def orbit_check(nav_path, eph_list, week, times):
    """Largest |RTKLIB satpos (the RINEX file) - simulator eph_state (PSINS's columns)|:
    (position m, clock s) over ``times`` (GPS s) and the satellites."""
    import pyrtklib5 as rtk

    from ins.simulate.gps_orbit import eph_state
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    if rtk.readrnx(str(nav_path), 1, "", obs, nav, sta) != 1:
        raise RuntimeError(f"RTKLIB cannot read {nav_path}")
    dp, dc = 0.0, 0.0
    for e in eph_list:
        r, _, dt, _ = eph_state(e, week, times)
        for k, ts in enumerate(times):
            t = rtk.gpst2time(week, float(ts))
            rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                                 rtk.Arr1Dint(1))
            if not rtk.satpos(t, t, e.prn, rtk.EPHOPT_BRDC, nav, rs, dts, var, svh):
                raise RuntimeError(f"RTKLIB: no position of G{e.prn:02d}")
            dp = max(dp, float(np.linalg.norm(np.array([rs[0], rs[1], rs[2]]) - r[k])))
            dc = max(dc, abs(dts[0] - dt[k]))
    return dp, dc


def run(folder, coupling, preset):
    """``(ProcessResult, seconds)`` of ``ins process`` on ``folder/config.toml``."""
    from ins.common.textfiles import read_toml
    from ins.estimation.pipeline.presets import apply_preset
    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import load_config
    path = str(Path(folder) / "config.toml")
    cfg = load_config(path)
    cfg.coupling = coupling
    cfg.identify = False        # loose and tight with the same noise (tight identifies none)
    if preset != "none":
        cfg = apply_preset(cfg, preset, read_toml(path, "a processing config (TOML)"))
    tic = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = process(cfg, accept_poor=True)
        res.smoothed
    return res, time.perf_counter() - tic


def differences(a, b, t_first=-np.inf, t_last=np.inf):
    """RMS and max of ``a - b`` (Trajectories, common epochs within the span): position
    N/E/D (m), velocity N/E/D (m/s), roll/pitch/heading (deg)."""
    from scipy.spatial.transform import Rotation

    from ins.nav import earth
    from ins.nav.interpolation import interpolate_trajectory
    t = a.time[(a.time >= max(t_first, b.time[0])) & (a.time <= min(t_last, b.time[-1]))]
    ai, bi = interpolate_trajectory(a, t), interpolate_trajectory(b, t)
    dp = earth.ned_offset(bi.lla, ai.lla)
    dv = ai.v_n - bi.v_n
    ea = Rotation.from_quat(ai.q_nb).as_euler("ZYX")[:, ::-1]
    eb = Rotation.from_quat(bi.q_nb).as_euler("ZYX")[:, ::-1]
    da = np.rad2deg((ea - eb + np.pi) % (2 * np.pi) - np.pi)
    return {name: (np.sqrt(np.mean(x ** 2, axis=0)), np.max(np.abs(x), axis=0))
            for name, x in (("pos", dp), ("vel", dv), ("att", da))}


def heading_minus_course(traj, min_speed_mps=3.0):
    """Median and spread (half the 16-84 % range) of heading - course over ground (deg)
    where the horizontal speed exceeds ``min_speed_mps``: a car's heading follows its
    track up to the IMU's mounting and the side slip, so a constant offset is the
    mounting and the spread the heading's noise plus the slip."""
    from scipy.spatial.transform import Rotation
    v = traj.v_n
    ok = np.hypot(v[:, 0], v[:, 1]) > min_speed_mps
    head = Rotation.from_quat(traj.q_nb[ok]).as_euler("ZYX")[:, 0]
    d = np.rad2deg((head - np.arctan2(v[ok, 1], v[ok, 0]) + np.pi) % (2 * np.pi) - np.pi)
    lo, med, hi = np.percentile(d, [16, 50, 84])
    return float(med), float((hi - lo) / 2.0)


def rejected(res):
    """Rejected fractions: {kind: (rejected, total)} of the GNSS measurements."""
    up = getattr(res.fwd, "updater", None)
    recs = getattr(up, "records", None)
    if recs is not None and hasattr(up, "satellites_used"):
        out = {}
        for r in recs:
            n = out.setdefault(r.name, [0, 0])
            n[0] += not r.accepted
            n[1] += 1
        return {k: tuple(v) for k, v in out.items()}
    c = res.counts
    return {"position/velocity fix": (c["rejected"], c["gnss_records"])}


def _fmt(d, key, unit):
    rms, mx = d[key]
    axes = "roll/pitch/heading" if key == "att" else "N/E/D"
    return (f"{key} RMS {axes} {'/'.join(f'{x:.3f}' for x in rms)} {unit}, max "
            f"{'/'.join(f'{x:.3f}' for x in mx)}")


def _summary(name, res, dt):
    c = res.counts
    sats = (f"satellites used min/mean {c['satellites_min']}/{c['satellites_mean']:.1f}"
            if c.get("coupling") == "tight" else "")
    rej = "; ".join(f"{k} rejected {a}/{n} ({100.0 * a / max(n, 1):.1f} %)"
                    for k, (a, n) in rejected(res).items())
    print(f"{name}: {dt:.1f} s; {sats}{'; ' if sats else ''}{rej}")


def psins_comparison(data, eph_list, week, imu, out):
    """Print PSINS's own GNSS positions (its demo's ``lspvt``: :func:`psins_spp`) over
    the IMU's span against the loose and tight smoothed trajectories: mean and RMS N/E/D."""
    import pymap3d

    from ins.nav import earth
    from ins.nav.interpolation import interpolate_trajectory
    obss = load(data)[2]
    t = np.unique(obss[(obss[:, 0] > imu.time[0]) & (obss[:, 0] < imu.time[-1]), 0])
    print(f"PSINS's GNSS positions (its demo's lspvt; {len(t)} epochs; its GM moves the "
          f"satellites by at most {gm_effect_m(eph_list, week, t[0]):.2f} m more) minus our "
          "smoothed trajectories:")
    for corrections in (False, True):
        x, lla = None, []
        for ti in t:
            x = psins_spp(eph_list, obss[obss[:, 0] == ti], week, x, corrections)
            lla.append(pymap3d.ecef2geodetic(*x[:3], deg=False))
        lla = np.array(lla)
        what = ("with c TGD, Klobuchar and Saastamoinen taken off as RTKLIB does"
                if corrections else "as PSINS: no TGD, ionosphere or troposphere")
        for coupling in ("loose", "tight"):
            d = earth.ned_offset(interpolate_trajectory(out[coupling].smoothed, t).lla, lla)
            print(f"  - {coupling}, {what}: mean N/E/D "
                  f"{'/'.join(f'{v:.2f}' for v in d.mean(0))} m, RMS "
                  f"{'/'.join(f'{v:.2f}' for v in np.sqrt(np.mean(d ** 2, 0)))} m")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", default=str(DATA))
    p.add_argument("--preset", default="mems", help="a preset of ins process, or none")
    p.add_argument("--keep", help="folder to keep the files in")
    p.add_argument("--outage", type=float, nargs=2, default=(185595.0, 185625.0),
                   metavar=("T0", "T1"), help="GPS s of the satellite removal (30 s)")
    p.add_argument("--no-outage", action="store_true")
    args = p.parse_args()
    base = Path(args.keep or tempfile.mkdtemp(prefix="psins_tc_"))
    facts = write_case(base / "all", args.data)
    week, eph_list, imu = facts["week"], facts["ephemerides"], facts["imu"]
    dp, dc = orbit_check(base / "all" / "psins.nav", eph_list, week,
                         np.linspace(imu.time[0], imu.time[-1], 5))
    print(f"# {base}: GPS week {week}, IMU {imu.time[0]:.1f}-{imu.time[-1]:.1f} s of week, "
          f"{len(eph_list)} ephemerides")
    print(f"satellite positions, RTKLIB on psins.nav against PSINS's columns (IS-GPS-200): "
          f"max {dp * 1e3:.3f} mm, clock max {dc * 1e12:.3f} ps")
    out = {}
    for coupling in ("loose", "tight"):
        res, dt = run(base / "all", coupling, args.preset)
        out[coupling] = res
        _summary(coupling, res, dt)
    for which in ("forward", "smoothed"):
        d = differences(getattr(out["tight"], which), getattr(out["loose"], which))
        print(f"tight - loose ({which}): " + "; ".join(
            _fmt(d, k, u) for k, u in (("pos", "m"), ("vel", "m/s"), ("att", "deg"))))
        for coupling in ("loose", "tight"):
            med, spread = heading_minus_course(getattr(out[coupling], which))
            print(f"  {coupling} {which}: heading - course over ground (above 3 m/s) "
                  f"median {med:.2f} deg, spread {spread:.2f} deg")
    psins_comparison(args.data, eph_list, week, imu, out)
    if args.no_outage:
        return
    t0, t1 = args.outage
    el = elevations(eph_list, week, t0, facts["approx_e"])
    seen = sorted({int(r) for r in load(args.data)[2][:, 1]} & set(el), key=lambda q: -el[q])
    ref = out["tight"].smoothed
    print(f"satellites removed {t0:.0f}-{t1:.0f} s (all but the highest n of "
          f"{', '.join(f'G{q:02d} {np.rad2deg(el[q]):.0f}' for q in seen)} deg), "
          "against the all-satellite tight smoothed solution, inside the span:")
    for n in (3, 2, 1):
        folder = base / f"keep{n}"
        write_case(folder, args.data, outage=(t0, t1), keep_prns=seen[:n])
        for coupling in (("loose", "tight") if n == 3 else ("tight",)):
            res, dt = run(folder, coupling, args.preset)
            name = f"{coupling}, {n} kept" if coupling == "tight" else "loose, outage (<4)"
            _summary(name, res, dt)
            for which in ("forward", "smoothed"):
                d = differences(getattr(res, which), ref, t0, t1 + 1.0)
                end = differences(getattr(res, which), ref, t1, t1 + 1.0)
                print(f"  {which}: {_fmt(d, 'pos', 'm')}; horizontal at the end "
                      f"{np.hypot(*end['pos'][1][:2]):.2f} m")


if __name__ == "__main__":
    main()
