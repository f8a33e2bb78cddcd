"""The simulated flight folder: every product of a plan, and ``manifest.toml`` naming them.

:func:`simulate_flight` runs the whole simulator (truth, IMU with sensor errors, GNSS
antenna log, mount angles, exposures, true EO, terrain, tie points) and writes the folder
of ``docs/interfaces.md``.  The folder is built aside and swapped into place whole
(:func:`ins.fileio.output_folder`, the rule of every command that writes a folder): a
non-empty folder is refused unless ``force=True``, and replaced only once the new one is
complete, so a failure or Ctrl-C leaves no partial output and the old folder untouched.

Reproducibility: every random product draws from its own generator, derived from the
seed and the product's name (:func:`product_seed`), so the same seed gives the same
bytes and changing, e.g., the GNSS rate leaves the IMU noise unchanged.
"""
import os
import tomllib
import zlib
from pathlib import Path

import numpy as np
import tomli_w

from .. import _textio
from ..errors import InputError
from ..fileio import atomic_open, check_output_folder, output_folder
from ..gnss import write_gnss
from ..imu import write_kfgins_text
from ..trajectory import Trajectory, write_nav
from .exposures import event_times, true_exposures
from .gnss import gnss_times, simulate_gnss
from .terrain import make_terrain
from .tiepoints import simulate_tiepoints

__all__ = ["simulate_flight", "product_seed", "product_rng", "FORMAT", "FILES"]

#: Value of the manifest's ``format`` key.
FORMAT = "insphoto-flight/1"
#: Manifest ``[files]`` key -> file name.
FILES = {"imu": "imu.txt", "gnss": "gnss.txt", "mount": "mount.txt", "truth": "truth.nav",
         "events": "events.csv", "camera": "camera.toml", "eo_true": "eo_true.csv",
         "eo_true_omega_phi_kappa": "eo_true_omega-phi-kappa.csv",
         "tiepoints": "tiepoints.csv", "ground_points": "ground_points.csv"}
MOUNT_HEADER = (b"# time_s roll_deg pitch_deg yaw_deg  (platform p relative to aircraft a: "
                b"C_ap = Rz(yaw) Ry(pitch) Rx(roll))\n")
#: IMU epochs per truth chunk written to truth.nav.
TRUTH_CHUNK = 50_000


def product_seed(seed, name):
    """Seed (int) of the random product ``name`` ("imu", "gnss", ...) of flight ``seed``."""
    ss = np.random.SeedSequence(int(seed), spawn_key=(zlib.crc32(name.encode()),))
    return int(ss.generate_state(1, np.uint64)[0])


def product_rng(seed, name):
    """``numpy.random.Generator`` of the random product ``name`` of flight ``seed``."""
    return np.random.default_rng(product_seed(seed, name))


# ---------------------------------------------------------------------------------------
# small writers

def _write_bytes(path, data):
    with atomic_open(path, "wb") as f:
        f.write(data)


def _csv_rows(ids, values, decimals):
    """Lines ``id,v1,v2,...`` (bytes): string ids, fixed-point numbers."""
    if len(ids) == 0:
        return b""
    text = _textio.format_fixed(values, np.asarray(decimals, np.int64), sep=",").tobytes()
    lines = text.split(b"\n")[:-1]
    return b"".join(i.encode() + b"," + line + b"\n" for i, line in zip(ids, lines))


def _frame_text(exposures):
    from photogrammetry.mapping import EnuFrame
    return EnuFrame(*exposures.origin_lla).header()


def _write_eo(path, exposures, system):
    """EO CSV of ``docs/interfaces.md`` (:func:`photogrammetry.exposure.write_eo_csv`)."""
    from photogrammetry.exposure import ExposureOrientation, write_eo_csv
    eo = ExposureOrientation(exposures.image_id, exposures.time, exposures.X_m,
                             exposures.angles(system), system, _frame_text(exposures))
    write_eo_csv(path, eo, comments=("true exterior orientation of the simulated flight",))


def _write_events(path, exposures):
    _write_bytes(path, b"image_id,time_s\n" + _csv_rows(exposures.image_id,
                                                       exposures.time[:, None], [6]))


def _write_tiepoints(path, tp, exposures, pixel_size_mm):
    header = (f"# tie points: observed photo coordinates (mm, origin at the principal point, "
              f"distorted as in camera.toml) with white Gaussian noise sigma_px = "
              f"{tp.sigma_px:g} (sigma_mm = {tp.sigma_px * pixel_size_mm:g}) per "
              f"coordinate\nimage_id,point_id,x_mm,y_mm\n")
    ids = [exposures.image_id[i] for i in tp.image_index]
    values = np.column_stack([tp.point_id, tp.xy_mm])
    _write_bytes(path, header.encode() + _csv_rows(ids, values, [0, 7, 7]))


def _write_ground(path, tp, exposures):
    header = (f"# ground truth of the tie points, mapping frame {_frame_text(exposures)}\n"
              "point_id,X_m,Y_m,Z_m\n")
    text = _textio.format_fixed(np.column_stack([tp.ground_id, tp.ground_m]),
                                np.array([0, 6, 6, 6], np.int64), sep=",").tobytes()
    _write_bytes(path, header.encode() + text)


def _write_mount(path, truth, rate_hz):
    """mount.txt at whole multiples of ``1 / rate_hz`` (evaluated in chunks)."""
    time = np.arange(np.ceil(truth.t_start * rate_hz - 1e-9),
                     np.floor(truth.t_end * rate_hz + 1e-9) + 1) / rate_hz
    decimals = np.array([6, 10, 10, 10], np.int64)
    with atomic_open(path, "wb") as f:
        f.write(MOUNT_HEADER)
        for k in range(0, len(time), TRUTH_CHUNK):
            t = time[k:k + TRUTH_CHUNK]
            rpy = np.rad2deg(truth.evaluate(t).mount_rpy)
            f.write(_textio.format_fixed(np.column_stack([t, rpy]), decimals).tobytes())


def _truth_pieces(truth, time, progress, first):
    """Trajectory pieces of the truth at ``time``; ``first`` receives the first epoch."""
    for k in range(0, len(time), TRUTH_CHUNK):
        s = truth.evaluate(time[k:k + TRUTH_CHUNK])
        piece = Trajectory(s.time, s.lla, s.v_n, s.q_nb)
        if k == 0:
            first.append(Trajectory(*(a[:1] for a in (s.time, s.lla, s.v_n, s.q_nb))))
        yield piece
        progress(min(k + TRUTH_CHUNK, len(time)))


# ---------------------------------------------------------------------------------------
# the flight

def _plan_and_text(plan):
    """(FlightPlan, bytes of its TOML file) from a path or a FlightPlan read from a file."""
    from .plan import FlightPlan, load_plan, parse_plan
    if isinstance(plan, FlightPlan):
        path = plan.source
        try:
            text = Path(path).read_bytes()
        except OSError:
            raise InputError("the plan's source file cannot be read: pass the plan's path",
                             path=path) from None
        if parse_plan(tomllib.loads(text.decode("utf-8")), source=path) != plan:
            raise InputError("the plan differs from its source file: pass the plan's path",
                             path=path)
        return plan, text
    path = os.fspath(plan)
    loaded = load_plan(path)
    return loaded, Path(path).read_bytes()


class _Stages:
    """One ``progress(done, total)`` over the stages, counted in IMU epochs."""

    def __init__(self, progress, n_epochs):
        self.progress, self.n = progress, max(int(n_epochs), 1)
        self.weights = {"imu": 1.0, "truth": 1.0, "rest": 0.5}
        self.total = int(sum(self.weights.values()) * self.n)
        self.base = 0

    def stage(self, name):
        """``callback(done, total=None)`` of one stage (``done`` out of its own total)."""
        start = self.base
        span = int(self.weights[name] * self.n)
        self.base += span

        def callback(done, total=None):
            if self.progress is not None:
                frac = done / (total if total else self.n)
                self.progress(start + int(span * min(frac, 1.0)), self.total)
        return callback

    def done(self):
        if self.progress is not None:
            self.progress(self.total, self.total)


def _camera_of(plan):
    from photogrammetry.camera import CameraMounting, FrameCamera
    c = plan.camera
    camera = FrameCamera(c.focal_length_mm, c.pixel_size_mm, c.width_px, c.height_px,
                         c.principal_point_px, c.radial_k, c.tangential_p)
    mounting = CameraMounting(axes=np.array(c.axes), lever_arm_m=np.array(c.lever_arm_m),
                              boresight_rad=np.deg2rad(c.boresight_deg))
    return camera, mounting


def simulate_flight(plan, out_dir, seed, grade=None, force=False, progress=None):
    """Simulate a survey flight and write its folder (``docs/interfaces.md``).

    Parameters
    ----------
    plan : str, os.PathLike or ins.simulate.plan.FlightPlan
        The TOML flight plan (copied verbatim to ``plan.toml``); a FlightPlan must have
        been read from a file (its ``source``), which is copied.
    out_dir : str or os.PathLike
        The flight folder to create.  Its parent must exist; an existing non-empty folder
        is replaced only with ``force=True``, after the new one is complete.
    seed : int
        Seed of every random product (>= 0); the same seed gives the same bytes.
    grade : {"navigation", "tactical", "mems"}, optional
        IMU grade replacing the plan's ``[imu] grade`` (the plan's per-item overrides
        still apply).
    force : bool
        Replace a non-empty ``out_dir``.
    progress : callable, optional
        ``progress(done, total)``.

    Returns
    -------
    pathlib.Path
        ``out_dir``.

    Raises
    ------
    InputError
        A bad plan (naming the key), a bad seed or grade.
    FileNotFoundError, NotADirectoryError, FileExistsError, PermissionError
        An output folder that cannot be written (naming ``out_dir``): missing parent, a
        file in the way, not empty without ``force``.
    """
    from .sensor_errors import PRESETS
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    if grade is not None and grade not in PRESETS:
        raise InputError(f"unknown IMU grade {grade!r} (expected one of {', '.join(PRESETS)})")
    out_dir = Path(out_dir)
    check_output_folder(out_dir, force)            # before the work, not only after it
    plan, plan_text = _plan_and_text(plan)
    with output_folder(out_dir, force) as tmp:
        _write_products(plan, plan_text, Path(tmp), int(seed), grade or plan.imu.grade,
                        progress)
    return out_dir


def _write_products(plan, plan_text, folder, seed, grade, progress):
    from .truth import build_truth
    truth = build_truth(plan)
    stages = _Stages(progress, (truth.t_end - truth.t_start) * plan.imu.rate_hz + 1)
    log, model, first = _write_imu_and_truth(plan, truth, folder, seed, grade, stages)
    rest = stages.stage("rest")
    files = _write_gnss_and_mount(plan, truth, folder, seed)
    rest(0.2, 1.0)
    exposures, tp = _write_images(plan, truth, folder, seed, rest)
    _write_bytes(folder / "plan.toml", plan_text)
    manifest = _manifest(plan, truth, first, log, model, files, seed, grade, len(exposures),
                         len(tp))
    _write_bytes(folder / "manifest.toml", tomli_w.dumps(manifest).encode())
    stages.done()


def _write_imu_and_truth(plan, truth, folder, seed, grade, stages):
    """imu.txt (with the sensor errors) and truth.nav; returns the log, the error model
    and the first truth epoch."""
    from .imu_synth import synthesize_imu
    from .sensor_errors import ImuErrorModel, apply_errors
    log = synthesize_imu(truth, plan.imu.rate_hz, progress=stages.stage("imu"))
    model = ImuErrorModel.preset(grade, **plan.imu.overrides)
    log = apply_errors(log, model, product_seed(seed, "imu"))
    write_kfgins_text(folder / FILES["imu"], log)
    first = []
    write_nav(folder / FILES["truth"],
              _truth_pieces(truth, log.time, stages.stage("truth"), first),
              week=plan.flight.gps_week)
    return log, model, first[0]


def _write_gnss_and_mount(plan, truth, folder, seed):
    """gnss.txt and (mount enabled) mount.txt; returns the manifest's [files]."""
    m, g = plan.mount, plan.gnss
    gnss = simulate_gnss(truth, gnss_times(truth.t_start, truth.t_end, g.rate_hz, g.outages),
                         m.l_bp, m.l_ap, g.sigma_ned, product_rng(seed, "gnss"),
                         velocity=g.velocity, sigma_vel_mps=g.sigma_vel)
    write_gnss(folder / FILES["gnss"], gnss)
    files = dict(FILES)
    if m.enabled:
        _write_mount(folder / FILES["mount"], truth, m.log_rate_hz)
    else:
        del files["mount"]
    return files


def _write_images(plan, truth, folder, seed, rest):
    """camera.toml, events, true EO, tie points and ground points."""
    from photogrammetry.camera import write_camera
    camera, mounting = _camera_of(plan)
    write_camera(folder / FILES["camera"], camera, mounting)
    b = plan.block
    origin = np.array([b.origin_lat, b.origin_lon, b.origin_h])
    exposures = true_exposures(truth, *event_times(truth.strips, plan.exposure_interval_s),
                               mounting.C_bc, mounting.lever_arm_m, origin)
    _write_events(folder / FILES["events"], exposures)
    _write_eo(folder / FILES["eo_true"], exposures, "phi-omega-kappa")
    _write_eo(folder / FILES["eo_true_omega_phi_kappa"], exposures, "omega-phi-kappa")
    rest(0.4, 1.0)
    t = plan.terrain
    terrain = make_terrain(t.relief_m, t.wavelength_m,
                           product_rng(seed, f"terrain/{t.seed_offset}"))
    tp = simulate_tiepoints(exposures, camera, terrain, plan.tie_points.per_image,
                            plan.tie_points.sigma_px, product_rng(seed, "tiepoints"),
                            progress=lambda d, n: rest(0.4 + 0.5 * d / max(n, 1), 1.0))
    _write_tiepoints(folder / FILES["tiepoints"], tp, exposures, camera.pixel_size_mm)
    _write_ground(folder / FILES["ground_points"], tp, exposures)
    return exposures, tp


def _floats(v):
    return [float(x) for x in v]


def _tidy(v):
    """Round unit conversions' last-bit noise (0.11999999999999998 -> 0.12)."""
    if isinstance(v, list):
        return [_tidy(x) for x in v]
    return float(f"{v:.12g}")


def _manifest(plan, truth, s0, log, model, files, seed, grade, n_images, n_obs):
    b, m, g = plan.block, plan.mount, plan.gnss
    rpy = s0.rpy(degrees=True)[0]
    return {
        "format": FORMAT,
        "flight": {"seed": seed, "grade": grade, "gps_week": plan.flight.gps_week,
                   "start_time_s": float(log.time[0]), "end_time_s": float(log.time[-1]),
                   "imu_rate_hz": float(plan.imu.rate_hz), "plan": "plan.toml",
                   "n_images": n_images, "n_tiepoint_observations": n_obs},
        "files": files,
        "frames": {
            "imu": "FRD body on the stabilized platform (b = p)",
            "n": "NED local level at the IMU",
            "a": "aircraft FRD (mount base; GNSS antenna on it)",
            "c": "camera: x, y image axes (x right, y up), z opposite to the view; "
                 "ray (x, y, -f)",
            "m": "ENU at block origin",
            "gnss": "antenna phase centre, WGS84 lat/lon deg, ellipsoidal h m",
            "truth": "IMU centre, .nav layout (week, time, lat, lon deg, h m, vN vE vD m/s, "
                     "roll pitch yaw deg)",
            "mount": "platform p relative to aircraft a: C_ap = Rz(yaw) Ry(pitch) Rx(roll)"},
        "mapping_frame": {"type": "enu", "origin_lat_deg": float(np.rad2deg(b.origin_lat)),
                          "origin_lon_deg": float(np.rad2deg(b.origin_lon)),
                          "origin_h_m": float(b.origin_h)},
        "lever_arm": {"imu_to_platform_centre_b_m": _floats(m.l_bp),
                      "platform_centre_to_antenna_a_m": _floats(m.l_ap)},
        "mount": {"enabled": bool(m.enabled), "log_rate_hz": float(m.log_rate_hz)},
        "imu": {k: _tidy(v) for k, v in model.to_units().items()},
        "gnss": {"rate_hz": float(g.rate_hz), "sigma_ned_m": _floats(g.sigma_ned),
                 "velocity": bool(g.velocity), "sigma_vel_mps": float(g.sigma_vel),
                 "outages": [_floats(o) for o in g.outages]},
        "tie_points": {"sigma_px": float(plan.tie_points.sigma_px),
                       "per_image": int(plan.tie_points.per_image)},
        "initial": {"lat_deg": float(np.rad2deg(s0.lla[0, 0])),
                    "lon_deg": float(np.rad2deg(s0.lla[0, 1])), "h_m": float(s0.lla[0, 2]),
                    "vel_ned_mps": _floats(s0.v_n[0]), "rpy_deg": _floats(rpy)},
        "stationary": {"segments_s": [_floats(seg) for seg in truth.stationary],
                       "static": plan.flight.start == "ground"},
    }
