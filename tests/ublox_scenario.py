"""What a u-blox receiver on a patch antenna shows, over the synthetic constellation of
tests/tight_scenario.py (test scaffolding, not library code; used by
tests/test_range_noise.py and bench/bench_robust_gnss.py).

Errors added to the exact ranges and range rates, per satellite:

* C/N0 = ``CN0_HORIZON + (CN0_ZENITH - CN0_HORIZON) sin el`` plus a slow fade (first-order
  Gauss-Markov, ``FADE_DBHZ`` standard deviation, ``FADE_TIME_S``): a body, a roof, a
  tree between the antenna and the satellite;
* code: multipath (Gauss-Markov, ``MULTIPATH_TIME_S``, standard deviation
  ``MULTIPATH_M / sin el``) plus white noise ``sqrt(0.3^2 + CN0_CODE_M^2 10^(-(C/N0 -
  45)/10))``;
* Doppler: white ``sqrt(0.02^2 + CN0_RATE_MPS^2 10^(-(C/N0 - 45)/10))`` m/s;
* blunders: with probability ``OUTLIER_RATE`` per epoch on a satellite below
  ``OUTLIER_CN0_DBHZ`` a reflection is locked onto: 10-50 m of either sign on the code
  for 1 to ``OUTLIER_MAX_S`` seconds (one value per episode); on its own, with the same
  probability, 0.5-3 m/s on one range rate.

The truth clock and geometry are tight_scenario's (the receiver clock a TCXO here).
"""
import numpy as np
import tight_scenario as ts

from ins.estimation.coupling.pseudorange import CLIGHT, line_of_sight

CN0_HORIZON, CN0_ZENITH = 30.0, 48.0
FADE_DBHZ, FADE_TIME_S = 4.0, 20.0
MULTIPATH_M, MULTIPATH_TIME_S = 1.0, 30.0
CN0_CODE_M, CN0_RATE_MPS = 1.5, 0.08
OUTLIER_RATE, OUTLIER_CN0_DBHZ, OUTLIER_MAX_S = 0.05, 36.0, 8

#: A TCXO's clock noise, m^2/s and m^2/s^3 (pseudorange.CLOCKS["tcxo"]).
TCXO = (0.5 * CLIGHT ** 2 * 2e-19, 2 * np.pi ** 2 * CLIGHT ** 2 * 2e-20)


def _gm(n, dt, tau, rng):
    """Unit-variance first-order Gauss-Markov samples."""
    phi = np.exp(-dt / tau)
    x = np.empty(n)
    x[0] = rng.normal()
    w = rng.normal(size=n) * np.sqrt(1 - phi ** 2)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + w[k]
    return x


def make_ublox_epochs(truth, times, l_b, seed=0, outlier_rate=OUTLIER_RATE):
    """:class:`RawEpochs` with u-blox-like errors (module notes) and C/N0; returns
    ``(epochs, clock_bias_m, errors)`` with ``errors[k]`` the code errors of epoch
    ``k``, m."""
    clean, bias = ts.make_epochs(truth, times, l_b, seed=seed, sigma_rho=(0.0, 0.0),
                                 sigma_rate=(0.0, 0.0), clock_psd=TCXO)
    rng = np.random.default_rng(seed + 1000)
    n, dt = len(times), float(np.median(np.diff(times)))
    rows = np.searchsorted(truth.time, times - 1e-6)
    fade = {s: _gm(n, dt, FADE_TIME_S, rng) * FADE_DBHZ for s in range(1, 25)}
    mp = {s: _gm(n, dt, MULTIPATH_TIME_S, rng) * MULTIPATH_M for s in range(1, 25)}
    snr, rng_m, rate, errs = [], [], [], []
    burst = {}                         # satellite -> (epochs left, code error m)
    for k in range(n):
        _, el = line_of_sight(clean.sat_pos_e[k], truth.lla[rows[k]])
        sats = clean.sats[k]
        s_el = np.sin(np.maximum(el, 1e-3))
        cn0 = (CN0_HORIZON + (CN0_ZENITH - CN0_HORIZON) * s_el
               + np.array([fade[s][k] for s in sats]))
        g = 10.0 ** (-0.1 * (cn0 - 45.0))
        e_code = (np.array([mp[s][k] for s in sats]) / s_el
                  + rng.normal(size=len(sats)) * np.sqrt(0.3 ** 2 + CN0_CODE_M ** 2 * g))
        e_rate = rng.normal(size=len(sats)) * np.sqrt(0.02 ** 2 + CN0_RATE_MPS ** 2 * g)
        weak = cn0 < OUTLIER_CN0_DBHZ
        hit = weak & (rng.random(len(sats)) < outlier_rate)
        for j in np.flatnonzero(hit):
            if burst.get(sats[j], (0, 0.0))[0] <= 0:
                burst[sats[j]] = (int(rng.integers(1, OUTLIER_MAX_S + 1)),
                                  rng.choice([-1, 1]) * rng.uniform(10, 50))
        for j, sat in enumerate(sats):
            left, size = burst.get(sat, (0, 0.0))
            if left > 0:
                e_code[j] += size
                burst[sat] = (left - 1, size)
        hit = weak & (rng.random(len(sats)) < outlier_rate)
        e_rate[hit] += rng.choice([-1, 1], hit.sum()) * rng.uniform(0.5, 3.0, hit.sum())
        snr.append(np.round(cn0, 2))
        rng_m.append(clean.range_m[k] + e_code)
        rate.append(clean.range_rate_mps[k] + e_rate)
        errs.append(e_code)
    clean.range_m, clean.range_rate_mps, clean.snr_dbhz = rng_m, rate, snr
    return clean, bias, errs


def spp_fde(epochs, lla0, sigma_rho=(1.0, 1.0), probability=1e-3):
    """Loose coupling's input as RTKLIB's single point gives it: weighted least squares
    with fault detection and exclusion (while the sum of squared normalized residuals
    fails the chi-square test at ``probability``, the satellite with the largest is
    dropped, down to 5), the covariance from the weights; epochs with fewer than 4
    satellites give no fix."""
    import pymap3d
    from scipy.stats import chi2

    from ins.estimation.coupling.pseudorange import sagnac_range
    from ins.io.gnss_log import GnssLog
    from ins.nav import earth
    x = np.append(earth.lla_to_ecef(*lla0), 0.0)
    times, llas, covs = [], [], []
    for i, t in enumerate(epochs.time):
        r_s, y = np.asarray(epochs.sat_pos_e[i]), np.asarray(epochs.range_m[i])
        keep = np.ones(len(y), bool)
        if len(y) < 4:
            continue
        while True:
            for _ in range(10):
                lla = np.array(pymap3d.ecef2geodetic(*x[:3], deg=False))
                e_n, el = line_of_sight(r_s, lla)
                C_en = earth.dcm_en(lla[0], lla[1])
                e_e = e_n @ C_en.T
                w = 1.0 / (sigma_rho[0] ** 2 + (sigma_rho[1] / np.sin(el)) ** 2)
                H = np.column_stack([-e_e, np.ones(len(y))])
                v = y - (sagnac_range(r_s, x[:3]) + x[3])
                N = H[keep].T @ (w[keep, None] * H[keep])
                dx = np.linalg.solve(N, H[keep].T @ (w[keep] * v[keep]))
                x = x + dx
                if np.linalg.norm(dx[:3]) < 1e-4:
                    break
            v = y - (sagnac_range(r_s, x[:3]) + x[3])
            m = keep.sum()
            q = w * v * v
            if m <= 4 or np.sum(q[keep]) <= chi2.isf(probability, m - 4) or m <= 5:
                break
            keep[np.flatnonzero(keep)[np.argmax(q[keep])]] = False
        if keep.sum() < 4:
            continue
        Q = np.linalg.inv(N)[:3, :3]
        times.append(t)
        llas.append(np.array(pymap3d.ecef2geodetic(*x[:3], deg=False)))
        covs.append(C_en.T @ Q @ C_en)
    covs = np.array(covs)
    return GnssLog(np.array(times), np.array(llas),
                   np.sqrt(np.einsum("nii->ni", covs)), cov_ned_m2=covs)
