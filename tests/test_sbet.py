"""Applanix SBET and SMRMSG: a numpy structured dtype as the independent reader (the field
order of PDAL's readers.sbet / readers.smrmsg), records written by hand with struct,
round trips, detection, ``ins compare`` on SBET, bad records named by number."""
import shutil
import struct
import subprocess

import numpy as np
import pytest

from ins.cli.main import main
from ins.common.errors import InputError
from ins.io.navfiles import read_trajectory, trajectory_format, write_nav
from ins.io.sbet import is_sbet, read_sbet, read_smrmsg, write_sbet, write_smrmsg
from ins.nav.rotation import euler_to_quat
from ins.nav.trajectory import Trajectory

# PDAL SbetCommon.hpp: GpsTime, Y, X, Z, XVelocity, YVelocity, ZVelocity, Roll, Pitch,
# Azimuth, WanderAngle, XBodyAccel, YBodyAccel, ZBodyAccel, XBodyAngRate, YBodyAngRate,
# ZBodyAngRate -- 17 little-endian doubles
SBET_DTYPE = np.dtype([(name, "<f8") for name in (
    "time", "lat", "lon", "h", "vx", "vy", "vz", "roll", "pitch", "heading", "wander",
    "ax", "ay", "az", "wx", "wy", "wz")])
SMRMSG_DTYPE = np.dtype([(name, "<f8") for name in (
    "time", "sn", "se", "sd", "svn", "sve", "svd", "sroll", "spitch", "sheading")])


def trajectory(n=50, seed=1):
    rng = np.random.default_rng(seed)
    t = 345600.0 + 0.005 * np.arange(n)
    lla = np.column_stack([np.deg2rad(30.5 + 1e-5 * np.arange(n)), np.deg2rad(-114.2 + rng.normal(0, 1e-6, n)),
                           800 + rng.normal(0, 1, n)])
    v = rng.normal(0, 40, (n, 3))
    rpy_deg = np.column_stack([rng.uniform(-30, 30, n), rng.uniform(-20, 20, n),
                               rng.uniform(-179, 179, n)])
    return Trajectory(t, lla, v, euler_to_quat(rpy_deg, degrees=True)), rpy_deg


def test_written_fields_by_structured_dtype(tmp_path):
    traj, rpy_deg = trajectory()
    p = tmp_path / "sbet.out"
    assert write_sbet(p, traj) == len(traj)
    rec = np.fromfile(p, dtype=SBET_DTYPE)
    assert p.stat().st_size == 136 * len(traj)
    np.testing.assert_array_equal(rec["time"], traj.time)
    np.testing.assert_array_equal(rec["lat"], traj.lla[:, 0])
    np.testing.assert_array_equal(rec["lon"], traj.lla[:, 1])
    np.testing.assert_array_equal(rec["h"], traj.lla[:, 2])
    # wander angle 0: x north, y west, z up
    np.testing.assert_array_equal(rec["vx"], traj.v_n[:, 0])
    np.testing.assert_array_equal(rec["vy"], -traj.v_n[:, 1])
    np.testing.assert_array_equal(rec["vz"], -traj.v_n[:, 2])
    np.testing.assert_allclose(np.rad2deg(rec["roll"]), rpy_deg[:, 0], atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(rec["pitch"]), rpy_deg[:, 1], atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(rec["heading"]), np.mod(rpy_deg[:, 2], 360), atol=1e-9)
    assert np.all((rec["heading"] >= 0) & (rec["heading"] < 2 * np.pi))
    for name in ("wander", "ax", "ay", "az", "wx", "wy", "wz"):
        assert not rec[name].any()


def test_round_trip_in_pieces(tmp_path):
    traj, _ = trajectory(120)
    pieces = [Trajectory(traj.time[a:b], traj.lla[a:b], traj.v_n[a:b], traj.q_nb[a:b])
              for a, b in ((0, 40), (40, 41), (41, 120))]
    p = tmp_path / "s.sbet"
    assert write_sbet(p, iter(pieces)) == 120
    back = read_sbet(p)
    np.testing.assert_array_equal(back.time, traj.time)
    np.testing.assert_array_equal(back.lla, traj.lla)
    np.testing.assert_array_equal(back.v_n, traj.v_n)
    dots = np.abs(np.sum(back.q_nb * traj.q_nb, axis=1))
    assert np.all(dots > 1 - 1e-14)


def test_record_by_hand_with_wander_angle(tmp_path):
    """A record with wander angle 30 deg: true heading = platform heading - wander,
    v_north = vx cos a - vy sin a, v_east = -vx sin a - vy cos a, z up."""
    a = np.deg2rad(30.0)
    vals = [1000.5, np.deg2rad(45.0), np.deg2rad(7.5), 123.25, 10.0, 2.0, -1.0,
            np.deg2rad(1.0), np.deg2rad(-2.0), np.deg2rad(100.0), a,
            0.1, 0.2, 9.8, 0.01, 0.02, 0.03]
    p = tmp_path / "hand.out"
    p.write_bytes(struct.pack("<17d", *vals) + struct.pack("<17d", *([1001.0] + vals[1:])))
    tr = read_trajectory(p)
    assert tr.time.tolist() == [1000.5, 1001.0]
    np.testing.assert_allclose(tr.lla[0], [np.deg2rad(45.0), np.deg2rad(7.5), 123.25])
    np.testing.assert_allclose(tr.v_n[0], [10 * np.cos(a) - 2 * np.sin(a),
                                           -10 * np.sin(a) - 2 * np.cos(a), 1.0], atol=1e-12)
    np.testing.assert_allclose(tr.rpy(degrees=True)[0], [1.0, -2.0, 70.0], atol=1e-9)


def test_smrmsg_round_trip_and_units(tmp_path):
    t = np.array([10.0, 11.0, 12.0])
    pos = np.array([[0.01, 0.02, 0.03]] * 3)
    vel = np.array([[0.001, 0.002, 0.003]] * 3)
    rpy = np.deg2rad(np.array([[1 / 60, 2 / 60, 0.5]] * 3))       # 1', 2', 30'
    p = tmp_path / "smrmsg.out"
    assert write_smrmsg(p, t, pos, vel, rpy) == 3
    rec = np.fromfile(p, dtype=SMRMSG_DTYPE)
    np.testing.assert_allclose(rec["sroll"], 1.0)
    np.testing.assert_allclose(rec["spitch"], 2.0)
    np.testing.assert_allclose(rec["sheading"], 30.0)
    np.testing.assert_array_equal(rec["sn"], 0.01)
    np.testing.assert_array_equal(rec["svd"], 0.003)
    back = read_smrmsg(p)
    np.testing.assert_array_equal(back.time, t)
    np.testing.assert_allclose(back.sigma_rpy_rad, rpy, rtol=1e-15)
    hand = tmp_path / "h.out"
    hand.write_bytes(struct.pack("<10d", 5.0, 1, 2, 3, 4, 5, 6, 60.0, 120.0, 1.5))
    got = read_smrmsg(hand)
    np.testing.assert_allclose(np.rad2deg(got.sigma_rpy_rad[0]), [1.0, 2.0, 0.025])
    np.testing.assert_array_equal(got.sigma_vel_ned_mps[0], [4, 5, 6])


def test_bad_records_named(tmp_path):
    traj, _ = trajectory(5)
    p = tmp_path / "s.out"
    write_sbet(p, traj)
    raw = bytearray(p.read_bytes())
    (tmp_path / "short.out").write_bytes(raw[:-8])
    with pytest.raises(InputError, match=r"short.out: record 5: file size 672 bytes is not a "
                                         r"multiple of 136"):
        read_sbet(tmp_path / "short.out")
    rec = np.frombuffer(bytes(raw), dtype=SBET_DTYPE).copy()
    rec["time"][3] = rec["time"][2]
    rec.tofile(tmp_path / "dup.out")
    with pytest.raises(InputError, match=r"dup.out: record 4: duplicated epoch"):
        read_sbet(tmp_path / "dup.out")
    rec = np.frombuffer(bytes(raw), dtype=SBET_DTYPE).copy()
    rec["lat"][1] = 30.5                        # degrees written as radians
    rec.tofile(tmp_path / "deg.out")
    with pytest.raises(InputError, match=r"deg.out: record 2: latitude 30.5"):
        read_sbet(tmp_path / "deg.out")
    rec = np.frombuffer(bytes(raw), dtype=SBET_DTYPE).copy()
    rec["roll"][4] = np.nan
    rec.tofile(tmp_path / "nan.out")
    with pytest.raises(InputError, match=r"nan.out: record 5: non-finite"):
        read_sbet(tmp_path / "nan.out")
    # an SMRMSG given as a trajectory: named
    write_smrmsg(tmp_path / "smrmsg.out", [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], np.ones((7, 3)),
                 np.ones((7, 3)), np.ones((7, 3)))
    with pytest.raises(InputError, match="SMRMSG accuracy file"):
        read_trajectory(tmp_path / "smrmsg.out")


def test_detection_and_compare(tmp_path, capsys):
    traj, _ = trajectory(200)
    nav = tmp_path / "t.nav"
    write_nav(nav, traj)
    sb = tmp_path / "t.bin"                        # no telling extension: by content
    write_sbet(sb, traj)
    assert trajectory_format(sb) == "sbet" and is_sbet(sb)
    assert trajectory_format(nav) == "nav" and not is_sbet(nav)
    assert trajectory_format(tmp_path / "x.out") == "sbet"
    assert main(["compare", str(sb), str(nav)]) == 0
    out = capsys.readouterr().out
    assert "200 common epochs" in out
    rms_line = [ln for ln in out.splitlines() if ln.startswith("horizontal mm")][0]
    assert float(rms_line.split()[3]) < 1e-3          # RMS in mm: .nav rounding only


@pytest.mark.skipif(shutil.which("pdal") is None, reason="PDAL not installed")
def test_pdal_reads_our_sbet(tmp_path):
    traj, _ = trajectory(20)
    p = tmp_path / "sbet.sbet"
    write_sbet(p, traj)
    txt = tmp_path / "out.txt"
    subprocess.run(["pdal", "translate", "--reader", "readers.sbet", str(p), str(txt),
                    "--writers.text.order=GpsTime,Y,X,Z,Azimuth",
                    "--writers.text.precision=12", "--writers.text.keep_unspecified=false"],
                   check=True, capture_output=True)
    rows = np.loadtxt(txt, delimiter=",", skiprows=1)
    np.testing.assert_allclose(rows[:, 0], traj.time)
    # PDAL reports the angles in degrees
    np.testing.assert_allclose(rows[:, 1], np.rad2deg(traj.lla[:, 0]), atol=1e-9)
    np.testing.assert_allclose(rows[:, 3], traj.lla[:, 2], atol=1e-9)


@pytest.fixture(scope="module")
def flight():
    from test_filter import short_flight
    return short_flight()


def test_eo_reads_sbet(flight, tmp_path):
    """photogrammetry eo on the flight's truth as SBET gives the EO of truth.nav (the .nav
    is rounded to 1e-12 deg and 1e-9 deg; the SBET holds the doubles)."""
    from ins.io.navfiles import read_nav
    from photogrammetry.cli.main import main as pg_main
    from photogrammetry.orientation.exposure import read_eo_csv
    sbet = tmp_path / "truth.out"
    write_sbet(sbet, read_nav(flight / "truth.nav"))
    assert pg_main(["eo", str(flight), "-q", "-o", str(tmp_path / "nav.csv")]) == 0
    assert pg_main(["eo", str(flight), "--trajectory", str(sbet), "-q",
                    "-o", str(tmp_path / "sbet.csv")]) == 0
    a, b = read_eo_csv(tmp_path / "nav.csv"), read_eo_csv(tmp_path / "sbet.csv")
    assert a.image_id == b.image_id
    np.testing.assert_allclose(b.position, a.position, rtol=0, atol=1e-5)
    np.testing.assert_allclose(b.angles, a.angles, rtol=0, atol=1e-9)
