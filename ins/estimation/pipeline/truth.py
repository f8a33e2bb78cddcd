"""Errors of a run of ``ins process`` against a truth ``.nav`` file (a simulated flight's
``truth.nav``): :func:`with_truth`, piece by piece, bounded memory.

The errors are taken on the epochs the solution shares with the truth (within 1 us);
a piece of the solution that shares none (an IMU whose stamps are not those of the
truth: a phone's jittered sensor clock, :mod:`ins.simulate.gnsslogger_writer`) is
compared with the truth interpolated to its epochs (:func:`ins.nav.interpolation.
interpolate_trajectory`: cubic Hermite positions on the truth's velocities, cubic
attitude), inside the truth's span."""
from dataclasses import replace

import numpy as np

from ins.common.errors import InputError
from ins.nav.trajectory import Trajectory


def with_truth(result, truth_path):
    """``result`` with its errors against a truth ``.nav`` file (piece by piece)."""
    from ins.io.navfiles import read_trajectory
    from ins.nav.accuracy import TrajectoryErrors, compare
    truth = read_trajectory(truth_path)

    def errors(pieces):
        parts = []
        for piece in pieces:
            lo, hi = np.searchsorted(truth.time, [piece.time[0] - 1e-6, piece.time[-1] + 1e-6])
            if hi > lo:
                ref = Trajectory(truth.time[lo:hi], truth.lla[lo:hi], truth.v_n[lo:hi],
                                 truth.q_nb[lo:hi])
                try:
                    parts.append(compare(piece, ref))
                except ValueError:
                    inner = _interpolated(piece, truth)
                    if inner is not None:
                        parts.append(compare(*inner))
        if not parts:
            raise InputError(f"{truth_path}: the trajectories share no epoch (times must "
                             f"match within 1 us, or lie inside the truth's span)")
        return TrajectoryErrors(*(np.concatenate([getattr(p, f) for p in parts])
                                  for f in ("time", "pos_n", "v_n", "att_n")))
    return replace(result, errors_forward=errors(result.iter_forward()),
                   errors_smoothed=errors(result.iter_smoothed()))


def _interpolated(piece, truth):
    """``(the piece's epochs inside the truth, the truth interpolated there)``, or None
    when none is inside."""
    from ins.nav.interpolation import interpolate_trajectory
    inside = (piece.time >= truth.time[0]) & (piece.time <= truth.time[-1])
    if not np.any(inside) or len(truth.time) < 2:
        return None
    est = Trajectory(piece.time[inside], piece.lla[inside], piece.v_n[inside],
                     piece.q_nb[inside])
    lo, hi = np.searchsorted(truth.time, [est.time[0], est.time[-1]])
    lo, hi = max(lo - 1, 0), min(hi + 1, len(truth.time))
    ref = Trajectory(truth.time[lo:hi], truth.lla[lo:hi], truth.v_n[lo:hi], truth.q_nb[lo:hi])
    return est, interpolate_trajectory(ref, est.time)
