"""Property-based tests (hypothesis) of the file readers (issue 8, hardening).

1. On arbitrary bytes, arbitrary text and mutated tables, the IMU, GNSS, mount, nav, EO,
   tie-point, event and lunar readers return or raise ``InputError`` -- never anything
   else (no IndexError, UnicodeDecodeError, csv.Error ...), and the error names the file.
2. Written tables read back exactly: IMU logs bit for bit (text, CSV, binary); GNSS,
   nav, EO files to the exact value of each printed field (the independent truth is
   Python's ``float()`` of the text), and writing what was read gives the same text.
"""
import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ins.common.errors import InputError
from ins.io.gnss import read_gnss, write_gnss
from ins.io.gnss_log import GnssLog
from ins.io.imu_files import (
    read_csv,
    read_kfgins_binary,
    read_kfgins_text,
    write_csv,
    write_kfgins_binary,
    write_kfgins_text,
)
from ins.io.mount import read_mount
from ins.io.navfiles import read_nav, write_nav
from ins.nav.imu import ImuLog
from ins.nav.rotation import euler_to_quat, wrap_to_pi
from ins.nav.trajectory import Trajectory
from photogrammetry.imagery.tiepoints import read_tiepoints
from photogrammetry.lunar.io import read_centres, read_times
from photogrammetry.orientation.camera import FrameCamera
from photogrammetry.orientation.exposure import (
    ExposureOrientation,
    read_eo_csv,
    read_events,
    write_eo_csv,
)

SETTINGS = settings(max_examples=40, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])
CAMERA = FrameCamera(focal_length_mm=50.0, pixel_size_mm=0.005, width_px=4000,
                     height_px=3000, principal_point_px=(1999.5, 1499.5),
                     radial_k=(-2e-6, 1e-10, 0.0), tangential_p=(3e-6, -2e-6))


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    return tmp_path_factory.mktemp("prop")


def _write(folder, name, data):
    path = os.path.join(folder, name)
    with open(path, "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode("utf-8"))
    return path


READERS = {
    "imu.txt": read_kfgins_text,
    "imu.csv": read_csv,
    "imu.bin": read_kfgins_binary,
    "gnss.txt": read_gnss,
    "mount.txt": read_mount,
    "traj.nav": read_nav,
    "eo.csv": read_eo_csv,
    "tiepoints.csv": read_tiepoints,
    "tiepoints_px.csv": lambda p: read_tiepoints(p, CAMERA),
    "events.csv": read_events,
    "times.csv": read_times,
    "centres.csv": read_centres,
}


def _only_input_error(name, path):
    """Call the reader; any exception but InputError (naming the file) fails."""
    try:
        READERS[name](path)
    except InputError as exc:
        assert os.path.basename(path) in str(exc), str(exc)
        assert "\n" not in str(exc)


# ---------------------------------------------------------------------------------------
# 1. fuzzing: only InputError

TABLE_ALPHABET = "0123456789.eE+-, \t\n#%nainf,xr_:;\r"
number_text = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10 ** 20, 10 ** 20).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e", ".", "1.2.3", "", "+", "0x1p3", "1,,2"]))
# a table line: 0 .. 14 number-like fields joined by a separator
table_line = st.tuples(st.lists(number_text, max_size=14),
                       st.sampled_from([" ", ",", "\t", ", ", "  "])).map(
    lambda t: t[1].join(t[0]))
table_text = st.lists(st.one_of(table_line, st.sampled_from(["", "# c", "% c"])),
                      max_size=30).map("\n".join)


@pytest.mark.parametrize("name", sorted(READERS))
@SETTINGS
@given(data=st.binary(max_size=400))
def test_arbitrary_bytes(scratch, name, data):
    _only_input_error(name, _write(scratch, name, data))


@pytest.mark.parametrize("name", sorted(READERS))
@SETTINGS
@given(text=st.text(alphabet=st.characters(codec="utf-8"), max_size=300))
def test_arbitrary_text(scratch, name, text):
    _only_input_error(name, _write(scratch, name, text))


@pytest.mark.parametrize("name", ["imu.txt", "gnss.txt", "mount.txt", "traj.nav"])
@SETTINGS
@given(text=st.one_of(table_text, st.text(alphabet=TABLE_ALPHABET, max_size=400)))
def test_numeric_tables(scratch, name, text):
    _only_input_error(name, _write(scratch, name, text))


HEADERS = {
    "imu.csv": "time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvel_x_mps,dvel_y_mps,dvel_z_mps",
    "eo.csv": "# system = phi-omega-kappa\nimage_id,time_s,X_m,Y_m,Z_m,phi_deg,omega_deg,kappa_deg",
    "tiepoints.csv": "image_id,point_id,x_mm,y_mm",
    "tiepoints_px.csv": "image_id,point_id,u_px,v_px",
    "events.csv": "image_id,time_s",
    "times.csv": "image_id,gps_week,gps_time_s",
    "centres.csv": "image_id,u_px,v_px,sigma_px",
}
csv_field = st.one_of(number_text, st.text(alphabet="abS01_ \"'#,", max_size=6))
csv_line = st.lists(csv_field, max_size=10).map(",".join)


@pytest.mark.parametrize("name", sorted(HEADERS))
@SETTINGS
@given(lines=st.lists(st.one_of(csv_line, st.just("")), max_size=12))
@example(lines=["0.0,15251,0.0"])            # found by hypothesis: ns overflow of GPS week
def test_csv_after_a_valid_header(scratch, name, lines):
    _only_input_error(name, _write(scratch, name, "\n".join([HEADERS[name]] + lines) + "\n"))


@pytest.mark.parametrize("utc", ["NaT", "3000-01-01T00:00:00Z", "-1", "", "2017-13-01"])
def test_times_out_of_range_are_refused(scratch, utc):
    """np.datetime64(text, "ns") wraps year 3000 to 1830 and reads 'NaT' / '' as NaT."""
    path = _write(scratch, "times_utc.csv", f"image_id,utc\na,2017-05-02T14:00:00Z\nb,{utc}\n")
    with pytest.raises(InputError, match=r"times_utc.csv:3: utc: expected ISO 8601"):
        read_times(path)


# ---------------------------------------------------------------------------------------
# 2. round trips

@st.composite
def imu_logs(draw):
    n = draw(st.integers(2, 40))
    t0 = draw(st.floats(-1e6, 1e6, allow_nan=False))
    dt = draw(st.sampled_from([0.005, 0.01, 1 / 300, 0.0025, 0.1]))
    jitter = draw(hnp.arrays(np.float64, n, elements=st.floats(0.0, 0.3 * dt)))
    time = t0 + dt * np.arange(n) + jitter
    assume(np.all(np.diff(time) > 0))
    # increments a real IMU gives: |w| < 20 rad/s, |f| < 100 m/s^2 (the readers' limits)
    finite = dict(allow_nan=False, allow_infinity=False, allow_subnormal=True)
    dtheta = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-0.5 * dt, 0.5 * dt,
                                                                      **finite)))
    dvel = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-30 * dt, 30 * dt,
                                                                    **finite)))
    return ImuLog(time, dtheta, dvel)


@pytest.mark.parametrize("ext, write, read", [
    ("txt", write_kfgins_text, read_kfgins_text), ("csv", write_csv, read_csv),
    ("bin", write_kfgins_binary, read_kfgins_binary)])
@SETTINGS
@given(log=imu_logs())
def test_imu_round_trip_is_bit_exact(scratch, ext, write, read, log):
    path = os.path.join(scratch, f"rt.{ext}")
    assert write(path, log) == len(log)
    back = read(path)
    for name in ("time", "dtheta_b", "dvel_b"):
        a, b = getattr(log, name), getattr(back, name)
        assert np.array_equal(a.view(np.int64), b.view(np.int64)) or np.array_equal(a, b), name


def _fields(path):
    """The numbers of a whitespace/comma text table as Python floats (the truth)."""
    with open(path) as f:
        return [[float(x) for x in line.replace(",", " ").split()]
                for line in f if line.strip() and not line.startswith("#")]


finite_floats = dict(allow_nan=False, allow_infinity=False)


@st.composite
def gnss_logs(draw):
    n = draw(st.integers(1, 20))
    time = 1e5 + np.cumsum(draw(hnp.arrays(np.float64, n, elements=st.floats(0.001, 10))))
    assume(np.all(np.diff(np.round(time, 6)) > 0))
    lat = draw(hnp.arrays(np.float64, n, elements=st.floats(-math.pi / 2, math.pi / 2)))
    lon = draw(hnp.arrays(np.float64, n, elements=st.floats(-math.pi, math.pi)))
    h = draw(hnp.arrays(np.float64, n, elements=st.floats(-500, 1e5)))
    std = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(0.001, 100)))
    vel = None
    if draw(st.booleans()):
        vel = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-500, 500)))
    return GnssLog(time, np.column_stack([lat, lon, h]), std, vel,
                   None if vel is None else std / 10)


@SETTINGS
@given(log=gnss_logs())
def test_gnss_round_trip(scratch, log):
    path = os.path.join(scratch, "rt_gnss.txt")
    write_gnss(path, log)
    rows = np.array(_fields(path))
    back = read_gnss(path)
    assert back.time.tolist() == rows[:, 0].tolist()
    assert back.lla[:, 0].tolist() == np.deg2rad(rows[:, 1]).tolist()
    assert back.lla[:, 2].tolist() == rows[:, 3].tolist()
    assert back.sigma_ned_m.tolist() == rows[:, 4:7].tolist()
    assert back.has_velocity == log.has_velocity
    if log.has_velocity:
        assert back.v_n.tolist() == rows[:, 7:10].tolist()
    # the written values are the given ones to the printed decimals
    np.testing.assert_allclose(back.time, log.time, atol=5e-7, rtol=0)
    np.testing.assert_allclose(np.rad2deg(back.lla[:, :2]), np.rad2deg(log.lla[:, :2]),
                               atol=6e-13, rtol=0)    # 0.5e-12 printed + deg<->rad ulps
    again = os.path.join(scratch, "rt_gnss2.txt")
    write_gnss(again, back)
    assert open(again).read() == open(path).read()


@st.composite
def trajectories(draw):
    n = draw(st.integers(1, 20))
    time = 1e5 + np.cumsum(draw(hnp.arrays(np.float64, n, elements=st.floats(0.001, 10))))
    assume(np.all(np.diff(np.round(time, 6)) > 0))
    lat = draw(hnp.arrays(np.float64, n, elements=st.floats(-1.5, 1.5)))
    lon = draw(hnp.arrays(np.float64, n, elements=st.floats(-math.pi, math.pi)))
    h = draw(hnp.arrays(np.float64, n, elements=st.floats(-500, 1e5)))
    v = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-500, 500)))
    rpy = np.column_stack([
        draw(hnp.arrays(np.float64, n, elements=st.floats(-179, 179))),
        draw(hnp.arrays(np.float64, n, elements=st.floats(-85, 85))),
        draw(hnp.arrays(np.float64, n, elements=st.floats(-180, 180)))])
    return Trajectory(time, np.column_stack([lat, lon, h]), v,
                      euler_to_quat(rpy, degrees=True))


@SETTINGS
@given(traj=trajectories())
def test_nav_round_trip(scratch, traj):
    path = os.path.join(scratch, "rt.nav")
    assert write_nav(path, traj, week=2300) == len(traj)
    rows = np.array(_fields(path))
    back = read_nav(path)
    assert back.time.tolist() == rows[:, 1].tolist()
    assert back.lla[:, 0].tolist() == np.deg2rad(rows[:, 2]).tolist()
    assert back.lla[:, 2].tolist() == rows[:, 4].tolist()
    assert back.v_n.tolist() == rows[:, 5:8].tolist()
    # attitude: through the quaternion, within 1e-9 deg of the printed angles
    d = back.rpy(degrees=True) - rows[:, 8:11]
    d[:, 2] = (d[:, 2] + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(d)) < 1e-9
    again = os.path.join(scratch, "rt2.nav")
    write_nav(again, back, week=2300)
    cols = [line.split()[:8] for line in open(again)]
    assert cols == [line.split()[:8] for line in open(path)]


ids = st.text(alphabet="ABCSxyz0123456789_-.", min_size=1, max_size=8)


@st.composite
def exterior_orientations(draw):
    names = draw(st.lists(ids, min_size=1, max_size=12, unique=True))
    n = len(names)
    system = draw(st.sampled_from(["phi-omega-kappa", "omega-phi-kappa"]))
    time = draw(hnp.arrays(np.float64, n, elements=st.floats(0, 604800)))
    pos = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-1e6, 1e6)))
    ang = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-math.pi, math.pi)))
    sig = None
    if draw(st.booleans()):
        sig = draw(hnp.arrays(np.float64, (n, 6), elements=st.floats(0, 10)))
    return ExposureOrientation(names, time, pos, ang, system, "enu; origin_lat_deg = 30.5",
                               None if sig is None else sig[:, :3],
                               None if sig is None else np.deg2rad(sig[:, 3:]))


@SETTINGS
@given(eo=exterior_orientations())
@example(eo=ExposureOrientation(["A"], [0.0], [[0.0, 0.0, 0.0]],
                                [[-math.pi, 0.0, -math.pi + 1e-13]], "omega-phi-kappa", "enu"))
def test_eo_round_trip(scratch, eo):
    path = os.path.join(scratch, "rt_eo.csv")
    write_eo_csv(path, eo)
    back = read_eo_csv(path)
    assert back.image_id == eo.image_id and back.system == eo.system
    assert back.frame == eo.frame and back.has_sigmas == eo.has_sigmas
    with open(path) as f:
        rows = [line.rstrip("\n").split(",") for line in f if not line.startswith("#")][1:]
    assert back.time.tolist() == [float(r[1]) for r in rows]
    assert back.position.tolist() == [[float(x) for x in r[2:5]] for r in rows]
    assert back.angles.tolist() == np.deg2rad([[float(x) for x in r[5:8]] for r in rows]).tolist()
    # angles are written wrapped to (-180, 180] deg (issue 12): -pi comes back as +pi
    assert np.all(back.angles <= math.pi) and np.all(back.angles > -math.pi)
    np.testing.assert_allclose(wrap_to_pi(back.angles - eo.angles), 0.0, atol=1e-12, rtol=0)
    again = os.path.join(scratch, "rt_eo2.csv")
    write_eo_csv(again, back)
    assert open(again).read() == open(path).read()


@SETTINGS
@given(obs=st.lists(st.tuples(ids, ids, st.floats(-30, 30, **finite_floats),
                              st.floats(-30, 30, **finite_floats)),
                    min_size=1, max_size=20, unique_by=lambda o: (o[0], o[1])))
def test_tiepoints_round_trip(scratch, obs):
    path = os.path.join(scratch, "rt_tp.csv")
    text = "# sigma_px = 0.5\nimage_id,point_id,x_mm,y_mm\n" + "".join(
        f"{i},{p},{x!r},{y!r}\n" for i, p, x, y in obs)
    _write(scratch, "rt_tp.csv", text)
    tp = read_tiepoints(path)
    assert list(tp.image_id) == [o[0] for o in obs]
    assert list(tp.point_id) == [o[1] for o in obs]
    assert tp.xy_mm.tolist() == [[o[2], o[3]] for o in obs]
    assert tp.line.tolist() == list(range(3, 3 + len(obs)))


# ---------------------------------------------------------------------------------------
# 3. random corruptions of a VALID file (issue: bad inputs, item 5): truncation, a
#    NaN/inf/huge value, two columns swapped, bytes that are not UTF-8 -> InputError
#    naming the file on one line (no numpy repr), or a result that is all finite;
#    CRLF line ends and trailing spaces -> the clean file's result exactly.

def _valid_files(folder):
    """One small valid file per reader (written by the package's own writers)."""
    from ins.io.rtklib import write_pos
    from ins.io.sbet import write_sbet, write_smrmsg
    n = 60
    time = 200000.0 + 0.01 * np.arange(n)
    k = np.arange(n)[:, None]
    imu = ImuLog(time, 1e-5 * np.sin(k + np.arange(3)), np.array([1e-4, -2e-4, -0.098])
                 + 1e-4 * np.cos(k + np.arange(3)))
    files = {}
    for ext, write in (("txt", write_kfgins_text), ("csv", write_csv),
                       ("bin", write_kfgins_binary)):
        files[f"imu.{ext}"] = os.path.join(folder, f"valid_imu.{ext}")
        write(files[f"imu.{ext}"], imu)
    m = 12
    tg = 200000.0 + np.arange(m)
    lla = np.column_stack([np.deg2rad(30.5 + 1e-5 * np.arange(m)),
                           np.deg2rad(114.3 + 2e-5 * np.arange(m)), 300.0 + np.arange(m)])
    v = np.tile([1.0, 2.0, -0.1], (m, 1))
    std = np.tile([0.02, 0.02, 0.04], (m, 1))
    files["gnss.txt"] = os.path.join(folder, "valid_gnss.txt")
    write_gnss(files["gnss.txt"], GnssLog(tg, lla, std, v, std / 2))
    files["gnss.pos"] = os.path.join(folder, "valid_gnss.pos")
    write_pos(files["gnss.pos"], GnssLog(tg, lla, std), week=2300)
    traj = Trajectory(tg, lla, v, euler_to_quat(np.tile([1.0, -2.0, 80.0], (m, 1)),
                                                degrees=True))
    files["traj.nav"] = os.path.join(folder, "valid_traj.nav")
    write_nav(files["traj.nav"], traj, week=2300)
    files["traj.sbet"] = os.path.join(folder, "valid_traj.sbet")
    write_sbet(files["traj.sbet"], traj)
    files["smrmsg.out"] = os.path.join(folder, "valid_smrmsg.out")
    write_smrmsg(files["smrmsg.out"], tg, std, std / 10, np.full((m, 3), 1e-4))
    files["mount.txt"] = _write(folder, "valid_mount.txt", "# time_s roll pitch yaw\n" + "".join(
        f"{t:.6f} {0.1 * j:.6f} {-0.2:.6f} {5.0 + j:.6f}\n" for j, t in enumerate(tg)))
    files["returns.csv"] = _write(folder, "valid_returns.csv", "time_s,range_m,scan_angle_deg\n"
                                  + "".join(f"{t:.3f},{300 + j},{j - 6}\n"
                                            for j, t in enumerate(tg)))
    return files


def _read_returns(path):
    from ins.lidar.lidar_files import iter_returns
    return list(iter_returns(path, "polygon"))


def _read_pos(path):
    from ins.io.rtklib import read_pos
    return read_pos(path)


def _read_sbet(path):
    from ins.io.sbet import read_sbet
    return read_sbet(path)


def _read_smrmsg(path):
    from ins.io.sbet import read_smrmsg
    return read_smrmsg(path)


CORRUPTED_READERS = {
    "imu.txt": read_kfgins_text, "imu.csv": read_csv, "imu.bin": read_kfgins_binary,
    "gnss.txt": read_gnss, "gnss.pos": _read_pos, "mount.txt": read_mount,
    "traj.nav": read_nav, "traj.sbet": _read_sbet, "smrmsg.out": _read_smrmsg,
    "returns.csv": _read_returns,
}
BINARY = {"imu.bin": 7, "traj.sbet": 17, "smrmsg.out": 10}      # doubles a record


@pytest.fixture(scope="module")
def valid(scratch):
    folder = os.path.join(scratch, "valid")
    os.makedirs(folder, exist_ok=True)
    return _valid_files(folder)


def _arrays(result):
    """The float arrays of a reader's result (dataclass, NamedTuple or list of them)."""
    if isinstance(result, list):
        return [a for r in result for a in _arrays(r)]
    items = result._asdict().values() if hasattr(result, "_asdict") else vars(result).values()
    return [np.asarray(a) for a in items
            if isinstance(a, np.ndarray) and np.issubdtype(a.dtype, np.floating)]


def _outcome(name, path):
    """The reader's result, or None after checking its InputError."""
    try:
        return CORRUPTED_READERS[name](path)
    except InputError as exc:
        msg = str(exc)
        assert os.path.basename(path) in msg and "\n" not in msg, msg
        assert "np.float64" not in msg and "array(" not in msg, msg
        return None


BAD_VALUES = ["nan", "inf", "-inf", "1e308", "-1e308", "1e30", "-9e15", "1e-320"]


@st.composite
def corruptions(draw, data, binary_width):
    kind = draw(st.sampled_from(["truncate", "value", "swap", "bytes"]))
    if kind == "truncate":
        return kind, data[:draw(st.integers(1, len(data) - 1))]
    if kind == "bytes":
        pos = draw(st.integers(0, len(data)))
        junk = draw(st.sampled_from([b"\xff", b"\xc3(", b"\x80\x80", b"\xfe\xff", b"\x00"]))
        return kind, data[:pos] + junk + data[pos:]
    if binary_width:
        rows = np.frombuffer(data, "<f8").reshape(-1, binary_width).copy()
        i, j = draw(st.integers(0, len(rows) - 1)), draw(st.integers(0, binary_width - 1))
        if kind == "value":
            rows[i, j] = float(draw(st.sampled_from(BAD_VALUES)))
        else:
            j2 = draw(st.integers(0, binary_width - 1))
            rows[:, [j, j2]] = rows[:, [j2, j]]
        return kind, rows.tobytes()
    lines = data.split(b"\n")
    body = [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith((b"#", b"%"))
            and not ln[:1].isalpha()]
    sep = b"," if b"," in lines[body[0]] else None
    split = (lambda ln: ln.split(b",")) if sep else (lambda ln: ln.split())
    join = (b"," if sep else b" ").join
    width = len(split(lines[body[0]]))
    if kind == "value":
        i = draw(st.sampled_from(body))
        f = split(lines[i])
        f[draw(st.integers(0, len(f) - 1))] = draw(st.sampled_from(BAD_VALUES)).encode()
        lines[i] = join(f)
    else:
        a, b = draw(st.integers(0, width - 1)), draw(st.integers(0, width - 1))
        for i in body:
            f = split(lines[i])
            if len(f) == width:
                f[a], f[b] = f[b], f[a]
                lines[i] = join(f)
    return kind, b"\n".join(lines)


@pytest.mark.parametrize("name", sorted(CORRUPTED_READERS))
@SETTINGS
@given(data=st.data())
def test_corrupted_valid_file(scratch, valid, name, data):
    with open(valid[name], "rb") as f:
        clean = f.read()
    kind, corrupt = data.draw(corruptions(clean, BINARY.get(name)), label="corruption")
    path = _write(scratch, "corrupt_" + name, corrupt)
    result = _outcome(name, path)
    if result is not None:
        for a in _arrays(result):
            assert np.all(np.isfinite(a)), f"{kind}: a non-finite value in the result"


@pytest.mark.parametrize("name", sorted(n for n in CORRUPTED_READERS if n not in BINARY))
@pytest.mark.parametrize("variant", ["crlf", "trailing spaces", "both"])
def test_line_end_variants_read_as_the_clean_file(scratch, valid, name, variant):
    with open(valid[name], "rb") as f:
        clean = f.read()
    text = clean
    if variant in ("trailing spaces", "both"):
        text = text.replace(b"\n", b"  \t \n")
    if variant in ("crlf", "both"):
        text = text.replace(b"\n", b"\r\n")
    want = _arrays(CORRUPTED_READERS[name](valid[name]))
    got = _arrays(CORRUPTED_READERS[name](_write(scratch, "variant_" + name, text)))
    assert len(got) == len(want) and all(np.array_equal(a, b) for a, b in zip(got, want))
