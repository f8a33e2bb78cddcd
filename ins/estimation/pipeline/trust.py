"""Trust checks of ``ins process``: the start position against the first GNSS fix
(:func:`check_start`) and the assessment of a finished run (:func:`assess_quality`).

The start position is checked against the first GNSS fix at or after the start time
(within :data:`START_FIX_WINDOW_S`): the start state is moved along its velocity to the
fix time and carried to the antenna through the lever arm.  Farther from the fix than
``START_SIGMAS`` (5) times the combined sigma (fix, start position, start velocity times
the time to the fix) plus :data:`START_SLACK_M` (300 m) is an ``InputError`` naming the
config key and the distance (a start of another flight, a wrong ``time_s``); between 5
sigma and that bound the start position sigma is widened to the distance, with a
warning.  Without ``lat_deg, lon_deg, h_m`` in ``[initial]`` (method ``given``) the
start position is taken from that fix, less the lever arm; the static and in-air
alignments take it from the fixes the same way.

After the run (:func:`assess_quality`): more than :data:`REJECT_WARN_FRACTION` (5 %)
of the GNSS measurements rejected by the innovation test is a
:class:`~ins.common.errors.QualityWarning`; more than :data:`REJECT_ERROR_FRACTION` (50 %), no
accepted measurement at all, or a written solution (smoothed, or forward with
``smooth = false``) farther than :data:`DEPART_SIGMAS` (10) fix sigmas from every fix
for :data:`DEPART_SPAN_S` (30 s) or more, or from the last fixes of its span for
:data:`DEPART_END_S` (10 s) or more, or from more than :data:`DEPART_ERROR_FRACTION`
(10 %) of all the fixes, is a :class:`~ins.common.errors.QualityError` naming
the likely cause (start state, IMU noise settings, lever arm, time base), unless
``accept_poor`` (then a warning).  A recovery of the forward filter from a run of
rejected fixes is a warning, :data:`RECOVERY_ERROR_COUNT` of them a QualityError; a
re-anchoring after a GNSS gap (:mod:`ins.estimation.core.updates`: the fixes after the gap
agree with each other, the INS drifted) is a warning whatever their number.  A
negative variance beyond rounding, or a covariance
the smoother cannot factor, is a ``QualityError`` naming the time and the state.
"""
from types import SimpleNamespace

import numpy as np

from ins.common.errors import InputError
from ins.estimation.core.error_model import NAV
from ins.estimation.core.lever_arm import antenna_lla
from ins.nav import earth

#: Start-position check (module notes): refused beyond START_SIGMAS x sigma + START_SLACK_M.
START_SIGMAS = 5.0
START_SLACK_M = 300.0
#: The GNSS fix that checks (or gives) the start position lies at most this long after it, s.
START_FIX_WINDOW_S = 10.0
#: Fraction of GNSS measurements rejected by the innovation test: warning above the first,
#: QualityError above the second.
REJECT_WARN_FRACTION = 0.05
REJECT_ERROR_FRACTION = 0.5
#: A fix "departs" when the written solution is more than DEPART_SIGMAS fix sigmas (RMS
#: over north, east, down of residual / sigma) from it; consecutive departing fixes over
#: DEPART_SPAN_S or more are a QualityError (the error grew and stayed: not a blunder).
DEPART_SIGMAS = 10.0
DEPART_SPAN_S = 30.0
#: ... or a run of departing fixes that lasts to the last fix of the solution's span over
#: DEPART_END_S or more: the written solution ends drifted (a short log has no room for
#: the 30 s; the comma2k19 segment with a tactical IMU's noise settings left its last
#: 12 s 10-135 m from the fixes).
DEPART_END_S = 10.0
#: ... or, in stretches of any length, departing from more than this fraction of the fixes
#: (a filter kept near the fixes by recoveries can leave them again and again: the
#: comma2k19 phone with navigation-grade noise settings, 57 m residual RMS, 150 m at most,
#: in stretches shorter than 30 s).
DEPART_ERROR_FRACTION = 0.1
#: Recoveries of the forward filter from a run of rejected position fixes
#: (:mod:`ins.estimation.core.updates`): one is a warning (a poor start, an unmodelled moment),
#: this many a QualityError (the filter's model does not hold: its sigmas are not to be
#: trusted).
RECOVERY_ERROR_COUNT = 2
#: Naming the cause: an estimated sensor error beyond this many stated sigmas, or a mean
#: NIS of the accepted fixes beyond this many times its expectation (3), points at the
#: IMU noise settings (healthy test and benchmark runs: at most 2.8 sigma, NIS 2.8-3.0).
SENSOR_SIGMAS = 3.0
NIS_FACTOR = 2.0


def first_fix_at(gnss, t0):
    """Index of the first GNSS record at or after ``t0`` (s), or None."""
    k = int(np.searchsorted(gnss.time, t0 - 1e-9))
    return k if k < len(gnss) else None


def fix_name(gnss, k):
    """GNSS record ``k`` named for messages: ``the GNSS fix at t = ... s (file:line)``."""
    line = (f":{int(gnss.line[k])}" if gnss.line is not None and gnss.path is not None
            and gnss.line[k] > 0 else "")
    where = f" ({gnss.path}{line})" if gnss.path else ""
    return f"the GNSS fix at t = {gnss.time[k]:.3f} s{where}"


def check_start(state, t0, gnss, lever, std, source="the start position"):
    """Check a start state against the first GNSS fix at or after ``t0`` (module notes).

    Parameters
    ----------
    state : NavState
        Start state (IMU) at ``t0`` (s).
    gnss : ins.io.gnss_log.GnssLog
    lever : ins.estimation.core.lever_arm.LeverArm
    std : dict
        ``pos_std_ned_m`` and ``vel_std_ned_mps`` of the start (m, m/s).
    source : str
        What gave the position (the config key), for the message.

    Returns
    -------
    dict or None
        ``distance_m``, ``bound_m``, ``sigma_m``, ``time`` of the fix; None when no fix
        lies within :data:`START_FIX_WINDOW_S` after ``t0``.

    Raises
    ------
    InputError
        Beyond ``START_SIGMAS * sigma + START_SLACK_M``, naming ``source`` and the
        distance.
    """
    from ins.nav.rotation import quat_to_dcm
    k = first_fix_at(gnss, t0)
    if k is None or gnss.time[k] - t0 > START_FIX_WINDOW_S:
        return None
    tg = float(gnss.time[k])
    dt = tg - t0
    lla = state.lla + earth.lla_rate(state.lla[0], state.lla[2], state.v_n) * dt
    ant = antenna_lla(lla, quat_to_dcm(state.q_nb), lever.at(tg)[0][0])
    offset = earth.ned_offset(gnss.lla[k], ant)
    d = float(np.linalg.norm(offset))
    pos = np.broadcast_to(np.asarray(std["pos_std_ned_m"], float), 3)
    vel = np.broadcast_to(np.asarray(std["vel_std_ned_mps"], float), 3)
    sigma = float(np.sqrt(np.sum(gnss.sigma_ned_m[k] ** 2) + np.sum(pos ** 2)
                          + np.sum(vel ** 2) * dt ** 2))
    bound = START_SIGMAS * sigma + START_SLACK_M
    if d > bound:
        n, e, dn = offset
        raise InputError(f"{source}: the start is {d:.1f} m from {fix_name(gnss, k)} "
                         f"(antenna through the lever arm; fix minus start: N {-n:.1f} E "
                         f"{-e:.1f} D {-dn:.1f} m), more than the bound {bound:.1f} m "
                         f"({START_SIGMAS:g} sigma = {START_SIGMAS * sigma:.2f} m + "
                         f"{START_SLACK_M:g} m): a start of another flight, a wrong time_s "
                         f"or a different time scale in the logs?  Without lat_deg, "
                         f"lon_deg, h_m the start is taken from the GNSS fixes")
    return {"distance_m": d, "bound_m": bound, "sigma_m": sigma, "time": tg}


def fix_residuals(result, gnss, lever):
    """Residuals of the written solution (smoothed, else forward) at the GNSS fixes.

    The solution at the node of each fix (the last IMU epoch at or before it) is moved
    along its velocity to the fix time (plus the estimated time offset, when the layout
    has one) and carried to the antenna through the lever arm (plus the estimated
    correction).

    Returns
    -------
    index : ndarray of int
        GNSS records within the solution's span.
    residual_m : ndarray, shape (len(index), 3)
        Solution's antenna minus fix, NED, m.
    normalized : ndarray, shape (len(index),)
        RMS over north, east, down of ``residual / sigma_ned_m`` of each fix.
    """
    from ins.nav.rotation import quat_to_dcm
    nt = result.node_time
    index = np.flatnonzero((gnss.time >= nt[0] - 1e-9) & (gnss.time <= nt[-1] + 1e-9))
    if len(index) == 0:
        return index, np.zeros((0, 3)), np.zeros(0)
    j_all = np.searchsorted(nt, gnss.time[index] + 1e-9, side="right") - 1
    del nt
    layout = getattr(result.fwd, "layout", None)
    res = np.empty((len(index), 3))
    chunks = (result.node_chunks() if hasattr(result, "node_chunks") else
              [SimpleNamespace(j0=0, time=result.node_time, solution=result.node_solution(),
                               smoothed_sensors=np.asarray(result.smoothed_sensors))])
    for c in chunks:                       # block by block over the nodes
        sel = np.flatnonzero((j_all >= c.j0) & (j_all < c.j0 + len(c.time)))
        if len(sel) == 0:
            continue
        j = j_all[sel] - c.j0
        states = c.solution[j]
        tg = gnss.time[index[sel]]
        # the estimated time offset and lever-arm correction (optional states), if any
        sens = c.smoothed_sensors[j]
        offset = (layout.estimate(sens, "time_offset")[:, 0] if layout is not None
                  else np.zeros(len(j)))
        lla = states[:, NAV.lla] + earth.lla_rate(states[:, 0], states[:, 2],
                                                  states[:, NAV.vel]) * (
            tg + offset - c.time[j])[:, None]
        l_b = lever.at(tg)[0]
        if layout is not None:
            l_b = l_b + layout.estimate(sens, "lever_arm")
        arm = np.einsum("nij,nj->ni", quat_to_dcm(states[:, NAV.q_nb]), l_b)
        ant = lla + earth.lla_rate(lla[:, 0], lla[:, 2], arm)
        res[sel] = earth.ned_offset(gnss.lla[index[sel]], ant)
    norm = np.sqrt(np.mean((res / gnss.sigma_ned_m[index]) ** 2, axis=1))
    return index, res, norm


def _runs(mask):
    """``(i0, i1)`` of every run of consecutive True in ``mask`` (i1 exclusive)."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def assess_quality(result, gnss, lever, cfg=None):
    """Whether a result can be trusted (module notes; thresholds at the module top).

    Returns
    -------
    dict
        ``tested``, ``rejected`` (GNSS measurements, positions and velocities),
        ``rejected_fraction``, ``positions_tested``, ``positions_rejected``,
        ``residual_rms_m``, ``residual_max_m`` (written solution against the fixes,
        3-D), ``departure`` (longest stretch of departing fixes: ``from_s``, ``to_s``,
        ``n``, ``max_m``; or None), ``sensor_ratio`` (largest estimated sensor error over
        its stated sigma, per group), ``warnings`` (list of str) and ``error`` (str, or
        None when the result can be trusted).
    """
    fwd = result.fwd
    c = result.counts
    tested = c["updates"] + c["rejected"]
    pos_rejected = fwd.nis > fwd.nis_threshold
    frac = c["rejected"] / tested if tested else 1.0
    index, res, norm = fix_residuals(result, gnss, lever)
    dist = np.linalg.norm(res, axis=1)
    departure = None
    for i0, i1 in _runs(norm > DEPART_SIGMAS):
        span = float(gnss.time[index[i1 - 1]] - gnss.time[index[i0]])
        at_end = i1 == len(index)
        longer = departure is None or span > departure["to_s"] - departure["from_s"]
        if longer or (at_end and span >= DEPART_END_S):
            departure = {"from_s": float(gnss.time[index[i0]]),
                         "to_s": float(gnss.time[index[i1 - 1]]), "n": int(i1 - i0),
                         "max_m": float(dist[i0:i1].max()), "at_end": at_end}
    sensor_ratio = {}
    if cfg is not None:
        sig = cfg.noise.sensor_std
        groups = (("gyro bias", slice(0, 3), 180 / np.pi * 3600, "deg/h"),
                  ("accel bias", slice(3, 6), 1e5, "mGal"),
                  ("gyro scale", slice(6, 9), 1e6, "ppm"),
                  ("accel scale", slice(9, 12), 1e6, "ppm"))
        best = {}                      # the largest ratio of each group (its first place)
        chunks = (result.node_chunks() if hasattr(result, "node_chunks") else
                  [SimpleNamespace(smoothed_sensors=np.asarray(result.smoothed_sensors))])
        for ch in chunks:
            est = np.abs(ch.smoothed_sensors)
            for name, sl, _, _ in groups:
                r = est[:, sl] / sig[sl]
                i = np.unravel_index(int(np.argmax(r)), r.shape)
                if name not in best or r[i] > best[name][0]:
                    best[name] = (r[i], est[i[0], sl][i[1]], i[1])
        for name, sl, unit, key in groups:
            if name in best:
                r, e, k = best[name]
                sensor_ratio[name] = (float(r), float(e * unit), float(sig[sl][k] * unit),
                                      key, "xyz"[k])
    q = {"tested": tested, "rejected": c["rejected"], "rejected_fraction": frac,
         "positions_tested": len(fwd.nis), "positions_rejected": int(pos_rejected.sum()),
         "residual_rms_m": float(np.sqrt(np.mean(dist ** 2))) if len(dist) else np.nan,
         "residual_max_m": float(dist.max()) if len(dist) else np.nan,
         "departure": departure, "sensor_ratio": sensor_ratio, "warnings": [],
         "error": None}
    counts = (f"{c['rejected']} of {tested} GNSS measurements rejected by the innovation "
              f"test ({100 * frac:.1f} %)")
    problems = []
    if tested == 0:
        problems.append(f"no GNSS record within the processed span ({c['gnss_records']} "
                        f"records, {c['outside_imu_span']} outside it)")
    elif c["updates"] == 0:
        problems.append(f"no GNSS measurement accepted ({counts})")
    elif frac > REJECT_ERROR_FRACTION:
        problems.append(f"{counts}: more than {100 * REJECT_ERROR_FRACTION:g} %")
    elif frac > REJECT_WARN_FRACTION:
        q["warnings"].append(f"{counts}: more than {100 * REJECT_WARN_FRACTION:g} %; "
                             f"{_causes(result, q, cfg)}")
    rec = getattr(fwd, "recoveries", [])
    if rec:
        spans = ", ".join(f"{a:.2f}-{b:.2f} s" for a, b, _, _ in rec[:4]) + \
            (" ..." if len(rec) > 4 else "")
        text = (f"{len(rec)} recover{'y' if len(rec) == 1 else 'ies'} from runs of rejected "
                f"position fixes ({spans}): the filter's covariance was too small for its "
                f"error there")
        if len(rec) >= RECOVERY_ERROR_COUNT:
            problems.append(text + f" ({RECOVERY_ERROR_COUNT} or more: its model does not "
                                   f"hold and its sigmas cannot be trusted)")
        else:
            q["warnings"].append(text + "; " + _causes(result, q, cfg))
    anchors = getattr(fwd, "reanchors", [])
    if anchors:
        spans = ", ".join(f"{a:.2f}-{b:.2f} s" for a, b, _, _ in anchors[:4]) + \
            (" ..." if len(anchors) > 4 else "")
        q["warnings"].append(
            f"{len(anchors)} re-anchoring{'' if len(anchors) == 1 else 's'} after GNSS gaps "
            f"({spans}): the fixes after the gap agreed with each other but not with the "
            f"INS, whose drift over the gap exceeded its stated covariance (the forward "
            f"solution's sigmas are too small in GNSS outages)")
    far = norm > DEPART_SIGMAS
    if len(far) and far.mean() > DEPART_ERROR_FRACTION:
        problems.append(
            f"the solution is more than {DEPART_SIGMAS:g} fix sigmas from {int(far.sum())} of "
            f"its {len(far)} GNSS fixes ({100 * far.mean():.0f} %, more than "
            f"{100 * DEPART_ERROR_FRACTION:g} %; up to {float(dist.max()):.3g} m)")
    span = None if departure is None else departure["to_s"] - departure["from_s"]
    if departure is not None and (span >= DEPART_SPAN_S
                                  or (departure["at_end"] and span >= DEPART_END_S)):
        bound = (f"bound {DEPART_SPAN_S:g} s" if span >= DEPART_SPAN_S else
                 f"to the end of the solution; bound there {DEPART_END_S:g} s")
        problems.append(
            f"the solution is more than {DEPART_SIGMAS:g} fix sigmas from all "
            f"{departure['n']} GNSS fixes from t = {departure['from_s']:.3f} to "
            f"{departure['to_s']:.3f} s ({span:.0f} s, up to {departure['max_m']:.3g} m; "
            f"{bound}: the solution drifted, or those fixes are wrong)")
    if problems:
        q["error"] = ("untrustworthy solution: " + "; ".join(problems) + ". "
                      + _causes(result, q, cfg))
    return q


def _causes(result, q, cfg):
    """The likely cause of a poor result, most likely first (a sentence)."""
    fwd = result.fwd
    c = result.counts
    causes = []
    if q["tested"] == 0 or c["outside_imu_span"] > 0.5 * c["gnss_records"]:
        causes.append("time base: the GNSS and IMU times do not overlap (check that both "
                      "logs use the same time scale, e.g. GPS seconds of week)")
    early = fwd.nis[:5] > fwd.nis_threshold
    if len(early) and early.all():
        causes.append("start state: the first GNSS fixes are already rejected (check "
                      "[initial] position, velocity, rpy_deg and time_s, the lever arm "
                      "and the time base)")
    noisy = [f"the estimated {name} {est:.3g} {unit} on {axis} is {ratio:.1f} x the stated "
             f"sigma {sig:.3g} {unit}"
             for name, (ratio, est, sig, unit, axis) in q["sensor_ratio"].items()
             if ratio > SENSOR_SIGMAS]
    accepted = fwd.nis[fwd.nis <= fwd.nis_threshold]
    if len(accepted) > 10 and accepted.mean() > NIS_FACTOR * 3.0:
        noisy.append(f"the accepted fixes' mean NIS is {accepted.mean():.1f} (3 expected: "
                     f"the filter is overconfident)")
    if noisy:
        causes.append("IMU noise settings: " + "; ".join(noisy) + " (the IMU is worse "
                      "than [imu_noise] states: give its grade's values)")
    generic = ("start state ([initial] or the alignment), IMU noise settings ([imu_noise]), "
               "lever arm ([gnss] lever_arm_b_m or [mount]) and time base (same time scale "
               "in both logs)")
    if not causes:
        return f"Likely cause: one of {generic}."
    return "Likely cause: " + "; ".join(causes) + f". Also check: {generic}."


def start_report(result, heading_from=None, skipped=None, heading_floor_deg=None):
    """What the start left open, for the summary: ``{"imu_skipped_s": (t_a, t_b) or
    None, "heading_from": str, "heading_std_deg": float, "heading_filter_std_deg":
    float, "heading_resolved": bool}``.

    ``heading_filter_std_deg`` is the largest sigma of the written solution's heading
    (the attitude error about the vertical, smoothed, else forward) over the nodes;
    ``heading_std_deg`` the same, but at least ``heading_floor_deg`` (deg) when given:
    the bound of a log that never moved, which the filter's linear model can claim to
    beat (:mod:`ins.estimation.alignment.motion`, module notes 4.).  Resolved when it
    is at most :data:`ins.estimation.alignment.initial.MAX_STATIC_HEADING_DEG` (2 deg).
    ``heading_from``: ``"gyrocompass"`` for a log that never moved (the heading is then
    what the Earth rate and the gyro biases allow), else the alignment's method
    (``"given"`` without one).  ``skipped`` is the IMU span before the start (s) that
    was not processed.
    """
    from ins.estimation.alignment.initial import MAX_STATIC_HEADING_DEG
    from ins.estimation.core.error_model import STATE
    std = np.asarray(result.smoothed_std)
    filt = np.rad2deg(float(np.max(std[:, STATE.att.start + 2]))) if len(std) else np.nan
    head = filt if heading_floor_deg is None else max(filt, float(heading_floor_deg))
    al = result.alignment
    source = heading_from or (al.method if al is not None else "given")
    return {"imu_skipped_s": None if skipped is None else tuple(float(t) for t in skipped),
            "heading_from": source, "heading_std_deg": head, "heading_filter_std_deg": filt,
            "heading_resolved": bool(head <= MAX_STATIC_HEADING_DEG)}
