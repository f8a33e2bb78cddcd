"""GNSS log reader and writer: round trip, velocity columns, line-naming errors."""
import numpy as np
import pytest

from ins.common.errors import InputError
from ins.io.gnss import read_gnss, write_gnss
from ins.io.gnss_log import GnssLog

LINES = ["300001.000 30.440548159583 114.470002215064 1001.76681 0.020 0.020 0.050",
         "300002.000 30.441088797341 114.470001933699 1001.63390 0.020 0.020 0.050",
         "300003.000 30.441630070390 114.470002034576 1001.55790 0.020 0.030 0.050"]


def write(tmp_path, lines, name="gnss.txt"):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_read_kfgins_layout(tmp_path):
    log = read_gnss(write(tmp_path, ["# comment"] + LINES))
    assert len(log) == 3 and not log.has_velocity
    np.testing.assert_allclose(np.rad2deg(log.lla[0, :2]), [30.440548159583, 114.470002215064],
                               rtol=0, atol=1e-12)
    assert log.lla[2, 2] == 1001.55790
    np.testing.assert_array_equal(log.sigma_ned_m[2], [0.02, 0.03, 0.05])
    assert list(log.line) == [2, 3, 4]


def test_round_trip_with_velocity(tmp_path):
    rng = np.random.default_rng(0)
    n = 5
    log = GnssLog(np.arange(n) + 0.25, np.column_stack([np.deg2rad(30 + rng.random(n)),
                                                         np.deg2rad(114 + rng.random(n)),
                                                         1000 + rng.random(n)]),
                  np.full((n, 3), 0.02), rng.normal(0, 50, (n, 3)), np.full((n, 3), 0.01))
    p = tmp_path / "g.txt"
    assert write_gnss(p, log) == n
    back = read_gnss(p)
    assert back.has_velocity
    np.testing.assert_allclose(back.time, log.time)
    np.testing.assert_allclose(back.lla[:, :2], log.lla[:, :2], atol=1e-13)
    np.testing.assert_allclose(back.v_n, log.v_n, atol=1e-6)


@pytest.mark.parametrize("line, pattern", [
    ("300004.000 30.44 114.47 1001.0 0.000 0.020 0.050", r"gnss.txt:4: std_n_m = 0.0"),
    ("300004.000 30.44 114.47 1001.0 0.020 0.020 -0.05", r"gnss.txt:4: std_d_m = -0.05"),
    ("300003.000 30.44 114.47 1001.0 0.020 0.020 0.050", r"gnss.txt:4: duplicated epoch"),
    ("300004.000 95.0 114.47 1001.0 0.020 0.020 0.050", r"gnss.txt:4: latitude"),
    ("300004.000 30.44 114.47 1001.0 0.020 0.020", r"gnss.txt:4"),
    ("300004.000 30.44 114.47 1001.0 0.02 0.02 0.05 1 2 3 0.1 0.1 0", r"gnss.txt:4"),
])
def test_bad_lines_are_named(tmp_path, line, pattern):
    with pytest.raises(InputError, match=pattern):
        read_gnss(write(tmp_path, LINES + [line]))


def test_zero_velocity_sigma(tmp_path):
    rows = [ln + " 1 2 3 0.1 0.1 0.1" for ln in LINES]
    rows[1] = LINES[1] + " 1 2 3 0.1 0.0 0.1"
    with pytest.raises(InputError, match=r"gnss.txt:2: std_ve_mps = 0.0"):
        read_gnss(write(tmp_path, rows))


def test_ten_columns_refused(tmp_path):
    with pytest.raises(InputError, match="expected 7"):
        read_gnss(write(tmp_path, [ln + " 1 2 3" for ln in LINES]))
