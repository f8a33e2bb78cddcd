"""The IMU's noise, the vehicle constraint and the GNSS velocity lag identified from the
log itself, by maximum likelihood over the forward filter's GNSS innovations.

Why
---
A datasheet states the noise of a sensor on a bench.  Shaken on a car's roof the same
part shows 2-30 times that in its samples, and most of it is vibration that the
strapdown integration averages out: neither number is what the filter must assume.  The
right one is the one under which the GNSS fixes are best predicted.

The likelihood
--------------
For a set of parameters ``theta`` the forward filter runs over the log (at most
:data:`SEARCH_WINDOW_S` from the start, no smoothing, no recovery) and every GNSS
position and velocity innovation ``nu`` with covariance ``S = H P H^T + R`` adds
``(rho(nu^T S^-1 nu) + log det S + m log 2 pi) / 2`` to the negative log-likelihood
(:func:`ins.estimation.core.measurements.innovation_nll`; ``rho`` is the square up to the
chi-square 99 % point and grows with the Mahalanobis distance beyond it, so that a few
wrong fixes do not decide the search).  The filter's own recursion makes this the exact
Gaussian likelihood of the fixes under ``theta`` (the prediction-error decomposition).
A weak log-normal prior (:data:`PRIOR_LN_SIGMA`: a factor of 10 at one sigma) ties
each noise parameter to its starting value (a preset named by the user, the noise
measured over a rest, or the best of the preset grades).

The search
----------
Coordinate-wise in the parameters' logarithms (the lag linearly): at each parameter the
likelihood is evaluated one step either side, the parabola through the three values
gives the new value (inside two steps) and its curvature the sigma,
``sigma_u = 1 / sqrt(d^2 NLL / du^2)``; a parameter whose curvature is not positive or
whose sigma exceeds a factor :data:`UNRESOLVED_FACTOR` is stated as not separable by the
data and keeps its starting value.  The innovations of a vibrating car at 4 Hz are not
white, so the sigmas are the likelihood's own (optimistic by the correlation), a
measure of how sharply the data decides, not a calibration.
The order: ARW and VRW (the clocks are judged badly under a wrong noise), the IMU-GNSS
time offset when the user gave none (from 0, steps of 50 then 10 ms; IMU clock minus
GNSS clock, the value of ``[gnss] time_shift_s``), the GNSS velocities' lag (starting
from :func:`ins.estimation.coupling.velocity_lag.velocity_lag`, the GNSS log's own estimate), the
non-holonomic constraint of a land vehicle (kept when it improves the likelihood by
more than :data:`NHC_MIN_GAIN`: a likelihood-ratio test that an aircraft or a walker
fails), the scale-factor priors and the bias instabilities of the gyros and
accelerometers, then ARW, VRW, the offset and the lag again with finer steps.
"""
from dataclasses import dataclass, field, replace

import numpy as np

from ins.estimation.core.error_model import ImuNoise

#: The search runs the filter over at most this much of the log from the start, s ...
SEARCH_WINDOW_S = 900.0
#: ... with the GNSS thinned to at most this rate, Hz: a fourth of the cost of a 4 Hz
#: receiver's, and the innovations then predict over 1 s, nearer the outages' scale.
SEARCH_RATE_HZ = 1.0
#: Weak prior: log-normal about the starting values with this sigma of the logarithm.
PRIOR_LN_SIGMA = np.log(10.0)
#: A parameter with a sigma beyond this factor (or no curvature) is not separable.
UNRESOLVED_FACTOR = 3.0
#: The non-holonomic constraint is kept when it lowers the NLL by more than this.
NHC_MIN_GAIN = 10.0
#: Steps a line search may walk downhill before its parabola (a factor 2^8 = 256 for
#: ARW and VRW: a datasheet's bench value to a shaking car's).
MAX_MOVES = 8
#: An IMU-GNSS offset found below this is not applied, s: on the simulated twin of the
#: real car (no offset; vibration and 3 % scale errors) the likelihood found 22 ms and
#: ins time-offset's cross-correlation -26 ms (tests/real_car_twin.py).
OFFSET_MIN_S = 0.03
#: An IMU-GNSS offset is applied only when it lowers the NLL by more than this against
#: none (with the vehicle constraint decided again for none), as the constraint must.
OFFSET_MIN_GAIN = 10.0
#: The preset grades tried as starting points when nothing else gives one.
START_GRADES = ("tactical", "mems", "consumer")


@dataclass
class Parameter:
    """One identified quantity: name, value, unit, sigma (a factor ``x/÷`` for the log
    parameters, seconds for the lag), the starting value, whether the data resolved it."""

    name: str
    value: float
    unit: str
    sigma: float
    start: float
    resolved: bool
    log: bool = True
    note: str = None

    def describe(self):
        if self.note is not None:
            return f"{self.name}: {self.note}"
        if not self.resolved:
            return (f"{self.name} {_fmt(self.value)} {self.unit}: not separable by the "
                    f"data (kept at the start value)")
        if self.log:
            return f"{self.name} {_fmt(self.value)} {self.unit} (x/÷ {self.sigma:.2f})"
        return f"{self.name} {_fmt(self.value)} +- {_fmt(self.sigma)} {self.unit}"


def _fmt(x):
    return f"{x:.3g}"


@dataclass
class Identified:
    """What :func:`identify` found: the noise settings, whether the non-holonomic
    constraint is used, the GNSS velocity shift (s, or None: not estimated), the
    parameters with their sigmas, the starting point's name, the filter runs it took,
    the NLL at the start and at the end."""

    noise: ImuNoise
    nhc: bool
    velocity_shift_s: object
    parameters: list = field(default_factory=list)
    start_name: str = ""
    runs: int = 0
    nll_start: float = np.nan
    nll: float = np.nan
    nhc_gain: float = None
    window_s: float = None
    velocity_lag: object = None   # ins.estimation.coupling.velocity_lag.VelocityLag: the start
    time_offset_s: object = None  # the IMU-GNSS offset found (s), None: not searched

    def describe(self):
        """One paragraph for the summary."""
        parts = [p.describe() for p in self.parameters]
        nhc = ("non-holonomic constraint of a land vehicle: as configured"
               if self.nhc_gain is None else
               "non-holonomic constraint of a land vehicle: "
               + ("used" if self.nhc else "not used")
               + f" (it changes the NLL by {-self.nhc_gain:+.0f})")
        lag = ("" if self.velocity_lag is None else
               f"; the lag's start: {self.velocity_lag.describe()}")
        return (f"identified from the log by maximum likelihood over the GNSS innovations "
                f"({self.runs} filter runs"
                + ("" if self.window_s is None else f" over {self.window_s:.0f} s")
                + f", from {self.start_name}; "
                f"NLL {self.nll_start:.0f} -> {self.nll:.0f}): " + "; ".join(parts)
                + "; " + nhc + lag)


class _Objective:
    """The NLL of a trial (noise, nhc, velocity shift), cached."""

    def __init__(self, run, start_values):
        self.run, self.cache, self.n = run, {}, 0
        self.u0 = {k: np.log(v) for k, v in start_values.items()}

    def __call__(self, point):
        key = tuple(sorted((k, round(float(v), 9)) for k, v in point.items()))
        if key not in self.cache:
            self.n += 1
            nll = self.run(point)
            prior = sum(0.5 * ((np.log(point[k]) - u0) / PRIOR_LN_SIGMA) ** 2
                        for k, u0 in self.u0.items() if k in point)
            self.cache[key] = nll + prior
        return self.cache[key]


def _line(obj, point, name, step, log, lo, hi):
    """Parabolic step along one parameter; returns (point, sigma in u, resolved)."""
    u = np.log(point[name]) if log else point[name]

    def at(v):
        p = dict(point)
        p[name] = float(np.exp(v)) if log else float(v)
        return p
    moves = 0
    while True:
        fm, f0, fp = obj(at(u - step)), obj(point), obj(at(u + step))
        if moves < MAX_MOVES and min(fm, fp) < f0 and np.isfinite(min(fm, fp)):
            nu = u - step if fm < fp else u + step       # walk downhill (evaluated)
            if not (lo <= (np.exp(nu) if log else nu) <= hi):
                break
            u, point, moves = nu, at(nu), moves + 1
            continue
        break
    curv = (fm - 2.0 * f0 + fp) / step ** 2
    if not (np.isfinite(curv) and curv > 0):
        return point, np.inf, False
    shift = float(np.clip(0.5 * (fm - fp) / (fm - 2.0 * f0 + fp), -1.0, 1.0)) * step
    new = at(u + shift)
    value = new[name]
    if not (lo <= value <= hi):
        new = point
    sigma = 1.0 / np.sqrt(curv)
    return new, sigma, True


def noise_of(base, point):
    """``base`` (ImuNoise) with the trial's ARW, VRW and bias-instability factors."""
    kw = {}
    if "arw" in point:
        kw["arw_deg_sqrth"] = base.arw_deg_sqrth * point["arw"]
    if "vrw" in point:
        kw["vrw_mps_sqrth"] = base.vrw_mps_sqrth * point["vrw"]
    if "gyro_scale" in point:
        kw["gyro_scale_std_ppm"] = base.gyro_scale_std_ppm * point["gyro_scale"]
    if "accel_scale" in point:
        kw["accel_scale_std_ppm"] = base.accel_scale_std_ppm * point["accel_scale"]
    if base.constant_sensors:
        if "gyro_bi" in point:
            kw["gyro_bias_instability_dph"] = base.gyro_bias_instability_dph * point["gyro_bi"]
        if "accel_bi" in point:
            kw["accel_bias_instability_mgal"] = (base.accel_bias_instability_mgal
                                                 * point["accel_bi"])
    return replace(base, **kw)


def identify(run_nll, starts, velocity_lag=None, test_nhc=True, window_s=None,
             progress=None, time_offset=False):
    """Maximum-likelihood noise settings (module notes).

    Parameters
    ----------
    run_nll : callable
        ``run_nll(noise, nhc, velocity_shift_s, time_offset_s)`` -> the NLL of the GNSS
        innovations of a forward run with those settings (``velocity_shift_s`` None: the
        log's stamps; ``time_offset_s``: added to every GNSS stamp, the positions' and the
        velocities', the IMU clock minus the GNSS clock; None: none).
    starts : list of (str, ImuNoise)
        Starting points (name, noise); the best is refined.
    velocity_lag : ins.estimation.coupling.velocity_lag.VelocityLag, optional
        The GNSS log's own lag estimate: its shift is refined (None: not estimated).
    test_nhc : bool
        Try the non-holonomic constraint (False: the user decided).
    window_s : float, optional
        Span of the search runs (for the description).
    progress : callable, optional
        ``progress(done_runs, expected_runs)``.
    time_offset : bool
        Search the IMU-GNSS time offset too (from 0; the user gave none).

    Returns
    -------
    Identified
    """
    expected = (2 * 8 + 2 * 3 + len(starts) + 2 + (2 if velocity_lag is not None else 0)
                + (6 if time_offset else 0))
    state = {"base": starts[0][1], "done": 0}

    def run(point):
        state["done"] += 1
        if progress is not None:
            progress(state["done"], max(expected, state["done"]))
        noise = noise_of(state["base"], point)
        return run_nll(noise, bool(point.get("nhc", 0)), point.get("vshift"),
                       point.get("toff"))

    # the best starting point (each at its own values)
    best = None
    for name, noise in starts:
        state["base"] = noise
        p = {"arw": 1.0, "vrw": 1.0, "nhc": 0}
        if velocity_lag is not None:
            p["vshift"] = velocity_lag.shift_s
        if time_offset:
            p["toff"] = 0.0
        f = run(p)
        if best is None or f < best[0]:
            best = (f, name, noise)
    nll_start, start_name, base = best
    state["base"] = base
    logs = {"arw": 1.0, "vrw": 1.0, "gyro_scale": 1.0, "accel_scale": 1.0}
    if base.constant_sensors:
        logs.update(gyro_bi=1.0, accel_bi=1.0)
    obj = _Objective(run, logs)
    point = dict(logs, nhc=0)
    if velocity_lag is not None:
        point["vshift"] = velocity_lag.shift_s
    if time_offset:
        point["toff"] = 0.0
    obj.cache[tuple(sorted((k, round(float(v), 9)) for k, v in point.items()))] = nll_start
    sig = {}

    def line(name, step, log=True):
        nonlocal point
        lo, hi = (1e-3, 1e3) if log else (-1.0, 1.0)
        point, sig[name], _ = _line(obj, point, name, step, log, lo, hi)

    # the white noise first (the clocks are judged badly under a wrong noise), then the
    # clocks, then the error priors and a second, finer pass with and without the vehicle
    # constraint
    line("arw", np.log(2.0))
    line("vrw", np.log(2.0))
    if time_offset:
        line("toff", 0.05, log=False)
    if velocity_lag is not None:
        line("vshift", 0.02, log=False)

    def second_pass(start):
        """The error priors and a finer pass from ``start`` -> (point, sigmas, NLL)."""
        nonlocal point, sig
        point, sig = start, dict(sig)
        line("gyro_scale", np.log(4.0))
        line("accel_scale", np.log(4.0))
        if base.constant_sensors:
            line("gyro_bi", np.log(4.0))
            line("accel_bi", np.log(4.0))
        line("arw", np.log(2.0) / 2)
        line("vrw", np.log(2.0) / 2)
        if time_offset:
            line("toff", 0.01, log=False)
        if velocity_lag is not None:
            line("vshift", 0.01, log=False)
        return point, sig, obj(point)

    # the vehicle constraint: the rest of the search with it and without it, the two
    # ends compared (the PSINS car, GNSS seed 1: decided after the clocks alone, the
    # constraint changed the NLL by +3 and was dropped; each branch searched to its end,
    # -14, and smoothed 0.36 -> 0.34 m; seed 0: 0.28 -> 0.24 m)
    nhc_gain = None
    if test_nhc:
        first, first_sig = point, sig
        ends = []
        for h in (0, 1):
            sig = first_sig
            ends.append(second_pass(dict(first, nhc=h)))
        nhc_gain = ends[0][2] - ends[1][2]
        point, sig, _ = ends[int(nhc_gain > NHC_MIN_GAIN)]
    else:
        point, sig, _ = second_pass(point)
    offset_gain = None
    if time_offset and abs(point["toff"]) >= OFFSET_MIN_S:
        # the offset against none at the point found, the constraint decided again (a
        # wrong offset found first can reject the constraint that no offset needs: the
        # PSINS car's -0.19 s, NLL 489, against none with the constraint, 481)
        alt = dict(point, toff=0.0)
        if test_nhc:
            gain = obj(dict(alt, nhc=0)) - obj(dict(alt, nhc=1))
            alt["nhc"] = int(gain > NHC_MIN_GAIN)
        offset_gain = obj(alt) - obj(point)
        if offset_gain <= OFFSET_MIN_GAIN:
            if alt["nhc"] != point["nhc"]:
                nhc_gain = gain
            rejected_offset, point = float(point["toff"]), alt
    params = _parameters(base, noise_of(base, point), point, sig, velocity_lag)
    if time_offset:
        s_t = sig.get("toff", np.inf)
        found = float(point["toff"])
        ok = bool(np.isfinite(s_t)) and abs(found) >= OFFSET_MIN_S
        if offset_gain is not None and offset_gain <= OFFSET_MIN_GAIN:
            found, ok = rejected_offset, False
        params.append(Parameter("IMU-GNSS time offset", found if ok else 0.0, "s",
                                float(s_t), 0.0, ok, log=False))
        if offset_gain is not None and offset_gain <= OFFSET_MIN_GAIN:
            params[-1].note = (f"{found * 1e3:+.0f} ms found, but it lowers the NLL by only "
                               f"{offset_gain:.1f} (at least {OFFSET_MIN_GAIN:g} needed): 0 kept")
        elif np.isfinite(s_t) and not ok:
            params[-1].note = (f"{found * 1e3:+.0f} ms found, below the {OFFSET_MIN_S * 1e3:.0f} "
                               f"ms the likelihood can tell on a vibrating car: 0 kept")
    keys = {"ARW": "arw", "VRW": "vrw", "gyro bias instability": "gyro_bi",
            "gyro scale-factor sigma": "gyro_scale", "accel scale-factor sigma": "accel_scale",
            "accel bias instability": "accel_bi", "GNSS velocity time shift": "vshift",
            "IMU-GNSS time offset": "toff"}
    for p in params:                    # what the data did not decide stays at its start
        if not p.resolved:
            point[keys[p.name]] = 1.0 if p.log else p.start
    noise = noise_of(base, point)
    out = Identified(noise, bool(point["nhc"]),
                     None if velocity_lag is None else float(point["vshift"]), params,
                     start_name, obj.n + len(starts) - 1, float(nll_start),
                     float(obj(point)), nhc_gain, window_s)
    out.time_offset_s = float(point["toff"]) if time_offset else None
    return out


def _parameters(base, noise, point, sig, lag):
    out = []

    def add(name, key, value, start, unit):
        s = sig.get(key, np.inf)
        factor = float(np.exp(s)) if np.isfinite(s) else np.inf
        ok = factor <= UNRESOLVED_FACTOR
        out.append(Parameter(name, float(value if ok else start), unit, factor,
                             float(start), ok))
    add("ARW", "arw", np.max(noise.arw_deg_sqrth), np.max(base.arw_deg_sqrth),
        "deg/sqrt(h)")
    add("VRW", "vrw", np.max(noise.vrw_mps_sqrth), np.max(base.vrw_mps_sqrth),
        "m/s/sqrt(h)")
    add("gyro scale-factor sigma", "gyro_scale", np.max(noise.gyro_scale_std_ppm),
        np.max(base.gyro_scale_std_ppm), "ppm")
    add("accel scale-factor sigma", "accel_scale", np.max(noise.accel_scale_std_ppm),
        np.max(base.accel_scale_std_ppm), "ppm")
    if base.constant_sensors:
        add("gyro bias instability", "gyro_bi", np.max(noise.gyro_bias_instability_dph),
            np.max(base.gyro_bias_instability_dph), "deg/h")
        add("accel bias instability", "accel_bi",
            np.max(noise.accel_bias_instability_mgal),
            np.max(base.accel_bias_instability_mgal), "mGal")
    if lag is not None:
        s = sig.get("vshift", np.inf)
        out.append(Parameter("GNSS velocity time shift", float(point["vshift"]), "s",
                             float(s), float(lag.shift_s), bool(np.isfinite(s)), log=False))
    return out

