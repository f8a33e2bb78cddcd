"""The flight path as smooth time profiles: track (heading of the ground velocity),
ground speed, climb velocity and the airborne weight, built from the plan's segments.

Every profile is a piecewise polynomial (:class:`scipy.interpolate.PPoly`) of constant
pieces and quintic "smootherstep" ramps ``a + (b - a)(10u^3 - 15u^4 + 6u^5)``: the ramped
quantity is C2, so the track rate and bank are C2 and the angular rates C1.

Time ``t`` is relative to the flight start (s).  Segments:

1. ``start = "ground"``: ``stationary_s`` at rest on the ground (truly static), a takeoff
   roll (speed ramp 0 -> V, peak acceleration ``takeoff_accel``), a climb at
   ``climb_rate`` to ``height_agl`` (vertical-speed ramps of :data:`CLIMB_RAMP_S`; the
   airborne weight, which switches wind crab and turbulence on, ramps 0 -> 1 during the
   first one).  ``start = "air"``: ``stationary_s`` of straight level flight at V.
2. A run-in of ``run_in_m``, then strip 0, and for each next strip a run-out, a turn
   manoeuvre to the next strip, a run-in and the strip; a run-out after the last strip.

Turns are coordinated turns at ``turn_rate`` with roll-in/roll-out ramps of
:data:`ROLL_IN_S`.  When the strip spacing allows, the manoeuvre is turn 90 deg, straight,
turn 90 deg; for a spacing smaller than the turn diameter it is a "bulb" turn: away from
the next strip by beta, then toward it by 180 deg + beta (beta solved so that the
lateral offset equals the spacing).  The manoeuvres are designed in the plane (flat
Earth); :mod:`~ins.simulate.truth` corrects each turn's lateral offset and run-in
(``corrections``) so that the strips start at their planned points on the geodetic path.
"""
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PPoly
from scipy.optimize import brentq

__all__ = ["Timeline", "FlightPath", "build_path", "ROLL_IN_S", "CLIMB_RAMP_S"]

#: Duration of the turn-rate ramps (roll in, roll out), s.
ROLL_IN_S = 5.0
#: Duration of the vertical-speed ramps at the start and end of a climb, s.
CLIMB_RAMP_S = 10.0
_SIGNALS = ("psi_dot", "speed", "v_down", "air")


class Timeline:
    """Sequential segments of ramps and constants of the four profiles.

    Profiles: ``psi_dot`` track rate (rad/s), ``speed`` ground speed (m/s), ``v_down``
    climb part of the down velocity (m/s), ``air`` airborne weight (0..1).
    """

    def __init__(self, **initial):
        self.t = 0.0
        self.breaks = [0.0]
        self.value = {k: float(initial.get(k, 0.0)) for k in _SIGNALS}
        self.coeffs = {k: [] for k in _SIGNALS}

    def add(self, duration, **targets):
        """Append a segment of ``duration`` s; each named profile ramps to its target,
        the others stay constant."""
        if duration <= 0:
            return
        for k in _SIGNALS:
            a = self.value[k]
            b = float(targets.get(k, a))
            d = b - a
            T = duration
            self.coeffs[k].append([6 * d / T ** 5, -15 * d / T ** 4, 10 * d / T ** 3, 0, 0, a])
            self.value[k] = b
        self.t += duration
        self.breaks.append(self.t)

    def ppoly(self, name):
        """The profile as a PPoly (degree 5; extrapolates the end pieces)."""
        return PPoly(np.array(self.coeffs[name]).T, np.array(self.breaks))

    def turn(self, angle, rate):
        """A coordinated turn by ``angle`` (rad, signed: + right) at ``rate`` (rad/s > 0)."""
        if angle == 0:
            return
        r = abs(rate)
        if abs(angle) < r * ROLL_IN_S:
            r = abs(angle) / ROLL_IN_S
        r = np.copysign(r, angle)
        self.add(ROLL_IN_S, psi_dot=r)
        self.add(abs(angle / r) - ROLL_IN_S, psi_dot=r)
        self.add(ROLL_IN_S, psi_dot=0.0)

    def straight(self, distance):
        """Straight flight over ``distance`` m at the current (constant) speed."""
        if distance > 0:
            self.add(distance / self.value["speed"])


def _planar_offset(tl):
    """(x, y) displacement (m) of a timeline flown from heading 0, by Gauss-Legendre
    quadrature of V (cos psi, sin psi) on each piece (16 panels x 8 nodes)."""
    rate, speed = tl.ppoly("psi_dot"), tl.ppoly("speed")
    psi = rate.antiderivative()
    x, w = np.polynomial.legendre.leggauss(8)
    edges = np.concatenate([np.linspace(a, b, 17)[:-1] for a, b in
                            zip(tl.breaks[:-1], tl.breaks[1:])] + [[tl.breaks[-1]]])
    mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * np.diff(edges)
    t = (mid[:, None] + half[:, None] * x).ravel()
    wt = (half[:, None] * w).ravel()
    v, p = speed(t), psi(t)
    return float(np.sum(wt * v * np.cos(p))), float(np.sum(wt * v * np.sin(p)))


def _manoeuvre(speed, rate, spacing, beta=None):
    """The turn to the next strip on the right: timeline from heading 0 to heading pi."""
    tl = Timeline(speed=speed)
    if beta is None:                                  # 90 - straight - 90
        tl.turn(np.pi / 2, rate)
        _, y = _planar_offset(tl)
        tl.straight(spacing - 2 * y)
        tl.turn(np.pi / 2, rate)
    else:                                             # bulb: away by beta, back by pi + beta
        tl.turn(-beta, rate)
        tl.turn(np.pi + beta, rate)
    return tl


def design_manoeuvre(speed, rate, spacing):
    """Timeline of the turn from a strip to the next one ``spacing`` m to the right,
    and its planar displacement (along, lateral) in m."""
    quarter = Timeline(speed=speed)
    quarter.turn(np.pi / 2, rate)
    if spacing >= 2 * _planar_offset(quarter)[1]:
        tl = _manoeuvre(speed, rate, spacing)
    else:
        def lateral(beta):
            return _planar_offset(_manoeuvre(speed, rate, spacing, beta))[1] - spacing
        beta = brentq(lateral, 0.0, np.deg2rad(179.0), xtol=1e-13)
        tl = _manoeuvre(speed, rate, spacing, beta)
    return tl, _planar_offset(tl)


@dataclass(frozen=True)
class FlightPath:
    """Profiles of the flight (t in s from the flight start) and its landmarks.

    Attributes
    ----------
    psi_dot, speed, v_down, air : scipy.interpolate.PPoly
        Track rate (rad/s), ground speed (m/s), climb down-velocity (m/s), airborne weight.
    psi0 : float
        Track at t = 0, rad.  ``psi(t) = psi0 + psi_dot.antiderivative()(t)``.
    h0 : float
        Height at t = 0 (before heave), m.
    strips : list of (t0, t1, azimuth_rad)
    stationary : list of (t0, t1)
    t_strip0 : float
        Start of strip 0 (the block origin), s.
    duration : float
        s.
    """
    psi_dot: PPoly
    speed: PPoly
    v_down: PPoly
    air: PPoly
    psi0: float
    h0: float
    strips: list
    stationary: list
    t_strip0: float
    duration: float


def build_path(plan, corrections=None):
    """Build the :class:`FlightPath` of a :class:`~ins.simulate.plan_model.FlightPlan`.

    ``corrections`` (n_strips - 1, 2), m: per turn, added to its lateral offset (the
    strip spacing it is designed for) and to the run-in after it; used by
    :mod:`~ins.simulate.truth` to place the strips on the geodetic path.
    """
    f, b = plan.flight, plan.block
    V = f.ground_speed
    ground = f.start == "ground"
    tl = Timeline(speed=0.0 if ground else V, air=0.0 if ground else 1.0)
    stationary = [(0.0, f.stationary)] if f.stationary > 0 else []
    tl.add(f.stationary)
    h0 = plan.flying_height_m
    if ground:
        h0 = b.origin_h
        tl.add(1.875 * V / f.takeoff_accel, speed=V)           # peak accel 1.875 dV/T
        c = f.climb_rate
        T_c = f.height_agl / c - CLIMB_RAMP_S
        if T_c < 0:
            c, T_c = f.height_agl / CLIMB_RAMP_S, 0.0
        tl.add(CLIMB_RAMP_S, v_down=-c, air=1.0)
        tl.add(T_c, v_down=-c)
        tl.add(CLIMB_RAMP_S, v_down=0.0)
    tl.straight(f.run_in)
    strips = []
    t_strip0 = tl.t
    spacing = plan.strip_spacing_m
    if corrections is None:
        corrections = np.zeros((max(b.n_strips - 1, 0), 2))
    designs = {}
    for i in range(b.n_strips):
        t0 = tl.t
        tl.straight(b.strip_length)
        strips.append((t0, tl.t, (b.strip_azimuth + (i % 2) * np.pi) % (2 * np.pi)))
        if i == b.n_strips - 1:
            tl.straight(f.run_in)
            break
        c_lat, c_along = (float(x) for x in corrections[i])
        if c_lat not in designs:
            designs[c_lat] = design_manoeuvre(V, f.turn_rate, spacing + c_lat)
        man, (along, _) = designs[c_lat]
        sign = 1.0 if i % 2 == 0 else -1.0
        run_out = max(f.run_in, f.run_in - along)
        tl.straight(run_out)
        for k in range(len(man.breaks) - 1):
            T = man.breaks[k + 1] - man.breaks[k]
            end_rate = man.coeffs["psi_dot"][k][5] + sum(man.coeffs["psi_dot"][k][:5]
                                                          * T ** np.arange(5, 0, -1))
            tl.add(T, psi_dot=sign * end_rate)
        tl.straight(run_out + along + c_along)
    return FlightPath(psi_dot=tl.ppoly("psi_dot"), speed=tl.ppoly("speed"),
                      v_down=tl.ppoly("v_down"), air=tl.ppoly("air"),
                      psi0=b.strip_azimuth, h0=h0, strips=strips, stationary=stationary,
                      t_strip0=t_strip0, duration=tl.t)
