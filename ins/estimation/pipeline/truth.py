"""Errors of a run of ``ins process`` against a truth ``.nav`` file (a simulated flight's
``truth.nav``): :func:`with_truth`, piece by piece, bounded memory."""
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
                    continue
        if not parts:
            raise InputError(f"{truth_path}: the trajectories share no epoch (times must "
                             f"match within 1 us)")
        return TrajectoryErrors(*(np.concatenate([getattr(p, f) for p in parts])
                                  for f in ("time", "pos_n", "v_n", "att_n")))
    return replace(result, errors_forward=errors(result.iter_forward()),
                   errors_smoothed=errors(result.iter_smoothed()))
