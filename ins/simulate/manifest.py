"""``manifest.toml`` of a simulated flight folder (``docs/interfaces.md``): the INS tables
and the merge of the tables that product writers add.

:func:`ins_tables` describes what :mod:`ins.simulate` writes (the IMU, GNSS, mount and
truth files, the frames of the trajectory, lever arms, the injected IMU errors, the
initial state, the stationary segments).  A product writer of another package (the
image products of :mod:`photogrammetry.simulate.images`: camera frame, mapping frame,
tie points) returns its own tables, which :func:`merge` adds.  The format fixes the order
of the tables and of the frames (:data:`TABLE_ORDER`, :data:`FRAME_ORDER`) so that the
file reads the same whoever wrote each part, and the same plan and seed give the same
bytes.
"""
import numpy as np

__all__ = ["FORMAT", "TABLE_ORDER", "FRAME_ORDER", "ins_tables", "merge"]

#: Value of the manifest's ``format`` key.
FORMAT = "insphoto-flight/1"
#: Order of the manifest's top-level keys in the format; keys of no product listed here
#: come last, in the order they were added.
TABLE_ORDER = ("format", "flight", "files", "frames", "mapping_frame", "lever_arm", "mount",
               "imu", "gnss", "tie_points", "scanner", "initial", "stationary")
#: Order of the frames in ``[frames]`` (``c`` camera and ``m`` mapping frame come from the
#: image products).
FRAME_ORDER = ("imu", "n", "a", "c", "m", "gnss", "truth", "mount")


def _floats(v):
    return [float(x) for x in v]


def _tidy(v):
    """Round unit conversions' last-bit noise (0.11999999999999998 -> 0.12)."""
    if isinstance(v, list):
        return [_tidy(x) for x in v]
    return float(f"{v:.12g}")


def ins_tables(plan, truth, s0, log, model, files, seed, grade):
    """The manifest of the INS products (a dict of TOML tables, in the format's order).

    Parameters
    ----------
    plan : ins.simulate.plan_model.FlightPlan
    truth : ins.simulate.truth.FlightTruth
    s0 : ins.nav.trajectory.Trajectory
        The true state at the first IMU epoch.
    log : ins.nav.imu.ImuLog
        The IMU log written (its first and last epochs).
    model : ins.simulate.sensor_errors.ImuErrorModel
        The injected IMU errors.
    files : dict
        ``[files]``: key -> file name of the INS products.
    seed : int
    grade : str
    """
    m, g = plan.mount, plan.gnss
    rpy = s0.rpy(degrees=True)[0]
    return {
        "format": FORMAT,
        "flight": {"seed": seed, "grade": grade, "gps_week": plan.flight.gps_week,
                   "start_time_s": float(log.time[0]), "end_time_s": float(log.time[-1]),
                   "imu_rate_hz": float(plan.imu.rate_hz), "plan": "plan.toml"},
        "files": dict(files),
        "frames": {
            "imu": "FRD body on the stabilized platform (b = p)",
            "n": "NED local level at the IMU",
            "a": "aircraft FRD (mount base; GNSS antenna on it)",
            "gnss": "antenna phase centre, WGS84 lat/lon deg, ellipsoidal h m",
            "truth": "IMU centre, .nav layout (week, time, lat, lon deg, h m, vN vE vD m/s, "
                     "roll pitch yaw deg)",
            "mount": "platform p relative to aircraft a: C_ap = Rz(yaw) Ry(pitch) Rx(roll)"},
        "lever_arm": {"imu_to_platform_centre_b_m": _floats(m.l_bp),
                      "platform_centre_to_antenna_a_m": _floats(m.l_ap)},
        "mount": {"enabled": bool(m.enabled), "log_rate_hz": float(m.log_rate_hz)},
        "imu": {k: _tidy(v) for k, v in model.to_units().items()},
        "gnss": {"rate_hz": float(g.rate_hz), "sigma_ned_m": _floats(g.sigma_ned_m),
                 "velocity": bool(g.velocity), "sigma_vel_mps": float(g.sigma_vel_mps),
                 "outages": [_floats(o) for o in g.outages]},
        "initial": {"lat_deg": float(np.rad2deg(s0.lla[0, 0])),
                    "lon_deg": float(np.rad2deg(s0.lla[0, 1])), "h_m": float(s0.lla[0, 2]),
                    "vel_ned_mps": _floats(s0.v_n[0]), "rpy_deg": _floats(rpy)},
        "stationary": {"segments_s": [_floats(seg) for seg in truth.stationary],
                       "static": plan.flight.start == "ground"},
    }


def _ordered(table, order):
    """``table`` with its keys in ``order``; the others last, in their own order."""
    rank = {k: i for i, k in enumerate(order)}
    return {k: table[k] for k in sorted(table, key=lambda k: rank.get(k, len(order)))}


def merge(manifest, *additions):
    """``manifest`` with the tables of ``additions`` added, in the format's order.

    Each addition is a dict ``{table: {key: value}}`` (a product writer's return value).
    The keys of a table that exists already come after its own (``[flight]`` counts,
    ``[files]`` of the product); new tables take their place of :data:`TABLE_ORDER`, new
    frames that of :data:`FRAME_ORDER`.

    Raises
    ------
    ValueError
        An addition that is not a table or that writes a key again (two products that
        claim the same file or setting).
    """
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in manifest.items()}
    for addition in additions:
        for table, entries in addition.items():
            if not isinstance(entries, dict) or not isinstance(out.get(table, {}), dict):
                raise ValueError(f"manifest: [{table}] of a product is not a table")
            target = out.setdefault(table, {})
            twice = sorted(set(entries) & set(target))
            if twice:
                raise ValueError(f"manifest: [{table}] {', '.join(twice)} written twice")
            target.update(entries)
    out = _ordered(out, TABLE_ORDER)
    if "frames" in out:
        out["frames"] = _ordered(out["frames"], FRAME_ORDER)
    return out
