"""Write the corpus of broken inputs in this folder (deterministic; run once, commit).

    python tests/data/bad/make_corpus.py

Every file is small (a few KB at most) and holds ONE defect, described in README.md.
The valid rows they are made from use the time scale of tests/data/flights/short.toml
(GPS seconds of week from 200000.0 s) so that the files can stand in for the simulated
flight's files.
"""
import hashlib
import os

HERE = os.path.dirname(os.path.abspath(__file__))

# static IMU at 30.5 deg latitude, level, heading north, 200 Hz: increments per 5 ms
IMU_ROW = "3.1416e-07 0 -1.8511e-07 0 0 -0.048966"
IMU_T0, IMU_DT, IMU_N = 200000.0, 0.005, 120


def _imu_rows(n=IMU_N, row=IMU_ROW):
    return [f"{IMU_T0 + k * IMU_DT:.3f} {row}" for k in range(n)]


def _gnss_rows(n=10):
    rows = []
    for k in range(n):
        t = 200000.0 + 0.5 * k
        rows.append(f"{t:.3f} 30.499294 {114.295389 + 2.56e-4 * k:.6f} 321.732 0.02 0.02 0.04 "
                    f"8.70 49.24 -0.30 0.01 0.01 0.01")
    return rows


def _mount_rows(n=50, dt=0.02):
    return [f"{200000.0 + k * dt:.2f} 0.26 -0.25 -8.59" for k in range(n)]


def _nav_rows(n=20):
    return [f"2300 {200000.0 + 0.01 * k:.6f} 30.499295 {114.295384 + 5.13e-6 * k:.9f} 320.052 "
            f"8.682 49.240 -0.312 -0.154 -0.014 80.056" for k in range(n)]


def _garbage(n=512, seed=b"insphoto bad corpus"):
    out, h = b"", seed
    while len(out) < n:
        h = hashlib.sha256(h).digest()
        out += h
    return out[:n]


def _lines(rows):
    return "\n".join(rows) + "\n"


def _swap(rows, i):
    rows = list(rows)
    rows[i], rows[i + 1] = rows[i + 1], rows[i]
    return rows


def _set_field(rows, i, j, value):
    rows = list(rows)
    parts = rows[i].split(" ")
    parts[j] = value
    rows[i] = " ".join(parts)
    return rows


MOUNT_HEADER = ("# time_s roll_deg pitch_deg yaw_deg  (platform p relative to aircraft a: "
                "C_ap = Rz(yaw) Ry(pitch) Rx(roll))")
EO_HEAD = ["# insphoto exterior orientation", "# system = phi-omega-kappa",
           "# frame = enu; origin_lat_deg = 30.5; origin_lon_deg = 114.3; origin_h_m = 20.0",
           "# units: time_s GPS seconds of week; X Y Z m; angles deg; sigmas in the same units"]
EO_COLS = "image_id,time_s,X_m,Y_m,Z_m,phi_deg,omega_deg,kappa_deg"
EO_ROWS = ["S01_001,200009.240000,-0.5,-92.3,320.1,0.01,0.02,-10.0",
           "S01_002,200010.200000,46.8,-84.0,320.3,0.01,0.02,-10.0",
           "S01_003,200011.160000,94.1,-75.6,320.2,0.01,0.02,-10.0"]
TP_HEAD = ["# tie points: sigma_px = 0.5", "image_id,point_id,x_mm,y_mm"]
TP_ROWS = ["S01_001,61,-8.6960822,-6.1555160", "S01_001,62,-6.0922785,-6.7036137",
           "S01_002,61,-3.1000000,-6.2000000", "S01_002,62,-0.5000000,-6.8000000"]
CAMERA = """[camera]
model = "frame"
focal_length_mm = 50.0
pixel_size_mm = 0.005
width_px = 4000
height_px = 3000
principal_point_px = [1999.5, 1499.5]
radial_k = [0.0, 0.0, 0.0]
tangential_p = [0.0, 0.0]

[mounting]
axes = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
lever_arm_m = [0.05, 0.1, 0.15]
boresight_deg = [0.0, 0.0, 0.0]
"""
FISHEYE = """[camera]
model = "fisheye-equisolid"
focal_length_px = 800.0
width_px = 1600
height_px = 1600
principal_point_px = [799.5, 799.5]
radial_k = [0.0, 0.0, 0.0]
"""
TIMES = ["image_id,utc", "m000,2017-05-02T14:00:00Z", "m001,2017-05-02T14:01:00Z",
         "m002,2017-05-02T14:02:00Z", "m003,2017-05-02T14:03:00Z"]
CENTRES = ["image_id,u_px,v_px,sigma_px", "m000,900.1,700.2,0.1", "m001,901.3,699.0,0.1",
           "m002,902.4,697.9,0.1", "m003,903.6,696.7,0.1"]


def _text_files(plan_text, config_text):
    imu, gnss, mount, nav = _imu_rows(), _gnss_rows(), _mount_rows(), _nav_rows()
    gap = imu[:60] + imu[80:]
    rates = [f"{IMU_T0 + k * IMU_DT:.3f} 6.2832e-05 0 -3.7022e-05 0 0 -9.7932"
             for k in range(IMU_N)]
    files = {
        # IMU (KF-GINS text unless the extension says otherwise)
        "imu_truncated.txt": _lines(imu[:-1]) + imu[-1][:30],
        "imu_wrong_columns.txt": _lines([r.rsplit(" ", 1)[0] for r in imu]),
        "imu_nan.txt": _lines(_set_field(imu, 36, 6, "nan")),
        "imu_unsorted.txt": _lines(_swap(imu, 49)),
        "imu_duplicated.txt": _lines(imu[:60] + [imu[59]] + imu[60:]),
        "imu_gap.txt": _lines(gap),
        "imu_rates.txt": _lines(rates),
        "imu_header.txt": _lines(["time gx gy gz ax ay az"] + imu),
        "imu_one_epoch.txt": _lines(imu[:1]),
        "imu_bad_unit.csv": _lines(["time_ms,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,"
                                    "dvel_x_mps,dvel_y_mps,dvel_z_mps"]
                                   + [f"{1000 * IMU_T0 + 5 * k:.0f},{IMU_ROW.replace(' ', ',')}"
                                      for k in range(20)]),
        # GNSS (KF-GINS text, 13 columns)
        "gnss_zero_sigma.txt": _lines(_set_field(gnss, 3, 5, "0.0")),
        "gnss_wrong_columns.txt": _lines([" ".join(r.split(" ")[:9]) for r in gnss]),
        "gnss_nan.txt": _lines(_set_field(gnss, 5, 1, "NaN")),
        "gnss_unsorted.txt": _lines(_swap(gnss, 4)),
        "gnss_duplicated.txt": _lines(gnss[:5] + [gnss[4]] + gnss[5:]),
        "gnss_lat_lon_swapped.txt": _lines(
            [" ".join([p[0], p[2], p[1]] + p[3:]) for p in (r.split(" ") for r in gnss)]),
        "gnss_truncated.txt": _lines(gnss[:-1]) + gnss[-1][:25],
        # mount logs
        "mount_truncated.txt": _lines([MOUNT_HEADER] + mount[:-1]) + mount[-1][:12],
        "mount_wrong_columns.txt": _lines([MOUNT_HEADER] + [r.rsplit(" ", 1)[0] for r in mount]),
        "mount_nan.txt": _lines([MOUNT_HEADER] + _set_field(mount, 9, 2, "nan")),
        "mount_unsorted.txt": _lines([MOUNT_HEADER] + _swap(mount, 19)),
        "mount_arcsec.txt": _lines([MOUNT_HEADER] + [f"{200000.0 + k * 0.02:.2f} 936.0 -900.0 "
                                                     f"-30924.0" for k in range(50)]),
        "mount_stops_early.txt": _lines([MOUNT_HEADER] + _mount_rows(n=101, dt=0.1)),
        # .nav trajectories
        "nav_truncated.txt": _lines(nav[:-1]) + nav[-1][:40],
        "nav_wrong_columns.txt": _lines([r.rsplit(" ", 1)[0] for r in nav]),
        "nav_nan.txt": _lines(_set_field(nav, 7, 4, "nan")),
        "nav_unsorted.txt": _lines(_swap(nav, 11)),
        "nav_duplicated.txt": _lines(nav[:12] + [nav[11]] + nav[12:]),
        "nav_lat_lon_swapped.txt": _lines(
            [" ".join(p[:2] + [p[3], p[2]] + p[4:]) for p in (r.split(" ") for r in nav)]),
        # exposure events
        "events_no_header.csv": _lines(["S01_001,200009.24", "S01_002,200010.20"]),
        "events_text_time.csv": _lines(["image_id,time_s", "S01_001,200009.24",
                                        "S01_002,12:00:10"]),
        "events_nan.csv": _lines(["image_id,time_s", "S01_001,200009.24", "S01_002,nan"]),
        "events_duplicate_id.csv": _lines(["image_id,time_s", "S01_001,200009.24",
                                           "S01_001,200010.20"]),
        "events_outside_trajectory.csv": _lines(["image_id,time_s", "S01_001,200009.24",
                                                 "S01_002,300000.00"]),
        "events_truncated.csv": _lines(["image_id,time_s", "S01_001,200009.24"]) + "S01_0",
        # solution standard deviations (eo --sigma)
        "std_negative.txt": _lines([f"{200000.0 + k:.6f} 0.01 0.01 0.02 0.001 0.001 0.002 "
                                    f"{'-0.001' if k == 3 else '0.001'} 0.001 0.003"
                                    for k in range(6)]),
        # frame camera files
        "camera_missing_focal.toml": CAMERA.replace("focal_length_mm = 50.0\n", ""),
        "camera_negative_pixel.toml": CAMERA.replace("pixel_size_mm = 0.005",
                                                     "pixel_size_mm = -0.005"),
        "camera_truncated.toml": CAMERA[:CAMERA.index("principal_point_px") + 25],
        "camera_reflection_axes.toml": CAMERA.replace("[0, 0, -1]]", "[0, 0, 1]]"),
        "camera_lever_arm_typo.toml": CAMERA.replace("lever_arm_m =", "lever_arm ="),
        "camera_mount_table.toml": CAMERA.replace("[mounting]", "[mount]"),
        # EO CSV
        "eo_no_system.csv": _lines([EO_HEAD[0], EO_HEAD[2], EO_HEAD[3],
                                    "image_id,time_s,X_m,Y_m,Z_m,a_deg,b_deg,c_deg"]
                                   + EO_ROWS),
        "eo_wrong_columns.csv": _lines(EO_HEAD + [EO_COLS]
                                       + [r.rsplit(",", 1)[0] for r in EO_ROWS]),
        "eo_nan.csv": _lines(EO_HEAD + [EO_COLS, EO_ROWS[0], EO_ROWS[1].replace("0.02", "nan"),
                                        EO_ROWS[2]]),
        "eo_truncated.csv": _lines(EO_HEAD + [EO_COLS] + EO_ROWS[:2]) + EO_ROWS[2][:30],
        # tie points
        "tiepoints_unknown_image.csv": _lines(TP_HEAD + TP_ROWS + ["S09_999,61,1.0,2.0"]),
        "tiepoints_bad_header.csv": _lines(["image,point,x,y"] + TP_ROWS),
        "tiepoints_nan.csv": _lines(TP_HEAD + TP_ROWS[:2] + ["S01_002,61,nan,-6.2"]),
        "tiepoints_truncated.csv": _lines(TP_HEAD + TP_ROWS[:3]) + "S01_002,62,-0.5",
        "tiepoints_duplicate.csv": _lines(TP_HEAD + TP_ROWS + [TP_ROWS[1]]),
        # lunar heading
        "times_unsorted.csv": _lines(TIMES[:2] + [TIMES[3], TIMES[2]] + TIMES[4:]),
        "times_bad_utc.csv": _lines(TIMES[:3] + ["m002,02/05/2017 14:02"] + TIMES[4:]),
        "times_truncated.csv": _lines(TIMES[:4]) + "m003,2017-05-0",
        "centres_nan.csv": _lines(CENTRES[:3] + ["m002,nan,697.9,0.1"] + CENTRES[4:]),
        "centres_zero_sigma.csv": _lines(CENTRES[:2] + ["m001,901.3,699.0,0"] + CENTRES[3:]),
        "centres_unknown_image.csv": _lines(CENTRES + ["m999,904.8,695.5,0.1"]),
        "fisheye_missing_focal.toml": FISHEYE.replace("focal_length_px = 800.0\n", ""),
        "fisheye_unknown_key.toml": FISHEYE.replace("radial_k =", "radial_k_rad ="),
        # flight plans (ins simulate)
        "plan_truncated.toml": plan_text[:plan_text.index("sigma_ned_m = [") + 20],
        "plan_unknown_key.toml": plan_text.replace("ground_speed_mps = 50.0",
                                                   "ground_speed_mps = 50.0\nspeed_kt = 97"),
        "plan_misspelt_section.toml": plan_text.replace("[tie_points]", "[tiepoints]"),
        "plan_negative_speed.toml": plan_text.replace("ground_speed_mps = 50.0",
                                                      "ground_speed_mps = -50.0"),
        "plan_scanner_arcsec.toml": plan_text + (
            "\n[scanner]\npulse_rate_hz = 2000.0\nlever_arm_m = [0.1, 0.05, 0.2]\n"
            "boresight_arcsec = [360, -288, 540]   # the unit of boresight_deg\n"),
        # processing configs (ins process --config)
        "config_unknown_key.toml": config_text.replace("[imu_noise]",
                                                       "[imu_noise]\narw_dph = 0.003"),
        "config_negative_noise.toml": config_text.replace("arw_deg_sqrth = 0.003",
                                                          "arw_deg_sqrth = -0.003"),
        "config_truncated.toml": config_text[:config_text.index("[imu_noise]") + 30],
        # flight folder manifest without the GNSS file
        "manifest_missing_files.toml": 'format = "insphoto-flight/1"\n\n[files]\n'
                                       'imu = "imu.txt"\ntruth = "truth.nav"\n',
        # empty and comment-only files
        "empty.txt": "",
        "comments_only.txt": "# a header comment\n% another comment\n\n# nothing else\n",
    }
    return files


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
    with open(os.path.join(root, "tests", "data", "flights", "short.toml")) as f:
        plan_text = f.read()
    with open(os.path.join(root, "data", "configs", "kfgins_like.toml")) as f:
        config_text = f.read()
    for name, text in _text_files(plan_text, config_text).items():
        with open(os.path.join(HERE, name), "w", newline="\n") as f:
            f.write(text)
    with open(os.path.join(HERE, "garbage.bin"), "wb") as f:
        f.write(_garbage())
    import struct
    rows = [[IMU_T0 + k * IMU_DT, 3.1416e-07, 0.0, -1.8511e-07, 0.0, 0.0, -0.048966]
            for k in range(20)]
    data = b"".join(struct.pack("<7d", *r) for r in rows)
    with open(os.path.join(HERE, "imu_truncated.bin"), "wb") as f:
        f.write(data + data[:20])


if __name__ == "__main__":
    main()
