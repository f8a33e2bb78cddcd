"""RTS smoother: the closed-loop formulation against filterpy's open-loop smoother on a
linear system, and the accuracy on the shared benchmark flight against the peers."""
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from ins.estimation.core.smoother import rts_errors


def test_closed_loop_rts_equals_open_loop_rts():
    """For a linear system the closed-loop filter (nominal corrected, error reset) and the
    open-loop filter are the same estimator; our RTS on the error states must reproduce
    filterpy's rts_smoother exactly."""
    rng = np.random.default_rng(4)
    n, m = 4, 60
    dt = 1.0
    F = np.eye(n) + np.diag([dt, 0.0, dt], 1)
    F[3, 3] = 0.99
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    Q = np.diag([1e-4, 1e-3, 1e-4, 1e-5])
    R = np.diag([0.5, 0.3])
    x_true = np.zeros(n)
    zs = []
    for _ in range(m):
        x_true = F @ x_true + rng.multivariate_normal(np.zeros(n), Q)
        zs.append(H @ x_true + rng.multivariate_normal(np.zeros(2), R))
    P0 = np.eye(n)
    x0 = np.array([0.5, -0.2, 0.1, 0.0])
    # open loop: filterpy
    kf = KalmanFilter(dim_x=n, dim_z=2)
    kf.x, kf.P, kf.F, kf.H, kf.Q, kf.R = x0.copy(), P0.copy(), F, H, Q, R
    xs, Ps = [x0.copy()], [P0.copy()]
    for z in zs:
        kf.predict()
        kf.update(z)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    xs_open, Ps_open, _, _ = kf.rts_smoother(np.array(xs), np.array(Ps),
                                              Fs=[F] * (m + 1), Qs=[Q] * (m + 1))
    # closed loop: the nominal carries the estimate, the filter the error (est - true)
    nominal = [x0.copy()]
    P = P0.copy()
    rec = SimpleNamespace(P_prior=[P0], P_post=[P0], Phi=[np.eye(n)], dx=[np.zeros(n)])
    for z in zs:
        nom = F @ nominal[-1]
        P = F @ P @ F.T + Q
        rec.P_prior.append(P)
        rec.Phi.append(F)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        dx = K @ (H @ nom - z)                     # estimated error of the nominal
        P = (np.eye(n) - K @ H) @ P
        nominal.append(nom - dx)
        rec.P_post.append(P)
        rec.dx.append(dx)
    rec = SimpleNamespace(**{k: np.array(v) for k, v in vars(rec).items()},
                          node_rows=np.arange(m + 1))
    err, Ps_closed = rts_errors(rec)
    np.testing.assert_allclose(np.array(nominal), np.array(xs), atol=1e-12)
    np.testing.assert_allclose(np.array(nominal) - err, xs_open, atol=1e-10)
    np.testing.assert_allclose(Ps_closed, Ps_open, atol=1e-10)


@pytest.fixture(scope="module")
def bench_runs(bench_data):
    sys.path.insert(0, str(bench_data.parents[1] / "bench"))
    from bench_process import config_for, frame, report
    from benchdata import SHARED
    sys.path.insert(0, str(SHARED / "bench" / "ins"))
    import peerlib

    from ins.estimation.pipeline.process import process
    truth = peerlib.load_nav(str(bench_data / "truth.nav"))
    out = {}
    for name in ("gnss.txt", "gnss_outage.txt"):
        cfg, meta = config_for(bench_data, name)
        res = process(cfg)
        out[name] = {k: report(peerlib, truth, meta, k, frame(peerlib, tr))
                     for k, tr in (("forward", res.forward), ("smoothed", res.smoothed))}
    return out


KFGINS_POS = (0.0104, 0.0096, 0.0183)
KFGINS_ATT = (4.1, 4.4, 107.0)
KFGINS_OUTAGE = (0.087, 0.374, 0.469)


def _rms(rep, kind, comps):
    return np.array([rep["rep"][f"{kind}_{c}"]["rms"] for c in comps])


def test_forward_no_worse_than_kfgins(bench_runs):
    fwd = bench_runs["gnss.txt"]["forward"]
    pos = _rms(fwd, "pos", ("north_m", "east_m", "down_m"))
    att = _rms(fwd, "att", ("roll_arcsec", "pitch_arcsec", "heading_arcsec"))
    # the README's figures are rounded: allow the rounding half-unit
    assert np.all(pos <= np.array(KFGINS_POS) + 5e-5), pos
    assert np.all(att <= np.array(KFGINS_ATT) + 0.05), att
    out = bench_runs["gnss_outage.txt"]["forward"]["outages"]
    ends = np.array([o["end_horizontal_m"] for o in out])
    assert np.all(ends <= np.array(KFGINS_OUTAGE) + 5e-4), ends


def test_smoothed_better_in_every_component(bench_runs):
    for name in ("gnss.txt", "gnss_outage.txt"):
        f, s = bench_runs[name]["forward"], bench_runs[name]["smoothed"]
        for kind, comps in (("pos", ("north_m", "east_m", "down_m")),
                            ("att", ("roll_arcsec", "pitch_arcsec", "heading_arcsec")),
                            ("vel", ("VN_mps", "VE_mps", "VD_mps"))):
            assert np.all(_rms(s, kind, comps) < _rms(f, kind, comps)), (name, kind)
        # heading over the WHOLE flight, including before the first turn
        assert s["whole"]["att_heading_arcsec"]["rms"] < 20.0
    s_out = bench_runs["gnss_outage.txt"]["smoothed"]["outages"]
    f_out = bench_runs["gnss_outage.txt"]["forward"]["outages"]
    for so, fo in zip(s_out, f_out):
        assert so["end_horizontal_m"] < 0.25 * fo["end_horizontal_m"]
        assert so["max_horizontal_m"] < 0.05


# --- numerical red flags: a failure names the node time and the state ----------------

def _chain(m=5, n=21, seed=0):
    """A consistent closed-loop record of ``m`` nodes (random walk, direct observation):
    the quantities rts_errors needs, with node times 100, 101, ... s."""
    rng = np.random.default_rng(seed)
    Q = np.diag(rng.uniform(0.5, 2.0, n)) * 1e-2
    R = np.eye(n) * 0.1
    P = np.eye(n)
    rec = SimpleNamespace(P_prior=[P], P_post=[P], Phi=[np.eye(n)], dx=[np.zeros(n)])
    for _ in range(m - 1):
        Pp = P + Q
        P = Pp - Pp @ np.linalg.inv(Pp + R) @ Pp
        rec.P_prior.append(Pp)
        rec.P_post.append(P)
        rec.Phi.append(np.eye(n))
        rec.dx.append(rng.normal(0, 0.1, n))
    out = SimpleNamespace(**{k: np.array(v) for k, v in vars(rec).items()})
    out.node_time = 100.0 + np.arange(m)
    return out


def test_smoother_cholesky_failure_names_the_node_time():
    from ins.common.errors import QualityError
    rec = _chain()
    rts_errors(rec)                                       # consistent: no error
    good = rec.P_prior.copy()
    bad = good.copy()
    bad[3, 4, 4] = -1e-3                                  # prior of node 3 (t = 103 s)
    rec.P_prior = bad
    with pytest.raises(QualityError, match=r"prior covariance at t = 103\.000 s is not "
                                           r"positive definite \(variance -1\.000e-03 for "
                                           r"state vel_E"):
        rts_errors(rec)
    # indefinite with a positive diagonal: the correlation's eigenvalue is named
    bad = good.copy()
    bad[2, 0, 1] = bad[2, 1, 0] = 1.5 * np.sqrt(bad[2, 0, 0] * bad[2, 1, 1])
    rec.P_prior = bad
    with pytest.raises(QualityError, match=r"t = 102\.000 s .*smallest eigenvalue"):
        rts_errors(rec)


def test_negative_smoothed_variance_is_a_failure_not_a_zero_sigma():
    """An inconsistent record (a prior smaller than the posterior it was predicted
    from) drives a smoothed variance negative: P+ + A (Ps - P-) A^T with A = P+ / P- =
    10 and Ps - P- = -0.09 gives 1 - 9 < 0.  Raised naming the time and the state (it
    used to print as sigma 0)."""
    from ins.common.errors import QualityError
    n = 21
    rec = SimpleNamespace(P_prior=np.array([np.eye(n), 0.1 * np.eye(n)]),
                          P_post=np.array([np.eye(n), 0.01 * np.eye(n)]),
                          Phi=np.array([np.eye(n), np.eye(n)]), dx=np.zeros((2, n)),
                          node_time=np.array([5.0, 6.0]))
    with pytest.raises(QualityError, match=r"at t = 5\.000 s: the smoothed covariance has "
                                           r"variance -8\.000e\+00 for state pos_N"):
        rts_errors(rec, full=False)
    # rounding-level negatives are not failures: -1e-12 of the scale gives sigma 0
    from ins.estimation.core.error_model import checked_std
    np.testing.assert_array_equal(checked_std([-1e-12, 4.0], [1.0, 4.0]), [0.0, 2.0])


@pytest.mark.slow
def test_smoothed_constant_sensor_errors_are_constant_and_match_the_truth():
    """The short test flight with constant sensor errors only (the navigation preset's
    biases and scale factors, no bias instability: the manifest's values are the
    truth at every epoch) and the filter's constant sensor model (no driving noise):
    the RTS smoother, through the feedback resets, gives one value per sensor state
    for the whole flight (the smoothed estimate of a constant), within 3 sigma of the
    injected value, and has learnt something (four sigmas below half their prior: the accelerometer biases
    and scale factors of this gentle navigation-grade flight)."""
    from pathlib import Path

    import tomllib
    from test_filter import PLAN, given_config, short_flight

    from ins.estimation.pipeline.process import process
    plan = PLAN.replace('grade = "navigation"\n', 'grade = "navigation"\n'
                        'gyro_bias_instability_dph = 0.0\n'
                        'accel_bias_instability_mgal = 0.0\n')
    assert plan != PLAN
    folder = short_flight(seed=5, plan=plan)
    man = tomllib.loads((Path(folder) / "manifest.toml").read_text())["imu"]
    cfg = given_config(folder)
    assert cfg.noise.constant_sensors and np.all(cfg.noise.q_continuous()[6:] == 0.0)
    res = process(cfg)
    dph, mgal, ppm = np.pi / 180 / 3600, 1e-5, 1e-6
    truth = np.concatenate([np.array(man["gyro_bias_dph"]) * dph,
                            np.array(man["accel_bias_mgal"]) * mgal,
                            np.array(man["gyro_scale_ppm"]) * ppm,
                            np.array(man["accel_scale_ppm"]) * ppm])
    est = res.smoothed_sensors[:, :12]
    std = res.smoothed_std[:, 9:21]
    np.testing.assert_allclose(est, np.broadcast_to(est[0], est.shape),
                               rtol=0, atol=1e-6 * float(np.min(std)))
    np.testing.assert_allclose(std, np.broadcast_to(std[0], std.shape), rtol=1e-6)
    z = (est[0] - truth) / std[0]
    assert np.all(np.abs(z) < 3.0), z
    ratio = std[0] / cfg.noise.sensor_std       # 1 for a state that learns nothing
    assert np.sum(ratio < 0.5) >= 4, ratio
