"""Tests of ins.nav.imu: ImuLog, readers/writers, input checks, axes, rates, compensation."""
import math
import os
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ins.common import textparse
from ins.common.errors import InputError, InputWarning
from ins.io import imu_files
from ins.nav import imu
from ins.nav.imu import ImuLog

G = 9.80665


def bits(a):
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def assert_same_log(a, b):
    for name in ("time", "dtheta_b", "dvel_b"):
        np.testing.assert_array_equal(bits(getattr(a, name)), bits(getattr(b, name)), name)


def make_log(n=400, dt=0.005, t0=300000.0, seed=0):
    """A plausible log: gravity reaction on -z (FRD), small rotations, noise."""
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(n) * dt
    dtheta = rng.standard_normal((n, 3)) * 1e-4 * dt
    dvel = (np.array([0.3, -0.1, -G]) + rng.standard_normal((n, 3)) * 0.5) * dt
    return ImuLog(time=t, dtheta_b=dtheta, dvel_b=dvel)


def kfgins_lines(t, a, b, fmt="%.17e"):
    return "".join(" ".join(["%.6f" % ti] + [fmt % v for v in ai] + [fmt % v for v in bi])
                   + "\n" for ti, ai, bi in zip(t, a, b))


GOOD = ("300000.000 1e-6 2e-6 3e-6 1e-3 2e-3 -0.049\n"
        "300000.005 1e-6 2e-6 3e-6 1e-3 2e-3 -0.049\n"
        "300000.010 1e-6 2e-6 3e-6 1e-3 2e-3 -0.049\n"
        "300000.015 1e-6 2e-6 3e-6 1e-3 2e-3 -0.049\n")
ROW = "1e-6 2e-6 3e-6 1e-3 2e-3 -0.049"


@pytest.fixture(params=["compiled", "python"])
def engine(request, monkeypatch):
    """Run a test with the compiled parser and with the pure-Python fallback."""
    if request.param == "python":
        monkeypatch.setattr(textparse, "_use_compiled", lambda: False)
    return request.param


# ----------------------------------------------------------------------------- errors

def test_input_error_format_and_pickle():
    import pickle
    e = InputError("bad thing\nsecond line", path="a/imu.txt", line=17)
    assert str(e) == "a/imu.txt:17: bad thing second line"
    assert isinstance(e, ValueError) and e.reason == "bad thing second line"
    assert str(InputError("x", path="f.bin", record=3)) == "f.bin: record 3: x"
    assert str(InputError("x", path="f.txt")) == "f.txt: x"
    assert str(InputError("x", line=4)) == "line 4: x"
    assert str(InputError("x")) == "x"
    back = pickle.loads(pickle.dumps(e))
    assert (str(back), back.path, back.line) == (str(e), "a/imu.txt", 17)
    assert issubclass(InputWarning, UserWarning)


# ----------------------------------------------------------------------------- ImuLog

def test_imulog_shapes_and_copies():
    t = np.array([0.0, 0.03, 0.04, 0.05, 0.06, 0.08])
    th = np.zeros((6, 3))
    log = ImuLog(t, th, np.ones((6, 3)))
    assert len(log) == 6
    assert log.time is not t and not log.time.flags.writeable
    t[0] = 99.0                                   # the log does not alias its input
    assert log.time[0] == 0.0
    with pytest.raises(ValueError):
        log.dvel_b[0, 0] = 1.0
    with pytest.raises(AttributeError):
        log.time = t
    # dt[0] is the median interval, not the first one
    np.testing.assert_allclose(log.dt, [0.01, 0.03, 0.01, 0.01, 0.01, 0.02], rtol=1e-12)
    assert not log.dt.flags.writeable
    assert log.nominal_dt == pytest.approx(0.01)
    np.testing.assert_array_equal(log.find_gaps(), [1, 5])
    np.testing.assert_array_equal(log.find_gaps(factor=2.5), [1])
    with pytest.raises(ValueError, match=r"dtheta_b must have shape \(6, 3\)"):
        ImuLog(t, np.zeros((6, 2)), np.zeros((6, 3)))
    with pytest.raises(ValueError, match=r"dvel_b must have shape \(6, 3\)"):
        ImuLog(t, np.zeros((6, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"time must have shape \(n,\)"):
        ImuLog(np.zeros((6, 1)), np.zeros((6, 3)), np.zeros((6, 3)))
    with pytest.raises(ValueError, match="array of numbers"):
        ImuLog(t, [["a", "b", "c"]] * 6, np.zeros((6, 3)))
    empty = ImuLog(np.empty(0), np.empty((0, 3)), np.empty((0, 3)))
    assert len(empty) == 0 and empty.dt.size == 0 and math.isnan(empty.nominal_dt)
    assert "n=6" in repr(log)


def test_slice_time_inclusive():
    log = make_log(n=10, dt=1.0, t0=0.0)
    part = log.slice_time(2.0, 5.0)
    np.testing.assert_array_equal(part.time, [2.0, 3.0, 4.0, 5.0])
    np.testing.assert_array_equal(part.dvel_b, log.dvel_b[2:6])
    assert len(log.slice_time(start=8.0)) == 2 and len(log.slice_time(end=0.0)) == 1
    assert len(log.slice_time()) == 10


# ----------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("ext,writer", [(".txt", imu_files.write_kfgins_text),
                                        (".bin", imu_files.write_kfgins_binary),
                                        (".csv", imu_files.write_csv)])
def test_round_trip_bit_exact(tmp_path, engine, ext, writer):
    log = make_log(n=500, dt=0.005)
    path = tmp_path / ("imu" + ext)
    assert writer(path, log) == 500
    back = imu_files.read_imu(path)
    assert_same_log(back, log)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]      # no temporary left


def test_text_writer_layout(tmp_path):
    log = make_log(n=3)
    imu_files.write_kfgins_text(tmp_path / "a.txt", log)
    first = (tmp_path / "a.txt").read_text().splitlines()[0].split()
    assert first[0] == "300000.000" and len(first) == 7
    assert first[1] == "%.17e" % log.dtheta_b[0, 0]
    imu_files.write_csv(tmp_path / "a.csv", log)
    lines = (tmp_path / "a.csv").read_text().splitlines()
    assert lines[0] == ("time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                        "dvel_x_mps,dvel_y_mps,dvel_z_mps")
    # irregular times that no fixed decimals represent are written exactly as well
    t = 1000.0 + np.cumsum(np.full(5, 0.005) + np.arange(5) * 1e-13)
    odd = ImuLog(t, log.dtheta_b[[0, 1, 2, 0, 1]], log.dvel_b[[0, 1, 2, 0, 1]])
    imu_files.write_kfgins_text(tmp_path / "odd.txt", odd)
    assert_same_log(imu_files.read_kfgins_text(tmp_path / "odd.txt"), odd)


def test_format_dispatch(tmp_path):
    log = make_log(n=50)
    imu_files.write_kfgins_binary(tmp_path / "a.imu", log)
    imu_files.write_kfgins_text(tmp_path / "a.dat", log)
    imu_files.write_kfgins_binary(tmp_path / "b.raw", log)
    assert_same_log(imu_files.read_imu(tmp_path / "a.imu"), log)
    assert_same_log(imu_files.read_imu(tmp_path / "a.dat"), log)
    assert_same_log(imu_files.read_imu(tmp_path / "b.raw", format="kfgins-bin"), log)
    with pytest.raises(InputError):              # binary read as text: not numbers
        imu_files.read_imu(tmp_path / "b.raw")
    with pytest.raises(ValueError, match="format must be one of kfgins, kfgins-bin, csv"):
        imu_files.read_imu(tmp_path / "a.dat", format="xls")


def test_writers_are_atomic(tmp_path):
    good = make_log(n=20)
    path = tmp_path / "out.txt"
    imu_files.write_kfgins_text(path, good)
    before = path.read_bytes()
    bad = ImuLog(good.time, np.where(np.arange(20)[:, None] == 7, np.nan, good.dtheta_b),
                 good.dvel_b)
    for writer in (imu_files.write_kfgins_text, imu_files.write_csv, imu_files.write_kfgins_binary):
        with pytest.raises(ValueError, match="row 7"):
            writer(path, bad)
        with pytest.raises(ValueError):
            writer(tmp_path / "new.txt", bad)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]
    with pytest.raises(OSError):
        imu_files.write_kfgins_text(tmp_path / "missing-dir" / "x.txt", good)
    with pytest.raises(TypeError):
        imu_files.write_kfgins_text(path, "not a log")


@settings(max_examples=40, deadline=None)
@given(
    t0=st.floats(-1e8, 1e9),
    steps=hnp.arrays(np.float64, st.integers(2, 30),
                     elements=st.floats(1e-3, 100.0)),
    regular=st.booleans(),
    data=st.data(),
)
def test_text_round_trip_property(tmp_path_factory, t0, steps, regular, data):
    """Any finite, strictly increasing, plausible table reads back bit-equal."""
    n = steps.size
    if regular:          # decimal-looking times, written in fixed point
        t = np.round(t0, 3) + np.arange(n) * 0.005
    else:                # arbitrary doubles, written as %.17e
        t = t0 + np.cumsum(steps)
    if not np.all(np.diff(t) > 0):
        return
    dt_min = float(np.min(np.diff(t)))
    inc = st.floats(-1.0, 1.0, allow_subnormal=True)
    u = data.draw(hnp.arrays(np.float64, (n, 6), elements=inc))
    # magnitudes a real IMU can reach (median |dvel|/dt < 100, |dtheta|/dt < 20)
    dtheta = u[:, :3] * 5.0 * dt_min
    dvel = u[:, 3:] * 30.0 * dt_min
    log = ImuLog(t, dtheta, dvel)
    d = tmp_path_factory.mktemp("prop")
    imu_files.write_kfgins_text(d / "a.txt", log)
    assert_same_log(imu_files.read_kfgins_text(d / "a.txt"), log)
    imu_files.write_csv(d / "a.csv", log)
    assert_same_log(imu_files.read_csv(d / "a.csv"), log)


# ----------------------------------------------------------------------------- bad inputs

TEXT_CASES = [
    # name, content, expected line (None: whole file), text expected in the message
    ("empty", "", None, "no data"),
    ("comments only", "# a\n\n% b\n   \n", None, "no data"),
    ("six columns", "# hdr\n300000.0 1 2 3 4 5\n", 2, "6 columns, expected at least 7"),
    ("short line", GOOD + "300000.020 1e-6 2e-6 3e-6 1e-3 2e-3\n", 5,
     "6 columns, expected 7"),
    ("long line", GOOD + "300000.020 " + ROW + " 7\n", 5, "8 columns, expected 7"),
    ("text in number", "# c\n\n" + GOOD + "300000.020 1e-6 1.2.3 3e-6 1e-3 2e-3 -0.049\n", 7,
     "'1.2.3'"),
    ("word", GOOD.replace("300000.010 1e-6", "300000.010 abc"), 3, "'abc'"),
    ("nan", GOOD.replace("300000.010 1e-6", "300000.010 nan"), 3,
     "non-finite value nan in dtheta_x"),
    ("inf", GOOD.replace("2e-3 -0.049\n300000.015", "inf -0.049\n300000.015"), 3,
     "non-finite value inf in dvel_y"),
    ("backwards", GOOD + "300000.012 " + ROW + "\n", 5,
     "time not increasing: 300000.012 s after 300000.015 s on line 4"),
    ("duplicate", GOOD + "300000.015 " + ROW + "\n", 5,
     "duplicated epoch: time 300000.015 s already on line 4"),
    ("one epoch", "300000.0 " + ROW + "\n", 1, "only one epoch"),
    ("crlf", GOOD.replace("\n", "\r\n") + "300000.020 1e-6 x 3e-6 1e-3 2e-3 -0.049\r\n", 5,
     "'x'"),
    ("empty field", GOOD + "300000.020,1e-6,,3e-6,1e-3,2e-3,-0.049\n", 5, "empty"),
]


@pytest.mark.parametrize("name,content,line,text", TEXT_CASES, ids=[c[0] for c in TEXT_CASES])
def test_text_reader_errors(tmp_path, engine, name, content, line, text):
    path = tmp_path / "bad_imu.txt"
    path.write_bytes(content.encode())
    with pytest.raises(InputError) as e:
        imu_files.read_kfgins_text(path)
    msg = str(e.value)
    assert "\n" not in msg
    assert e.value.path == str(path) and e.value.line == line
    prefix = f"{path}:{line}: " if line is not None else f"{path}: "
    assert msg.startswith(prefix), msg
    assert text in msg, msg


def csv_text(rows=4, header="time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvel_x_mps,"
                            "dvel_y_mps,dvel_z_mps"):
    body = "".join(f"{300000 + k * 0.005:.3f},1e-6,2e-6,3e-6,1e-3,2e-3,-0.049\n"
                   for k in range(rows))
    return header + "\n" + body


CSV_CASES = [
    ("unknown unit", csv_text(header="time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                                     "dvel_x_kmh,dvel_y_mps,dvel_z_mps"), 1,
     "header column 5 'dvel_x_kmh': unknown unit 'kmh'; accepted: dvel_x_mps (m/s)"),
    ("gyro unit", csv_text(header="time_s,gyro_x_rpm,gyro_y_dps,gyro_z_dps,accel_x_mps2,"
                                  "accel_y_mps2,accel_z_mps2"), 1,
     "accepted: gyro_x_radps (rad/s), gyro_x_dps (deg/s), gyro_x_dph (deg/h)"),
    ("time unit", csv_text(header="time_ms,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                                  "dvel_x_mps,dvel_y_mps,dvel_z_mps"), 1,
     "'time_ms': unknown unit 'ms'; accepted: time_s (s)"),
    ("no unit", csv_text(header="time,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                                "dvel_x_mps,dvel_y_mps,dvel_z_mps"), 1, "'time': no unit"),
    ("missing column", "time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvel_x_mps,dvel_y_mps\n"
     "1,2,3,4,5,6\n", 1, "misses column(s) dvel_z_*"),
    ("duplicate column", csv_text(header="time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                                         "dvel_x_mps,dvel_y_mps,dvel_x_mps"), 1,
     "dvel x is already column 5"),
    ("mixed kinds", csv_text(header="time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                                    "accel_x_mps2,accel_y_mps2,accel_z_mps2"), 1, "mixes"),
    ("no header", "300000.0,1,2,3,4,5,6\n300000.1,1,2,3,4,5,6\n", 1, "no header line"),
    ("empty", "", None, "no header line"),
    ("header only", "# comment\n" + csv_text(rows=0), 2, "no data lines after the header"),
    ("short data line", csv_text() + "300000.020,1e-6,2e-6,3e-6,1e-3,2e-3\n", 6,
     "6 columns, expected 7"),
    ("first data line short", csv_text(rows=0) + "300000.020,1e-6,2e-6,3e-6,1e-3,2e-3\n", 2,
     "6 columns, but the header (line 1) names 7"),
    ("text in number", csv_text() + "300000.020,1e-6,2e-6,3e-6,1e-3,2e-3,oops\n", 6,
     "field 7 (dvel_z_mps) is not a number: 'oops'"),
    ("nan", csv_text() + "300000.020,1e-6,2e-6,3e-6,1e-3,NaN,-0.049\n", 6,
     "non-finite value nan in dvel_y_mps"),
    ("duplicate epoch", csv_text() + "300000.015,1e-6,2e-6,3e-6,1e-3,2e-3,-0.049\n", 6,
     "duplicated epoch"),
]


@pytest.mark.parametrize("name,content,line,text", CSV_CASES, ids=[c[0] for c in CSV_CASES])
def test_csv_reader_errors(tmp_path, engine, name, content, line, text):
    path = tmp_path / "bad_imu.csv"
    path.write_bytes(content.encode())
    with pytest.raises(InputError) as e:
        imu_files.read_csv(path)
    msg = str(e.value)
    assert e.value.path == str(path) and e.value.line == line, msg
    assert msg.startswith(f"{path}:{line}: " if line else f"{path}: "), msg
    assert text in msg, msg


def test_csv_rates_argument_must_match_header(tmp_path):
    path = tmp_path / "inc.csv"
    path.write_text(csv_text())
    with pytest.raises(InputError, match="rates=True was asked, but the header names increments"):
        imu_files.read_csv(path, rates=True)
    with pytest.raises(InputError, match="rates=True"):
        imu_files.read_imu(path, rates=True)
    assert len(imu_files.read_csv(path, rates=False)) == 4


def test_csv_header_variants(tmp_path):
    """Comments before the header, quotes, any column order, extra columns, CRLF, BOM."""
    path = tmp_path / "v.csv"
    path.write_bytes(
        b"\xef\xbb\xbf# exported by a logger\r\n"
        b'"temp_c","dvel_z_mps","time_s","dtheta_x_rad","dtheta_y_rad","dtheta_z_rad",'
        b'"dvel_x_mps","dvel_y_mps"\r\n'
        b"20.5,-0.049,300000.000,1e-6,2e-6,3e-6,1e-3,2e-3\r\n"
        b"20.6,-0.048,300000.005,1e-6,2e-6,3e-6,1e-3,2e-3\r\n")
    log = imu_files.read_csv(path)
    np.testing.assert_array_equal(log.time, [300000.0, 300000.005])
    np.testing.assert_array_equal(log.dvel_b[:, 2], [-0.049, -0.048])
    np.testing.assert_array_equal(log.dtheta_b[0], [1e-6, 2e-6, 3e-6])


BIN_ROW = [1e-6, 2e-6, 3e-6, 1e-3, 2e-3, -0.049]


def write_records(path, times, nan_at=None):
    table = np.array([[t] + BIN_ROW for t in times], dtype="<f8")
    if nan_at is not None:
        table[nan_at, 3] = np.nan
    path.write_bytes(table.tobytes())
    return table


def test_binary_reader_errors(tmp_path):
    path = tmp_path / "bad.bin"
    path.write_bytes(b"")
    with pytest.raises(InputError, match="empty file") as e:
        imu_files.read_kfgins_binary(path)
    assert str(e.value).startswith(f"{path}: ")
    table = write_records(path, [0.0, 0.005, 0.01])
    path.write_bytes(table.tobytes() + b"\0" * 20)
    with pytest.raises(InputError) as e:
        imu_files.read_kfgins_binary(path)
    msg = str(e.value)
    assert e.value.record == 4 and f"{path}: record 4: " in msg
    assert "file size 188 bytes is not a multiple of 56" in msg and "byte 168" in msg
    write_records(path, [0.0, 0.005, 0.01, 0.015], nan_at=2)
    with pytest.raises(InputError, match=r"record 3: non-finite value nan in dtheta_z"):
        imu_files.read_kfgins_binary(path)
    write_records(path, [0.0, 0.005, 0.005, 0.015])
    with pytest.raises(InputError, match=r"record 3: duplicated epoch: time 0.005 s already "
                                         r"on record 2"):
        imu_files.read_kfgins_binary(path)
    write_records(path, [0.0, 0.005, 0.01, 0.0])
    with pytest.raises(InputError, match=r"record 4: time not increasing"):
        imu_files.read_kfgins_binary(path)


# ----------------------------------------------------------------------------- rates

def test_rates_to_increments_constant_rates(tmp_path):
    """Constant rates: increment = rate * (t[k] - t[k-1]), first row the median dt."""
    w = np.array([0.01, -0.02, 0.3])          # rad/s
    f = np.array([0.5, -0.2, -G])             # m/s^2
    t = np.array([10.0, 10.02, 10.03, 10.04, 10.08, 10.09])   # a 0.04 s gap
    dt_true = np.array([0.01, 0.02, 0.01, 0.01, 0.04, 0.01])  # first row: the median
    path = tmp_path / "rates.txt"
    path.write_text(kfgins_lines(t, np.tile(w, (6, 1)), np.tile(f, (6, 1))))
    log = imu_files.read_kfgins_text(path, rates=True)
    np.testing.assert_allclose(log.dtheta_b, w * dt_true[:, None], rtol=1e-12)
    np.testing.assert_allclose(log.dvel_b, f * dt_true[:, None], rtol=1e-12)
    np.testing.assert_array_equal(log.find_gaps(), [1, 4])
    th, dv = imu.rates_to_increments(t, np.tile(w, (6, 1)), np.tile(f, (6, 1)))
    np.testing.assert_allclose(th, log.dtheta_b, rtol=1e-15)
    # CSV with deg/s and g units, same physical rates
    lines = ["time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g"]
    for ti in t:
        lines.append(",".join(repr(float(v)) for v in [ti, *np.rad2deg(w), *(f / G)]))
    (tmp_path / "rates.csv").write_text("\n".join(lines) + "\n")
    log2 = imu_files.read_imu(tmp_path / "rates.csv")
    np.testing.assert_allclose(log2.dtheta_b, log.dtheta_b, rtol=1e-13)
    np.testing.assert_allclose(log2.dvel_b, log.dvel_b, rtol=1e-13)
    # deg/h
    lines[0] = "time_s,gyro_x_dph,gyro_y_dph,gyro_z_dph,accel_x_mps2,accel_y_mps2,accel_z_mps2"
    (tmp_path / "dph.csv").write_text(
        lines[0] + "\n" + "".join(f"{float(ti)!r},3600,0,-7200,0,0,-9.8\n" for ti in t))
    log3 = imu_files.read_csv(tmp_path / "dph.csv")
    np.testing.assert_allclose(log3.dtheta_b, np.deg2rad([1, 0, -2]) * dt_true[:, None],
                               rtol=1e-12)


def test_rates_binary(tmp_path):
    w, f = np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, -G])
    t = np.arange(5) * 0.01
    table = np.column_stack([t, np.tile(w, (5, 1)), np.tile(f, (5, 1))]).astype("<f8")
    (tmp_path / "r.bin").write_bytes(table.tobytes())
    log = imu_files.read_imu(tmp_path / "r.bin", rates=True)
    np.testing.assert_allclose(log.dvel_b[:, 2], -G * 0.01, rtol=1e-12)


def test_rates_read_as_increments_are_refused(tmp_path):
    """A 200 Hz file of specific force (|f| ~ 9.8 per sample) read as increments."""
    rng = np.random.default_rng(2)
    n = 300
    t = 1000.0 + np.arange(n) * 0.005
    gyro = rng.standard_normal((n, 3)) * 0.01
    accel = np.array([0.1, 0.0, -G]) + rng.standard_normal((n, 3)) * 0.1
    path = tmp_path / "rates.txt"
    path.write_text(kfgins_lines(t, gyro, accel))
    with pytest.raises(InputError) as e:
        imu_files.read_imu(path)
    msg = str(e.value)
    assert msg.startswith(f"{path}: ") and "implausible velocity increments" in msg
    assert "--rates" in msg and "rates=True" in msg
    log = imu_files.read_imu(path, rates=True)                 # accepted as rates
    np.testing.assert_allclose(log.dvel_b, accel * 0.005, rtol=1e-9)
    # binary too
    table = np.column_stack([t, gyro, accel]).astype("<f8")
    (tmp_path / "rates.bin").write_bytes(table.tobytes())
    with pytest.raises(InputError, match="--rates"):
        imu_files.read_imu(tmp_path / "rates.bin")
    # a fast-spinning rate file (|w| = 30 rad/s per sample) read as increments
    spin = np.tile([0.0, 0.0, 30.0], (n, 1))
    small = np.tile([0.0, 0.0, -G * 0.005], (n, 1))
    path.write_text(kfgins_lines(t, spin, small))
    with pytest.raises(InputError, match="implausible angle increments.*--rates"):
        imu_files.read_imu(path)
    # a CSV whose increment header hides rates gets a header hint
    lines = ["time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvel_x_mps,dvel_y_mps,dvel_z_mps"]
    lines += [",".join(repr(float(v)) for v in [ti, *g, *a]) for ti, g, a in zip(t, gyro, accel)]
    (tmp_path / "r.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="accel_z_mps2 in the header"):
        imu_files.read_imu(tmp_path / "r.csv")


def test_increments_read_as_rates_warn(tmp_path):
    log = make_log(n=100)
    imu_files.write_kfgins_text(tmp_path / "inc.txt", log)
    with pytest.warns(InputWarning, match="may hold increments"):
        imu_files.read_imu(tmp_path / "inc.txt", rates=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        imu_files.read_imu(tmp_path / "inc.txt")


def test_real_log_is_plausible(tmp_path):
    """Sanity of the thresholds: a 1 Hz log at 2 g and a 1 kHz log at rest pass."""
    for dt, f in ((1.0, 2 * G), (0.001, G)):
        n = 50
        t = np.arange(n) * dt
        log = ImuLog(t, np.full((n, 3), 0.5 * dt), np.tile([0.0, 0.0, -f * dt], (n, 1)))
        imu_files.write_kfgins_binary(tmp_path / "ok.bin", log)
        assert_same_log(imu_files.read_imu(tmp_path / "ok.bin"), log)


# ----------------------------------------------------------------------------- axes

# What an IMU at rest, level, nose turning right at R rad/s measures, written by hand in
# each axes convention: specific force points UP (reaction to gravity, +G along "up"),
# the rotation is about DOWN (right-handed: nose to the right), i.e. -R about "up".
R = 0.2
PHYSICAL = {
    # axes: (gyro in IMU axes, accel in IMU axes, forward unit vector, right unit vector)
    "FRD": ([0, 0, R], [0, 0, -G], [1, 0, 0], [0, 1, 0]),
    "FLU": ([0, 0, -R], [0, 0, G], [1, 0, 0], [0, -1, 0]),
    "RFU": ([0, 0, -R], [0, 0, G], [0, 1, 0], [1, 0, 0]),
    "FUR": ([0, -R, 0], [0, G, 0], [1, 0, 0], [0, 0, 1]),
}


@pytest.mark.parametrize("axes", list(PHYSICAL))
def test_axes_mapping_physical(tmp_path, axes):
    gyro, accel, fwd, right = (np.array(v, dtype=float) for v in PHYSICAL[axes])
    t = np.arange(4) * 0.01
    rows = [gyro, accel, 2.0 * fwd - 9.0 * np.cross(fwd, right), 3.0 * right]
    path = tmp_path / f"{axes}.txt"
    # rows 0..1: rest + right turn; rows 2..3: forward/down and right accelerations
    path.write_text(kfgins_lines(t, np.array([gyro, gyro, gyro, gyro]),
                                 np.array([accel, accel, rows[2], rows[3]])))
    log = imu_files.read_kfgins_text(path, axes=axes.lower() if axes == "FLU" else axes, rates=True)
    np.testing.assert_allclose(log.dtheta_b[1] / 0.01, [0, 0, R], atol=1e-15)  # yaw right: +z
    np.testing.assert_allclose(log.dvel_b[1] / 0.01, [0, 0, -G], atol=1e-12)   # (0, 0, -g)
    # fwd x right = down in a right-handed frame; 2 fwd - 9 down -> (2, 0, -9) in FRD
    np.testing.assert_allclose(log.dvel_b[2] / 0.01, [2.0, 0, -9.0], atol=1e-12)
    np.testing.assert_allclose(log.dvel_b[3] / 0.01, [0, 3.0, 0], atol=1e-12)


def test_axes_matrices():
    for axes in imu.AXES:
        C = imu.C_frd_axes(axes)
        assert np.linalg.det(C) == pytest.approx(1.0)
        np.testing.assert_array_equal(C @ C.T, np.eye(3))
    C = imu.C_frd_axes("FRD")
    C[0, 0] = 5.0                                   # a copy: the table is unchanged
    assert imu.C_frd_axes("FRD")[0, 0] == 1.0
    with pytest.raises(ValueError, match="axes must be one of FRD, FLU, RFU, FUR"):
        imu.C_frd_axes("NED")
    with pytest.raises(ValueError, match="axes must be one of"):
        imu_files.read_imu("does-not-matter.txt", axes="XYZ")


# ----------------------------------------------------------------------------- compensation

def test_compensation_recovers_injected_errors():
    rng = np.random.default_rng(4)
    n = 200
    t = 50.0 + np.cumsum(rng.uniform(0.004, 0.006, n))
    true = ImuLog(t, rng.standard_normal((n, 3)) * 1e-3, rng.standard_normal((n, 3)) * 0.05)
    dt = true.dt[:, None]
    b_g = np.array([0.5, -0.4, 0.6]) * imu.DPH
    b_a = np.array([50.0, -40.0, 60.0]) * imu.MGAL
    s_g = np.array([100.0, -200.0, 300.0]) * imu.PPM
    s_a = np.array([-50.0, 80.0, 1000.0]) * imu.PPM
    raw = ImuLog(t, (1 + s_g) * true.dtheta_b + b_g * dt, (1 + s_a) * true.dvel_b + b_a * dt)
    raw_copy = np.array(raw.dvel_b)
    comp = imu.compensate(raw, gyro_bias=b_g, accel_bias=b_a, gyro_scale=s_g, accel_scale=s_a)
    np.testing.assert_allclose(comp.dtheta_b, true.dtheta_b, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(comp.dvel_b, true.dvel_b, rtol=1e-12, atol=1e-17)
    np.testing.assert_array_equal(comp.time, t)
    np.testing.assert_array_equal(raw.dvel_b, raw_copy)           # input untouched
    # bias only, scalar, and per-row (n, 3) forms; None leaves the log as it is
    only = imu.compensate(true, accel_bias=0.1)
    np.testing.assert_allclose(only.dvel_b, true.dvel_b - 0.1 * dt, rtol=1e-14)
    np.testing.assert_array_equal(only.dtheta_b, true.dtheta_b)
    per_row = imu.compensate(true, gyro_bias=np.tile(b_g, (n, 1)))
    np.testing.assert_allclose(per_row.dtheta_b, true.dtheta_b - b_g * dt, rtol=1e-14)
    same = imu.compensate(true)
    assert_same_log(same, true)


def test_compensation_arguments():
    log = make_log(n=5)
    with pytest.raises(ValueError, match="gyro_bias must be a scalar, shape"):
        imu.compensate(log, gyro_bias=[1.0, 2.0])
    with pytest.raises(ValueError, match="accel_scale must be greater than -1"):
        imu.compensate(log, accel_scale=[-1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        imu.compensate(log, accel_bias=[np.nan, 0, 0])


def test_unit_constants():
    assert imu.DPH == pytest.approx(4.84813681109536e-06, rel=1e-14)
    assert imu.MGAL == 1e-5 and imu.PPM == 1e-6 and imu.G0 == 9.80665


# ----------------------------------------------------------------------------- file safety

def test_reading_leaves_files_untouched(tmp_path):
    log = make_log(n=50)
    paths = [tmp_path / "a.txt", tmp_path / "a.bin", tmp_path / "a.csv"]
    imu_files.write_kfgins_text(paths[0], log)
    imu_files.write_kfgins_binary(paths[1], log)
    imu_files.write_csv(paths[2], log)
    bad = tmp_path / "bad.txt"
    bad.write_text(GOOD + "300000.015 " + ROW + "\n")
    paths.append(bad)
    old = 1_600_000_000_000_000_000
    for p in paths:
        os.utime(p, ns=(old, old))
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns, p.stat().st_mode) for p in paths}
    for p in paths[:3]:
        back = imu_files.read_imu(p)                  # the good files read (and equal the log)
        np.testing.assert_allclose(back.time, log.time, rtol=0, atol=1e-9)
        np.testing.assert_allclose(back.dvel_b, log.dvel_b, rtol=1e-9, atol=1e-12)
    with pytest.raises(InputError, match=r"bad\.txt:5: duplicated epoch: time 300000\.015 s "
                                         r"already on line 4"):
        imu_files.read_imu(bad)
    for p in paths:
        assert (p.read_bytes(), p.stat().st_mtime_ns, p.stat().st_mode) == before[p]
    assert sorted(q.name for q in tmp_path.iterdir()) == sorted(p.name for p in paths)


def test_bench_file_head(tmp_path, bench_data):
    """The first lines of the shared benchmark log (KF-GINS text) read as expected."""
    src = bench_data / "imu_clean.txt"
    with open(src, "rb") as f:
        head = b"".join(f.readline() for _ in range(2000))
    (tmp_path / "head.txt").write_bytes(head)
    log = imu_files.read_kfgins_text(tmp_path / "head.txt")
    ref = np.loadtxt(tmp_path / "head.txt")
    np.testing.assert_array_equal(bits(log.time), bits(ref[:, 0]))
    np.testing.assert_array_equal(bits(log.dvel_b), bits(ref[:, 4:7]))
    assert log.nominal_dt == pytest.approx(0.005)
    imu_files.write_kfgins_text(tmp_path / "again.txt", log)
    assert (tmp_path / "again.txt").read_bytes() == head      # byte-identical rewrite
