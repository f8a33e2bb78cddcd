"""RTK/INS on the real GEONET pair (../shared/real/rtklib_static_pair: rover 0759, base
3040, 3.3 km, Trimble 5700, GPS L1 C/A + L1 carrier, an hour at 30 s) with a static
tactical IMU written at the rover (the IMU is simulated; the GNSS is real).

The rover's file gets three windows of 10 minutes with only its 4, 3 and 2 highest
satellites (the others removed from the RINEX, as a partial outage does), then:

- loose: RTKLIB's kinematic PPK of the masked rover file as the GNSS log;
- tight code: the code and Doppler double differences (``carrier_phase = false``);
- tight RTK: code, Doppler and carrier double differences with LAMBDA (the default);

each forward and smoothed, horizontal RMS at the rover's epochs (every 30 s; the
forward solution coasts on the INS between them) against RTKLIB's static solution of
the unmasked pair (the reference: its fixed static position) in each window and over
the hour.  The IMU's heading is given 3 deg off ([initial] rpy_deg); its errors are the
simulator's tactical grade.

    .venv/bin/python bench/bench_rtk_static_pair.py [--keep DIR]
"""
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"
ROVER, BASE, NAV = (PAIR / n for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
#: (start min after the first epoch, length min, satellites kept)
WINDOWS = ((10.0, 10.0, 4), (25.0, 10.0, 3), (40.0, 10.0, 2))
IMU_RATE_HZ = 50.0
HEADING_DEG, HEADING_ERROR_DEG = 30.0, 3.0


def reference():
    """RTKLIB's static solution of the pair: the rover antenna, ECEF m, and its lla."""
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.nav.earth import lla_to_ecef
    with tempfile.TemporaryDirectory() as tmp:
        st = solve(str(ROVER), str(NAV), str(Path(tmp) / "static.pos"), base=str(BASE),
                   options=RtklibOptions(systems=("gps",), mode="static",
                                         direction="forward"))
    lla = st.log.lla[-1]
    return lla_to_ecef(*lla), lla


def static_imu(lla, t0, t1, path, seed=7):
    """A tactical IMU at rest at ``lla`` (rad, m) from ``t0`` to ``t1`` (GPS s of week),
    heading :data:`HEADING_DEG`, level: exact increments of the Earth rate and gravity
    in the body, then the simulator's tactical errors; written as KF-GINS text."""
    from ins.io.imu_files import write_kfgins_text
    from ins.nav import earth
    from ins.nav.imu import ImuLog
    from ins.nav.rotation import euler_to_dcm
    from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
    C_nb = euler_to_dcm(np.deg2rad([0.0, 0.0, HEADING_DEG]))
    w_b = C_nb.T @ earth.earth_rate_n(lla[0])
    f_b = C_nb.T @ -earth.gravity_n(lla[0], lla[2])
    t = np.arange(t0, t1 + 0.5 / IMU_RATE_HZ, 1.0 / IMU_RATE_HZ)
    dt = 1.0 / IMU_RATE_HZ
    log = ImuLog(t, np.tile(w_b * dt, (len(t), 1)), np.tile(f_b * dt, (len(t), 1)))
    log = apply_errors(log, ImuErrorModel.preset("tactical"), seed)
    write_kfgins_text(str(path), log)


def masked_rover(r_e, out):
    """The rover's RINEX 2 file with, in each window, only its highest satellites."""
    from ins.gnss.raw_epochs import read_raw_epochs
    from ins.estimation.coupling.pseudorange import line_of_sight
    import pymap3d
    raw = read_raw_epochs(str(ROVER), str(NAV), r_e)
    lla = np.array(pymap3d.ecef2geodetic(*r_e, deg=False))
    t_first = raw.time[0]
    keep = {}
    for k, t in enumerate(raw.time):
        for a, b, n in WINDOWS:
            if t_first + 60 * a <= t < t_first + 60 * (a + b):
                el = line_of_sight(raw.sat_pos_e[k], lla)[1]
                keep[round(t, 3)] = {raw.names[k][i] for i in np.argsort(-el)[:n]}
    lines = ROVER.read_text().splitlines()
    head = next(i for i, s in enumerate(lines) if "END OF HEADER" in s) + 1
    n_types = next(int(s[:6]) for s in lines if "# / TYPES OF OBSERV" in s)
    per_sat = (n_types + 4) // 5
    out_lines, i = lines[:head], head
    while i < len(lines):
        h = lines[i]
        n = int(h[29:32])
        if h[28] not in " 01":           # an event (header records follow): as it is
            out_lines += lines[i:i + 1 + n]
            i += 1 + n
            continue
        sats = "".join(lines[i + j][32:68] for j in range((n + 11) // 12))
        sats = [sats[3 * j:3 * j + 3].replace(" ", "0") for j in range(n)]
        body = lines[i + (n + 11) // 12: i + (n + 11) // 12 + n * per_sat]
        i += (n + 11) // 12 + n * per_sat
        yy, mo, dd, hh, mi, ss = (float(v) for v in h[:26].split())
        sow = ((dd - 2) * 86400 + 6 * 86400 + hh * 3600 + mi * 60 + ss)   # 2005-04-02 Sat
        kept = keep.get(round(sow, 3))
        sel = [j for j, s in enumerate(sats) if kept is None or s in kept]
        ids = "".join(sats[j] for j in sel)
        chunks = [ids[k:k + 36] for k in range(0, max(len(ids), 1), 36)]
        out_lines.append(f"{h[:29]}{len(sel):3d}{chunks[0]}")
        out_lines += [" " * 32 + c for c in chunks[1:]]
        for j in sel:
            out_lines += body[j * per_sat:(j + 1) * per_sat]
    out.write_text("\n".join(out_lines) + "\n")
    return raw.time[0], raw.time


def run(folder, name, coupling, carrier, lla):
    from ins.estimation.pipeline.config import load_config
    from ins.estimation.pipeline.process import process
    deg = np.rad2deg(lla)
    cfg_path = folder / f"{name}.toml"
    cfg_path.write_text(
        f'[files]\nimu = "imu.txt"\nrover = "rover_masked.obs"\nbase = "{BASE}"\n'
        f'nav = ["{NAV}"]\n'
        f'[rtklib]\nmode = "kinematic"\nsystems = ["gps"]\n'
        f'[gnss]\ncoupling = "{coupling}"\ncarrier_phase = {str(carrier).lower()}\n'
        f'[initial]\nrpy_deg = [0.0, 0.0, {HEADING_DEG + HEADING_ERROR_DEG}]\n'
        f'vel_ned_mps = [0.0, 0.0, 0.0]\n'
        f'[imu_noise]\narw_deg_sqrth = 0.12\nvrw_mps_sqrth = 0.05\ngyro_bias_std_dph = 2.0\n'
        f'accel_bias_std_mgal = 1500.0\ngyro_scale_std_ppm = 500.0\n'
        f'accel_scale_std_ppm = 500.0\n')
    cfg = load_config(str(cfg_path))
    tic = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = process(cfg, accept_poor=True)
    return res, time.perf_counter() - tic


def horizontal(traj, lla, epochs=None):
    """Times, horizontal and vertical errors (m) of ``traj`` against ``lla``, at the
    rover's epochs (``epochs``, s) or at every row."""
    from ins.nav import earth
    t, lla_t = traj.time, traj.lla
    if epochs is not None:
        j = np.clip(np.searchsorted(t, np.asarray(epochs) - 1e-6), 0, len(t) - 1)
        t, lla_t = t[j], lla_t[j]
    d = earth.ned_offset(np.broadcast_to(lla, lla_t.shape), lla_t)
    return t, np.hypot(d[:, 0], d[:, 1]), d[:, 2]


def main(keep=None):
    r_e, lla = reference()
    folder = Path(keep or tempfile.mkdtemp(prefix="rtk-pair-"))
    folder.mkdir(parents=True, exist_ok=True)
    t_first, epochs = masked_rover(r_e, folder / "rover_masked.obs")
    static_imu(lla, t_first - 5.0, t_first + 3600.0, folder / "imu.txt")
    print(f"# GEONET 0759 - 3040, reference: RTKLIB static {np.rad2deg(lla[:2])} deg "
          f"{lla[2]:.3f} m; windows (start min, min, satellites) {WINDOWS}")
    print("| run | " + " | ".join(f"{n} sats fwd / smoothed" for *_, n in WINDOWS)
          + " | hour fwd / smoothed | vertical smoothed | fix rate | slips | time s |")
    print("|---|" + "---|" * (len(WINDOWS) + 5))
    for name, coupling, carrier in (("loose", "loose", False), ("tight code", "tight", False),
                                    ("tight RTK", "tight", True)):
        res, dt = run(folder, name.replace(" ", "_"), coupling, carrier, lla)
        cells, hour, vert = [], [], None
        for traj in (res.forward, res.smoothed):
            t, h, v = horizontal(traj, lla, epochs)
            rms = lambda m: float(np.sqrt(np.mean(h[m] ** 2)))    # noqa: E731
            cells.append([rms((t >= t_first + 60 * a) & (t < t_first + 60 * (a + b)))
                          for a, b, _ in WINDOWS])
            hour.append(rms(t >= t_first))
            vert = float(np.sqrt(np.mean(v[t >= t_first] ** 2)))
        c = res.counts
        print(f"| {name} | " + " | ".join(f"{f:.3f} / {s:.3f}" for f, s in zip(*cells))
              + f" | {hour[0]:.3f} / {hour[1]:.3f} | {vert:.3f} | "
              f"{c.get('fix_rate', '-')} | {c.get('cycle_slips', '-')} | {dt:.1f} |")
    if keep is None:
        import shutil
        shutil.rmtree(folder)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(args[args.index("--keep") + 1] if "--keep" in args else None)
