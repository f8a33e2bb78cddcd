"""The covariance screen of RTKLIB .pos solutions (ins.io.pos_screen), on hand-written
files whose rows are valid covariances, not one (sdn 0 beside sdne -0.43 m, as RTKLIB
demo5 2.5.0 writes with pos1-dynamics on) or out of all proportion (sde 41 m)."""
import warnings

import numpy as np
import pytest

from ins.common.errors import InputError, InputWarning
from ins.io.pos_screen import RATIO, invalid_covariance, screen
from ins.io.rtklib import read_pos

HEAD = ("% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp)\n"
        "%  GPST          latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)"
        "   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n")


def _row(k, q, sig):
    return (f"1316 {518400 + 30 * k:.3f}   35.160875019  139.613838552    70.2721   {q}   7 "
            + " ".join(f"{v:8.4f}" for v in sig) + "   0.00  223.0\n")


def _write(path, rows):
    path.write_text(HEAD + "".join(_row(k, q, s) for k, (q, s) in enumerate(rows)))
    return path


VALID = (0.0050, 0.0040, 0.0120, 0.0010, -0.0020, 0.0030)


def test_valid_rows_pass_unchanged(tmp_path):
    f = _write(tmp_path / "ok.pos", [(1, VALID)] * 6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        log = read_pos(f)
    assert len(log) == 6 and not log.screen
    # sdn^2 on the north diagonal, sdne |sdne| between north and east
    assert log.cov_ned_m2[0, 0, 0] == pytest.approx(0.005 ** 2)
    assert log.cov_ned_m2[0, 0, 1] == pytest.approx(0.001 ** 2)


def test_invalid_row_repaired_and_absurd_row_dropped(tmp_path):
    bad = (0.0000, 0.7307, 0.3348, -0.4266, -0.3630, 0.6530)     # line 13 of the pair
    huge = (0.0060, 41.5777, 0.0150, 0.0, 0.0, 0.0)              # valid, but 41 m on a fix
    rows = [(1, VALID)] * 4 + [(1, bad), (1, huge), (1, VALID)]
    f = _write(tmp_path / "bad.pos", rows)
    with pytest.warns(InputWarning, match=r"bad\.pos.*1 record.*not a covariance \(lines 7\)"
                                          r".*1 record.*dropped.*lines 8"):
        log = read_pos(f)
    assert len(log) == 6                                        # the 41 m row dropped
    assert log.screen.repaired_lines.tolist() == [7]
    assert log.screen.dropped_lines.tolist() == [8]
    k = list(log.line).index(7)
    cov = log.cov_ned_m2[k]
    # rule: off-diagonal dropped, each variance at least its quality's median (the
    # valid rows': sdn 0.005), the printed ones kept where larger (sde 0.7307)
    assert np.allclose(cov - np.diag(np.diag(cov)), 0.0)
    assert np.sqrt(cov[0, 0]) == pytest.approx(0.005, abs=1e-9)
    assert np.sqrt(cov[1, 1]) == pytest.approx(0.7307, abs=1e-9)
    assert np.sqrt(cov[2, 2]) == pytest.approx(0.3348, abs=1e-9)
    assert np.all(np.linalg.eigvalsh(log.cov_ned_m2) > 0)


def test_unscreened_read_keeps_every_row(tmp_path):
    bad = (0.0000, 0.7307, 0.3348, -0.4266, -0.3630, 0.6530)
    f = _write(tmp_path / "bad.pos", [(1, VALID)] * 3 + [(1, bad)])
    log = read_pos(f, screen_covariance=False)
    assert len(log) == 4 and log.screen is None


def test_invalid_rows_without_peers_are_dropped(tmp_path):
    bad = (0.0000, 0.7307, 0.3348, -0.4266, -0.3630, 0.6530)
    f = _write(tmp_path / "float.pos", [(1, VALID)] * 3 + [(2, bad), (2, VALID)])
    with pytest.warns(InputWarning, match="no valid peer"):
        log = read_pos(f)
    assert log.line.tolist() == [3, 4, 5, 7]


def test_every_row_invalid_is_an_error(tmp_path):
    bad = (0.0000, 0.7307, 0.3348, -0.4266, -0.3630, 0.6530)
    f = _write(tmp_path / "all.pos", [(1, bad)] * 4)
    with pytest.raises(InputError, match="no record left"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_pos(f)


def test_rounding_of_valid_covariances_is_never_flagged():
    """Valid covariances down to a correlation of 0.999 and sigmas at the printing's
    resolution, printed as RTKLIB prints them (4 decimals of the signed roots)."""
    rng = np.random.default_rng(1)
    n = 20000
    a = rng.normal(size=(n, 3, 3)) * rng.uniform(1e-4, 0.05, size=(n, 1, 1))
    cov = a @ np.swapaxes(a, 1, 2)
    cov[::3] += np.eye(3) * 1e-10                 # nearly singular ones too
    roots = np.round(np.sign(cov) * np.sqrt(np.abs(cov)), 4)
    printed = roots * np.abs(roots)
    assert not invalid_covariance(printed).any()
    # and the pair's printed row is caught
    s = np.array([[0.7307, -0.4266, -0.3630], [-0.4266, 0.0, 0.6530], [-0.3630, 0.6530, 0.3348]])
    assert invalid_covariance((s * np.abs(s))[None]).all()


def test_ratio_rule_is_per_quality():
    """A float epoch 50 times a fix's sigma is not out of proportion: floats are compared
    with floats."""
    idx = np.arange(3)
    q = np.array([1] * 5 + [2] * 4)
    sig = np.array([0.005] * 5 + [0.25, 0.3, 0.4, 0.3])
    cov = np.zeros((9, 3, 3))
    cov[:, idx, idx] = (sig ** 2)[:, None]
    _, keep, report = screen(cov, q, np.arange(9) + 1)
    assert keep.all() and not report
    cov[2, idx, idx] = (0.005 * RATIO * 1.1) ** 2
    _, keep, report = screen(cov, q, np.arange(9) + 1)
    assert keep.tolist() == [True, True, False] + [True] * 6
