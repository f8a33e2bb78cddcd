"""The INS part of a simulated flight folder, and the hook for the products of others.

:func:`simulate_flight` runs the INS part of the simulator (truth, IMU with sensor
errors, GNSS antenna log, mount angles), writes ``imu.txt``, ``gnss.txt``, ``mount.txt``,
``truth.nav`` and ``plan.toml``, then calls each PRODUCT WRITER it is given and writes
``manifest.toml`` (:mod:`ins.simulate.manifest`) naming everything (``docs/interfaces.md``).

Product writers are how a package above ``ins`` adds its files without ``ins``
importing it (``ins`` never imports ``photogrammetry``: ``tests/test_layering.py``).
A writer is a callable ``writer(flight) -> dict``: ``flight`` is a :class:`FlightProducts`
(the plan, the truth, the folder being built, the seed and a progress callback); it
writes its files into ``flight.folder``, draws its random numbers from
``product_rng(flight.seed, name)``, and returns the manifest tables it adds
(``{"files": {...}, "flight": {...}, ...}``, merged by :func:`ins.simulate.manifest.merge`).
The complete folder of ``ins simulate`` (with exposures, true EO, terrain and tie points,
which need the camera model) is :func:`photogrammetry.simulate.folder.simulate_flight`,
this function with the image writer of :mod:`photogrammetry.simulate.images`; without
writers the folder holds the INS products only (enough for ``ins process``).

The folder is built aside and swapped into place whole (:func:`ins.common.fileio.output_folder`,
the rule of every command that writes a folder): a non-empty folder is refused unless
``force=True``, and replaced only once the new one is complete, so a failure or Ctrl-C
(also inside a product writer) leaves no partial output and the old folder untouched.

Reproducibility: every random product draws from its own generator, derived from the
seed and the product's name (:func:`product_seed`), so the same seed gives the same
bytes and changing, e.g., the GNSS rate leaves the IMU noise (and the tie points)
unchanged.
"""
import os
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import tomli_w
import tomllib

from ins.common import textformat
from ins.common.errors import InputError
from ins.common.fileio import atomic_open, check_output_folder, output_folder
from ins.io.gnss import write_gnss
from ins.io.imu_files import write_kfgins_text
from ins.io.navfiles import write_nav
from ins.nav.trajectory import Trajectory
from ins.simulate.gnss import gnss_times, simulate_gnss
from ins.simulate.manifest import FORMAT, ins_tables, merge

__all__ = ["simulate_flight", "FlightProducts", "product_seed", "product_rng", "write_bytes",
           "FORMAT", "FILES"]

#: Manifest ``[files]`` key -> file name of the INS products (``mount`` only with the
#: mount enabled).
FILES = {"imu": "imu.txt", "gnss": "gnss.txt", "mount": "mount.txt", "truth": "truth.nav"}
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

def write_bytes(path, data):
    """Write ``data`` (bytes) to ``path`` atomically (:func:`ins.common.fileio.atomic_open`)."""
    with atomic_open(path, "wb") as f:
        f.write(data)


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
            f.write(textformat.format_fixed(np.column_stack([t, rpy]), decimals).tobytes())


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
    from ins.simulate.plan_model import FlightPlan
    from ins.simulate.plan_read import load_plan, parse_plan
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


@dataclass(frozen=True)
class FlightProducts:
    """What a product writer of :func:`simulate_flight` is given.

    Attributes
    ----------
    plan : ins.simulate.plan_model.FlightPlan
        The flight plan (with its ``[camera]``, ``[terrain]``, ``[tie_points]``).
    truth : ins.simulate.truth.FlightTruth
        The true trajectory, evaluable at any time (``truth.evaluate(t)``).
    folder : pathlib.Path
        The folder being built (a hidden temporary beside the user's folder): write the
        product's files here, under the names the writer returns in ``[files]``.
    seed : int
        The flight's seed: draw from ``product_rng(seed, name)``, one name per product.
    progress : callable
        ``progress(fraction)``, 0 to 1, of the writer's own work.
    """

    plan: object
    truth: object
    folder: Path
    seed: int
    progress: Callable[[float], None]

    def rng(self, name):
        """``product_rng(seed, name)``: the generator of the product ``name``."""
        return product_rng(self.seed, name)


def simulate_flight(plan, out_dir, seed, grade=None, force=False, progress=None,
                    products=(), gnss_raw_nav=None):
    """Simulate the INS part of a survey flight (and the given products) into a folder.

    Parameters
    ----------
    plan : str, os.PathLike or ins.simulate.plan_model.FlightPlan
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
    products : sequence of callable
        Product writers ``writer(flight: FlightProducts) -> dict`` of manifest tables
        (module docstring), called in order after the INS products.  The complete flight
        folder of ``ins simulate`` is
        :func:`photogrammetry.simulate.folder.simulate_flight`.
    gnss_raw_nav : str or os.PathLike, optional
        RINEX GPS navigation file: write the raw observations (``rover.obs``, ``rover.nav``,
        ``receiver_clock.txt``, ``gnss_raw_truth.csv``: :mod:`ins.simulate.gnss_raw_product`)
        with the plan's ``[gnss_raw]`` settings or their defaults; replaces the plan's
        ``[gnss_raw] nav_file``.  Without it, the plan's ``[gnss_raw]`` (when present)
        decides.

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
    from ins.simulate.sensor_errors import PRESETS
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    if grade is not None and grade not in PRESETS:
        raise InputError(f"unknown IMU grade {grade!r} (expected one of {', '.join(PRESETS)})")
    out_dir = Path(out_dir)
    check_output_folder(out_dir, force)            # before the work, not only after it
    plan, plan_text = _plan_and_text(plan)
    raw = _raw_settings(plan, gnss_raw_nav)
    with output_folder(out_dir, force) as tmp:
        _write_products(plan, plan_text, Path(tmp), int(seed), grade or plan.imu.grade,
                        progress, tuple(products), raw)
    return out_dir


def _raw_settings(plan, nav):
    """The settings of the raw GPS observations (or None), with ``nav`` as nav_file."""
    if nav is None:
        return plan.gnss_raw
    from dataclasses import replace

    from ins.simulate.gnss_raw import RawSettings
    return replace(plan.gnss_raw or RawSettings(), nav_file=os.path.abspath(os.fspath(nav)))


def _write_products(plan, plan_text, folder, seed, grade, progress, products, raw=None):
    from ins.simulate.truth import build_truth
    truth = build_truth(plan)
    if raw is not None and raw.multi:    # several systems or signals: the same, checked
        from ins.simulate import gnss_multi_product
        gnss_multi_product.check_multi(raw, plan.source, plan.flight.gps_week, truth.t_start,
                                       truth.t_end)
        products = (lambda flight: gnss_multi_product.write_gnss_multi(
            flight, raw, product_rng(seed, "gnss_raw")),) + products
    elif raw is not None:                # the orbits must cover the flight: before the work
        from ins.simulate import gnss_raw_product
        gnss_raw_product.check_span(gnss_raw_product.load_orbits(raw, plan.source),
                                    plan.flight.gps_week, truth.t_start, truth.t_end)
        products = (lambda flight: gnss_raw_product.write_gnss_raw(
            flight, raw, product_rng(seed, "gnss_raw")),) + products
    stages = _Stages(progress, (truth.t_end - truth.t_start) * plan.imu.rate_hz + 1)
    log, model, first = _write_imu_and_truth(plan, truth, folder, seed, grade, stages)
    rest = stages.stage("rest")
    files = _write_gnss_and_mount(plan, truth, folder, seed)
    rest(0.2, 1.0)
    added = []
    if plan.scanner is not None:            # the plan's own LiDAR products
        from ins.simulate.lidar import write_lidar
        products = products + (write_lidar,)
    share = 0.8 / max(len(products), 1)
    for k, writer in enumerate(products):
        start = 0.2 + k * share
        flight = FlightProducts(plan, truth, folder, seed,
                                lambda f, start=start: rest(start + share * min(f, 1.0), 1.0))
        added.append(writer(flight))
    write_bytes(folder / "plan.toml", plan_text)
    manifest = merge(ins_tables(plan, truth, first, log, model, files, seed, grade), *added)
    write_bytes(folder / "manifest.toml", tomli_w.dumps(manifest).encode())
    stages.done()


def _write_imu_and_truth(plan, truth, folder, seed, grade, stages):
    """imu.txt (with the sensor errors) and truth.nav; returns the log, the error model
    and the first truth epoch."""
    from ins.simulate.imu_synth import synthesize_imu
    from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
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
                         m.l_bp, m.l_ap, g.sigma_ned_m, product_rng(seed, "gnss"),
                         velocity=g.velocity, sigma_vel_mps=g.sigma_vel_mps)
    write_gnss(folder / FILES["gnss"], gnss)
    files = dict(FILES)
    if m.enabled:
        _write_mount(folder / FILES["mount"], truth, m.log_rate_hz)
    else:
        del files["mount"]
    return files
