"""`ins allan` on a simulated static MEMS IMU with a large gyro bias (issue 24): not
refused; the IEEE 952 coefficients fitted within their intervals of the simulated truth;
a slow tilt and a turn about the vertical still refused; the Allan deviation against
allantools (an independent implementation, used only as an oracle)."""
import numpy as np
import pytest

from ins.cli.main import main
from ins.estimation.alignment.static_check import static_check
from ins.estimation.tools.allan import TERMS, allan_deviation, fit_noise_model
from ins.io.imu_files import write_kfgins_text
from ins.nav import earth
from ins.nav.imu import ImuLog
from ins.nav.rotation import euler_to_dcm

DT = 0.01
DEG = np.pi / 180.0
#: Truths per sensor (rate units: rad/s, m/s^2): N dominates tau < 3 s, B 3 .. 100 s,
#: K beyond 100 s (crossings of N/sqrt(tau), 0.664 B and K sqrt(tau/3)).
N_G = 0.3 * DEG / 60                     # 0.3 deg/sqrt(h)
B_G = N_G / np.sqrt(3.0) / 0.664         # 15.7 deg/h
K_G = 0.664 * B_G / np.sqrt(100.0 / 3)   # 94 deg/h/sqrt(h)
N_A = 0.06 / 60                          # 0.06 m/s/sqrt(h)
B_A = N_A / np.sqrt(3.0) / 0.664         # 87 mGal
K_A = 0.664 * B_A / np.sqrt(100.0 / 3)
GYRO_BIAS = np.array([0.7, -0.7, 0.7]) * DEG      # rad/s: ADIS16405 class
ACCEL_BIAS = np.array([0.08, -0.05, 0.06])        # m/s^2


def _flicker(rng, n, h):
    """Rate noise of one-sided PSD h / f (frequency-domain shaping of white noise over
    twice the length, so that the record does not wrap): Allan variance 2 ln2 h."""
    w = np.fft.rfft(rng.standard_normal(2 * n))
    f = np.fft.rfftfreq(2 * n, DT)
    f[0] = np.inf
    return np.fft.irfft(w * np.sqrt(h / f / (2 * DT)), 2 * n)[:n]


def _noise(rng, n, N, B, K):
    """White (N) + flicker (B, IEEE 952: Allan variance (2 ln2/pi) B^2) + rate random
    walk (K), a rate series."""
    return (N / np.sqrt(DT) * rng.standard_normal(n) + _flicker(rng, n, B ** 2 / np.pi)
            + np.cumsum(K * np.sqrt(DT) * rng.standard_normal(n)))


def mems_static(duration_s, seed, tilt_deg=0.0, turn=None, rpy_deg=(2.0, -3.0, 40.0)):
    """A static MEMS log (Earth rate, gravity, the biases above, the noise above on
    every axis) at 100 Hz; ``tilt_deg``: the body turns steadily by this angle about its
    x axis over the log; ``turn`` = (t0, t1, angle_deg): a turn about the vertical."""
    rng = np.random.default_rng(seed)
    n = int(round(duration_s / DT))
    t = (np.arange(n) + 1) * DT
    lat = 0.6
    C_bn0 = euler_to_dcm(np.deg2rad(rpy_deg)).T
    w_ie_n = earth.OMEGA_IE * np.array([np.cos(lat), 0.0, -np.sin(lat)])
    f_n = np.array([0.0, 0.0, -9.80])
    w_b = np.tile(C_bn0 @ w_ie_n, (n, 1))
    f_b = np.tile(C_bn0 @ f_n, (n, 1))
    if tilt_deg:
        a = np.deg2rad(tilt_deg) * (t - DT / 2) / duration_s
        c, s = np.cos(a), np.sin(a)
        f0 = f_b[0].copy()              # v_b = Rx(a)^T v_b0
        f_b[:, 1], f_b[:, 2] = c * f0[1] + s * f0[2], -s * f0[1] + c * f0[2]
        w_b[:, 0] += np.deg2rad(tilt_deg) / duration_s
    if turn is not None:
        t0, t1, ang = turn
        w_b[(t > t0) & (t <= t1)] += C_bn0[:, 2] * np.deg2rad(ang) / (t1 - t0)
    gyro = w_b + GYRO_BIAS + np.column_stack([_noise(rng, n, N_G, B_G, K_G) for _ in range(3)])
    acc = f_b + ACCEL_BIAS + np.column_stack([_noise(rng, n, N_A, B_A, K_A) for _ in range(3)])
    return ImuLog(t, gyro * DT, acc * DT)


@pytest.fixture(scope="module")
def two_hours():
    return mems_static(7200.0, seed=3)


def test_mems_with_large_gyro_bias_is_static(two_hours):
    log = two_hours
    check = static_check(log.time, log.dtheta_b, log.dvel_b)
    assert check.static, check.reasons
    assert check.mean_rate > np.deg2rad(1.1)          # the bias: 1.2 deg/s in all
    # gravity's direction wanders with the accelerometers' flicker and random walk
    assert check.tilt < np.deg2rad(0.15)


def test_fitted_coefficients_cover_the_truth(two_hours):
    """Each of the 30 coefficients (Q, N, B, K, R x 6 axes) within its 99.7 % interval
    of the truth, and at most 5 outside the 95 % ones (P < 1 % with honest intervals);
    the central values of N, B within 1 %, 8 % of the truth."""
    log = two_hours
    fits = [fit_noise_model(log.dtheta_b, DT), fit_noise_model(log.dvel_b, DT)]
    truths = [np.array([0.0, N_G, B_G, K_G, 0.0]), np.array([0.0, N_A, B_A, K_A, 0.0])]
    out95 = 0
    for fit, truth in zip(fits, truths):
        lo3, hi3 = fit.interval(3.0)
        for i in range(3):
            for j, term in enumerate(TERMS):
                assert lo3[j, i] <= truth[j] <= hi3[j, i], (term, i, fit.value[:, i], truth)
                out95 += not fit.lo[j, i] <= truth[j] <= fit.hi[j, i]
        assert np.allclose(fit.N, truth[1], rtol=0.01)
        assert np.allclose(fit.B, truth[2], rtol=0.08)
        assert np.all(fit.chi2 < 3.0)
    assert out95 <= 5


def test_slow_tilt_is_refused():
    """1 deg about a horizontal axis over 30 min (0.0006 deg/s, far below the gyro
    noise of any window): refused by gravity's direction."""
    log = mems_static(1800.0, seed=4, tilt_deg=1.0)
    check = static_check(log.time, log.dtheta_b, log.dvel_b)
    assert not check.static
    assert "gravity's direction" in check.reasons[0]
    # between the centres of the first and last 60 s windows: 1 deg * (1 - 1/30)
    assert check.tilt == pytest.approx(np.deg2rad(1.0 - 1 / 30), rel=0.05)
    assert check.spans == []
    # the same log without the tilt is static
    still = mems_static(1800.0, seed=4)
    assert static_check(still.time, still.dtheta_b, still.dvel_b).static


def test_turn_about_the_vertical_is_refused():
    """A turntable: 90 deg about the vertical in 10 s - gravity does not move; the gyro
    sees it against its running median."""
    log = mems_static(900.0, seed=5, turn=(400.0, 410.0, 90.0))
    check = static_check(log.time, log.dtheta_b, log.dvel_b)
    assert not check.static
    assert check.tilt < np.deg2rad(0.15)
    assert len(check.spans) == 1
    a, b = check.spans[0]
    assert 399.0 - 1e-6 <= a <= 400.0 + 1e-6 and 410.0 - 1e-6 <= b <= 411.0 + 1e-6


def test_against_allantools(two_hours):
    """Overlapping Allan deviation of the same rates at the same taus (allantools'
    oadev, frequency data), with the 0.7 deg/s bias in the data."""
    allantools = pytest.importorskip("allantools")
    log = two_hours
    tau, ours = allan_deviation(log.dtheta_b, DT)
    for i in range(3):
        t2, theirs, _, _ = allantools.oadev(log.dtheta_b[:, i] / DT, rate=1 / DT,
                                            data_type="freq", taus=tau)
        assert np.allclose(t2, tau, rtol=1e-12, atol=0)
        assert np.max(np.abs(theirs / ours[:, i] - 1)) < 1e-11


def test_cli_on_mems_log(tmp_path, capsys):
    log = mems_static(1200.0, seed=6)
    path = tmp_path / "imu.txt"
    write_kfgins_text(path, log)
    png = tmp_path / "allan.png"
    assert main(["allan", str(path), "--plot", str(png)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    rows = {line.split()[0] + line.split()[1]: line.split() for line in out.splitlines()
            if line[:2] in ("g ", "a ")}
    assert len(rows) == 6
    for i in "xyz":                  # N value, then its interval "[lo," "hi]"
        n_g, lo, hi = (float(v.strip("[],")) for v in rows["g" + i][5:8])
        assert lo <= 0.3 <= hi and n_g == pytest.approx(0.3, rel=0.03)
        n_a, lo, hi = (float(v.strip("[],")) for v in rows["a" + i][5:8])
        assert lo <= 0.06 <= hi and n_a == pytest.approx(0.06, rel=0.03)
    assert png.stat().st_size > 1000


def test_cli_exit_3_when_the_model_does_not_fit(tmp_path, capsys):
    """A vibration the model lacks (a 2 Hz sinusoid of 0.05 deg/s on the gyro x axis,
    above the white noise at every tau but the first few): the table, the classic
    reading of gyro x (its N not readable: no stretch of slope -1/2; B at the minimum)
    and the plot, then exit 3; --accept-poor exits 0.  (A curve with a readable white
    noise line exits 0: tests/test_allan_drift.py.)"""
    log = mems_static(600.0, seed=7)
    dth = log.dtheta_b.copy()
    dth[:, 0] += np.deg2rad(0.05) * np.sin(2 * np.pi * 2.0 * log.time) * DT
    path = tmp_path / "imu.txt"
    write_kfgins_text(path, ImuLog(log.time, dth, log.dvel_b))
    png = tmp_path / "allan.png"
    assert main(["allan", str(path), "--plot", str(png)]) == 3
    out, err = capsys.readouterr()
    assert "does not describe" in err and "gyro x" in err and "gyro y" not in err
    assert "no stretch of slope -1/2" in err
    lines = out.splitlines()
    assert len(lines) == 13 and png.exists()
    assert lines[9].startswith("the IEEE 952 model does not describe the curve of gyro x ")
    assert lines[11].startswith("gyro x") and "not readable" in lines[11]
    assert main(["allan", str(path), "--accept-poor"]) == 0
