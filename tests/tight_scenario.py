"""Synthetic GPS constellation over a simulated flight, for tight coupling (test
scaffolding, not library code; used by tests/test_tight.py and bench/bench_tight.py).

The truth is independent of the filter's measurement model: satellites on circular
orbits (radius 26 560 km, 55 deg inclination, 6 planes of 4) in an inertial frame, the
signal's transmit time found by iteration and the Earth's rotation during the travel
applied as an exact rotation of the frame; range rates are central differences of the
exact ranges over +-5 ms of the truth trajectory.  The antenna sits on a fixed arm
``l_b`` in the truth's body frame.  Receiver clock: bias 5 km, drift 0.3 m/s, then the
two-state clock model (:func:`clock_truth`, an OCXO by default).  Pseudorange noise ``sqrt(a^2 + b^2 / sin^2 el)``; range-rate noise likewise.
"""
import functools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ins.estimation.coupling.pseudorange import CLIGHT  # noqa: E402
from ins.gnss.raw_epochs import RawEpochs  # noqa: E402
from ins.io.gnss_log import GnssLog  # noqa: E402
from ins.nav import earth  # noqa: E402
from ins.nav.rotation import quat_to_dcm  # noqa: E402

R_ORBIT = 26_560e3
N_ORBIT = np.sqrt(3.986004418e14 / R_ORBIT ** 3)        # mean motion, rad/s


def sat_eci(t, k):
    """Inertial position of satellite ``k`` (0..23) at time ``t`` (s), m."""
    plane, slot = divmod(k, 4)
    raan = np.deg2rad(60.0 * plane + 17.0)
    u = N_ORBIT * t + np.deg2rad(90.0 * slot + 15.0 * plane)
    inc = np.deg2rad(55.0)
    x, y = R_ORBIT * np.cos(u), R_ORBIT * np.sin(u)
    xo, yo, zo = x, y * np.cos(inc), y * np.sin(inc)
    return np.array([xo * np.cos(raan) - yo * np.sin(raan),
                     xo * np.sin(raan) + yo * np.cos(raan), zo])


def rz_frame(theta):
    """Frame rotation about z by ``theta`` (coordinates in the rotated frame)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def sat_ecef(t, k):
    """ECEF position at ``t`` (the frame of that instant), m."""
    return rz_frame(earth.OMEGA_IE * t) @ sat_eci(t, k)


def exact_range(t_rx, r_rx_e, k):
    """Geometric range, transmit-time ECEF satellite position and its ECEF velocity."""
    tau = 0.075
    for _ in range(5):
        r_s = sat_ecef(t_rx - tau, k)
        r_s_rx = rz_frame(earth.OMEGA_IE * tau) @ r_s       # into the receive-time frame
        tau = np.linalg.norm(r_s_rx - r_rx_e) / CLIGHT
    r_s = sat_ecef(t_rx - tau, k)
    v_s = (sat_ecef(t_rx - tau + 0.01, k) - sat_ecef(t_rx - tau - 0.01, k)) / 0.02
    rho = np.linalg.norm(rz_frame(earth.OMEGA_IE * tau) @ r_s - r_rx_e)
    return rho, r_s, v_s


def antenna_ecef(truth, rows, l_b):
    q = truth.q_nb[rows]
    off = np.einsum("nij,j->ni", quat_to_dcm(q), l_b)
    return earth.offset_ecef(truth.lla[rows], off)


#: Clock noise of the simulation and the filter, (bias, drift) spectral densities
#: m^2/s and m^2/s^3: an OCXO (Brown and Hwang: h0 = 8e-20, h-2 = 4e-23).
OCXO = (0.5 * CLIGHT ** 2 * 8e-20, 2 * np.pi ** 2 * CLIGHT ** 2 * 4e-23)


def clock_truth(times, rng, clock_psd):
    """Receiver clock bias (m) and drift (m/s) at ``times``: 5 km and 0.3 m/s at the
    start, then the two-state model with ``clock_psd`` (exact discretization)."""
    qb, qd = clock_psd
    bias, drift = [5000.0], [0.3]
    for dt in np.diff(times):
        Q = [[qb * dt + qd * dt ** 3 / 3, qd * dt ** 2 / 2], [qd * dt ** 2 / 2, qd * dt]]
        w = rng.multivariate_normal(np.zeros(2), Q)
        bias.append(bias[-1] + drift[-1] * dt + w[0])
        drift.append(drift[-1] + w[1])
    return np.array(bias), np.array(drift)


def make_epochs(truth, times, l_b, seed=0, mask_deg=10.0, sigma_rho=(0.3, 0.3),
                sigma_rate=(0.05, 0.05), clock_psd=OCXO):
    """:class:`RawEpochs` of every satellite above ``mask_deg`` at ``times`` (on truth
    rows), with the truth clock; returns ``(epochs, clock_bias_m)``."""
    rng = np.random.default_rng(seed)
    rows = np.searchsorted(truth.time, times - 1e-6)
    bias, drift = clock_truth(times, rng, clock_psd)
    out = {k: [] for k in ("sats", "sat_pos_e", "sat_vel_e", "range_m", "range_rate_mps")}
    r_all = antenna_ecef(truth, np.concatenate([rows - 1, rows, rows + 1]), l_b)
    n = len(rows)
    r_m, r_0, r_p = r_all[:n], r_all[n:2 * n], r_all[2 * n:]
    for i, (t, row) in enumerate(zip(times, rows)):
        dt2 = truth.time[row + 1] - truth.time[row - 1]
        lla = truth.lla[row]
        ids, rp, vp, rho_l, rate_l = [], [], [], [], []
        for k in range(24):
            rho, r_s, v_s = exact_range(t, r_0[i], k)
            d = r_s - r_0[i]
            el = np.arcsin(np.dot(d / np.linalg.norm(d),
                                  earth.dcm_en(lla[0], lla[1])[:, 2]) * -1.0)
            if el < np.deg2rad(mask_deg):
                continue
            rate = (exact_range(truth.time[row + 1], r_p[i], k)[0]
                    - exact_range(truth.time[row - 1], r_m[i], k)[0]) / dt2
            s_r = np.hypot(sigma_rho[0], sigma_rho[1] / np.sin(el))
            s_d = np.hypot(sigma_rate[0], sigma_rate[1] / np.sin(el))
            ids.append(k + 1)
            rp.append(r_s)
            vp.append(v_s)
            rho_l.append(rho + bias[i] + rng.normal(0.0, s_r))
            rate_l.append(rate + drift[i] + rng.normal(0.0, s_d))
        out["sats"].append(np.array(ids, dtype=int))
        out["sat_pos_e"].append(np.array(rp).reshape(-1, 3))
        out["sat_vel_e"].append(np.array(vp).reshape(-1, 3))
        out["range_m"].append(np.array(rho_l))
        out["range_rate_mps"].append(np.array(rate_l))
    names = [[f"G{s:02d}" for s in ids] for ids in out["sats"]]
    return RawEpochs(times, names=names, **out), bias


def spp(epochs, lla0, sigma_rho=(0.3, 0.3)):
    """Loose coupling's input from the same pseudoranges: a weighted least-squares point
    position (Gauss-Newton, Sagnac as the filter's) at every epoch with >= 4 satellites;
    returns a :class:`GnssLog` with the NED covariance."""
    from ins.estimation.coupling.pseudorange import line_of_sight, sagnac_range
    x = np.append(earth.lla_to_ecef(*lla0), 0.0)
    times, llas, covs = [], [], []
    import pymap3d
    for i, t in enumerate(epochs.time):
        r_s, y = epochs.sat_pos_e[i], epochs.range_m[i]
        if len(y) < 4:
            continue
        for _ in range(8):
            lla = np.array(pymap3d.ecef2geodetic(*x[:3], deg=False))
            e_n, el = line_of_sight(r_s, lla)
            C_en = earth.dcm_en(lla[0], lla[1])
            e_e = e_n @ C_en.T
            w = 1.0 / (sigma_rho[0] ** 2 + (sigma_rho[1] / np.sin(el)) ** 2)
            H = np.column_stack([-e_e, np.ones(len(y))])
            z = y - (sagnac_range(r_s, x[:3]) + x[3])
            N = H.T @ (w[:, None] * H)
            dx = np.linalg.solve(N, H.T @ (w * z))
            x = x + dx
            if np.linalg.norm(dx[:3]) < 1e-4:
                break
        Q = np.linalg.inv(N)[:3, :3]
        times.append(t)
        llas.append(np.array(pymap3d.ecef2geodetic(*x[:3], deg=False)))
        covs.append(C_en.T @ Q @ C_en)
    covs = np.array(covs)
    return GnssLog(np.array(times), np.array(llas),
                   np.sqrt(np.einsum("nii->ni", covs)), cov_ned_m2=covs)


def masked(epochs, span, n_keep, lla, choose="spread"):
    """The epochs with only ``n_keep`` satellites inside ``span`` (s), ids fixed over the
    span, chosen among those visible over the whole span (seen from ``lla`` at its
    start): ``"highest"`` the highest ones; ``"spread"`` the set whose horizontal lines
    of sight spread most (largest smallest eigenvalue of ``sum e_h e_h^T``, then the
    largest trace: a mask that leaves satellites in different directions)."""
    import itertools

    from ins.estimation.coupling.pseudorange import line_of_sight
    t0, t1 = span
    inside = (epochs.time >= t0) & (epochs.time <= t1)
    idx = np.flatnonzero(inside)
    common = functools.reduce(np.intersect1d, [epochs.sats[i] for i in idx])
    i0 = int(idx[0])
    e_n, el = line_of_sight(epochs.sat_pos_e[i0], lla)
    sats0 = list(epochs.sats[i0])
    if choose == "highest":
        order = [s for s in epochs.sats[i0][np.argsort(-el)] if s in common]
        keep = np.array(order[:n_keep])
    else:
        def score(c):
            E = np.array([e_n[sats0.index(s), :2] for s in c]).reshape(-1, 2)
            M = E.T @ E
            return (np.linalg.eigvalsh(M)[0], np.trace(M))
        keep = np.array(max(itertools.combinations(common, min(n_keep, len(common))),
                            key=score)) if n_keep else np.array([], int)

    def rule(i, sats):
        return np.isin(sats, keep) if inside[i] else np.ones(len(sats), bool)
    return epochs.select(rule)


# ---------------------------------------------------------------------------------------
# the flight and the runs

TACTICAL = "tactical"


def flight(grade=TACTICAL, seed=3):
    """The simulated flight of tests/test_filter.py's plan with an IMU of ``grade``:
    ``(imu, truth, noise, t0)``."""
    from test_filter import PLAN, given_config, short_flight

    from ins.io import imu_files
    from ins.io.navfiles import read_nav
    folder = short_flight(seed, PLAN.replace('grade = "navigation"', f'grade = "{grade}"'))
    cfg = given_config(folder, varying=False)
    return imu_files.read_imu(cfg.imu), read_nav(cfg.truth), cfg.noise, float(
        cfg.initial["time_s"])


#: Antenna arm in the body frame, m.
L_B = np.array([0.6, 0.25, -1.6])


def run(imu, truth, noise, t_start, t_end, gnss, tight, smooth=False, options=None,
        clock_psd=OCXO):
    """Forward filter (and smoother) from the truth state at ``t_start``: loose with a
    :class:`GnssLog`, tight with :class:`RawEpochs`; returns ``(fwd, states)``."""
    from ins.estimation.core.error_model import StateLayout
    from ins.estimation.core.filter import run_forward
    from ins.estimation.core.filter_settings import FilterSettings
    from ins.estimation.core.lever_arm import LeverArm
    from ins.estimation.coupling.pseudorange import TightUpdater
    from ins.estimation.core.smoother import smooth as rts
    from ins.nav.mechanization import NavState
    r = int(np.searchsorted(truth.time, t_start - 1e-6))
    state = NavState(truth.lla[r], truth.v_n[r], truth.q_nb[r])
    kw = {}
    if tight:
        kw = dict(layout=StateLayout(("clock",)), clock_psd=clock_psd,
                  updater=functools.partial(TightUpdater, options=options))
    settings = FilterSettings(noise=noise, lever=LeverArm(L_B), pos_std_ned_m=[0.5] * 3,
                              vel_std_ned_mps=[0.05] * 3, att_std_deg=[0.05, 0.05, 0.2],
                              use_velocity=False, **kw)
    fwd = run_forward(imu, gnss, state, settings, start=truth.time[r], end=t_end)
    if smooth:
        return fwd, rts(fwd).states
    return fwd, fwd.states


def horizontal_error(fwd_time, states, truth, t):
    """Horizontal position error (m) of the solution at the epoch nearest ``t``."""
    i = int(np.argmin(np.abs(fwd_time - t)))
    j = int(np.argmin(np.abs(truth.time - fwd_time[i])))
    d = earth.ned_offset(truth.lla[j], states[i, :3])
    return float(np.hypot(d[0], d[1]))
