"""The boresight's sigma with the INS attitude's common error over the exposures.

A boresight calibration from a block (``photogrammetry refine --method known-base
--datum none``) compares the INS camera attitude ``R_ins = C_mn C_nb_ins C_bc`` with the
attitude the tie points and GNSS bases give.  With the INS attitude error as a small
rotation ``delta_b(t)`` in the IMU body frame, ``C_nb_ins = C_nb Exp(delta_b)``, and the
camera axes ``C_bc = axes B`` (``B = Rx(rx) Ry(ry) Rz(rz)``, the boresight of the camera
file),

    R_ins = C_mn C_nb axes Exp(delta_c) B,    delta_c = axes^T delta_b,

so that each exposure shows the boresight plus ``delta_c`` (to first order: the rx, ry,
rz of ``B`` are a rotation vector in the camera frame).  The estimate is a weighted mean
over the exposures; its error against the true boresight is

    e = e_adj + mean_i(delta_c(t_i)),

``e_adj`` the adjustment's own error (its covariance: the adjustment's boresight sigma)
and the second term the INS attitude error common to the exposures.  A body-fixed part
of ``delta_b`` (the IMU's uncalibrated axis misalignment levels the platform wrongly; a
heading error is body-fixed about the down axis whatever the heading) cannot be told
from a boresight by any calibration: it must be in the boresight's sigma.

Its variance is ``var(mean_i delta_c) = (1/n^2) sum_ij cov(delta_c(t_i), delta_c(t_j))``.
The smoothed trajectory gives only the per-epoch sigmas (``solution_std.txt``: roll,
pitch, yaw), not the correlation in time.  The INS attitude error is strongly
time-correlated (Schuler period, bias and misalignment states): this module takes it as
FULLY correlated over the block, per camera axis,

    sigma_ins[k] = mean_i sqrt(P_c,i[k, k]),    P_c,i = axes^T diag(s_roll^2, s_pitch^2, s_yaw^2) axes,

(with the roll, pitch, yaw sigmas at the exposure times as the body-frame rotation
variances: exact for level flight, first order in the tilt otherwise).  By Cauchy-Schwarz
this is an upper bound of the sigma of the mean: any decorrelation (e.g. a tilt fixed in
the navigation frame that changes sign in the body between strips flown back and forth)
only lowers it, so the total is conservative.  The total sigma of the boresight is

    sigma_total = sqrt(sigma_adj^2 + sigma_ins^2)

(the INS noise that the adjustment's REML fit takes as white is counted there once
more, at most its sigma over sqrt(n): negligible against the common part).
``bench/bench_boresight_sigma.py`` checks the z-scores over simulated flights.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.nav.interpolation import interpolate_linear

__all__ = ["BoresightSigma", "ins_common_sigma", "boresight_sigma"]


@dataclass(frozen=True)
class BoresightSigma:
    """Sigmas of an estimated boresight (rx, ry, rz of the camera file), rad.

    Attributes
    ----------
    adjustment : ndarray (3,)
        The adjustment's own sigma (tie points, GNSS bases, INS noise as white).
    ins_common : ndarray (3,) or None
        The INS attitude error common to the exposures, in the camera frame (fully
        correlated bound, :func:`ins_common_sigma`); None without the trajectory's
        sigma file.
    source : str or None
        The sigma file it came from (for the report).
    """
    adjustment: np.ndarray
    ins_common: np.ndarray = None
    source: str = None

    @property
    def total(self):
        """``sqrt(adjustment^2 + ins_common^2)`` (rad, (3,)); the adjustment's alone
        without the INS sigma."""
        if self.ins_common is None:
            return np.asarray(self.adjustment, float)
        return np.hypot(self.adjustment, self.ins_common)

    @property
    def has_ins(self):
        return self.ins_common is not None


def ins_common_sigma(std_time, std, times, axes, names=None, path=None):
    """The INS attitude sigma common to the exposures, in the camera frame (rad).

    Parameters
    ----------
    std_time : ndarray (k,)
        Times of the trajectory's sigmas, s.
    std : ndarray (k, 9) or (k, 3)
        Trajectory sigmas as :func:`photogrammetry.orientation.exposure.read_solution_std`
        returns them (N, E, D m; vN, vE, vD m/s; roll, pitch, yaw rad), or the roll,
        pitch, yaw sigmas alone (rad).
    times : ndarray (n,)
        Exposure times, s (inside ``std_time``).
    axes : ndarray (3, 3)
        Camera axes in the IMU body frame (``C_bc`` without the boresight).
    names : sequence of str, optional
        Image ids (for the error message of a time outside the sigmas).
    path : str, optional
        The sigma file (for error messages).

    Returns
    -------
    ndarray (3,)
        ``mean_i sqrt(diag(axes^T diag(s_i^2) axes))``: the sigma of the boresight's
        share of the INS error under full correlation over the exposures (an upper
        bound; module docstring), rx, ry, rz order.
    """
    std = np.asarray(std, float)
    rpy = std[:, 6:9] if std.shape[1] == 9 else std
    if rpy.shape[1] != 3:
        raise ValueError(f"std must have 9 or 3 columns, got {std.shape}")
    times = np.asarray(times, float)
    t = np.asarray(std_time, float)
    outside = np.flatnonzero((times < t[0]) | (times > t[-1]))
    if outside.size:
        k = int(outside[0])
        who = f"exposure {names[k]}" if names is not None else "an exposure"
        raise InputError(f"{who} at t = {float(times[k])!r} s is outside the sigma file's "
                         f"times ({float(t[0])!r} .. {float(t[-1])!r} s; {outside.size} "
                         "such): the trajectory sigmas must cover the exposures", path=path)
    s = interpolate_linear(t, rpy, times, names=names)
    axes = np.asarray(axes, float)
    P_c = np.einsum("ji,nj,jk->nik", axes, s ** 2, axes)
    return np.sqrt(np.einsum("nii->ni", P_c)).mean(axis=0)


def boresight_sigma(adjustment_sigma, std=None, times=None, axes=None, source=None,
                    names=None):
    """:class:`BoresightSigma` of an estimated boresight.

    Parameters
    ----------
    adjustment_sigma : array_like (3,)
        The adjustment's sigma of rx, ry, rz, rad.
    std : (ndarray (k,), ndarray (k, 9)), optional
        The trajectory's sigmas (:func:`photogrammetry.orientation.exposure.read_solution_std`);
        without them the sigma is the adjustment's alone.
    times : ndarray (n,)
        Exposure times, s (needed with ``std``).
    axes : ndarray (3, 3)
        Camera axes in the body frame (needed with ``std``).
    source : str, optional
        The sigma file's name.
    names : sequence of str, optional
        Image ids (error messages).
    """
    adj = np.asarray(adjustment_sigma, float)
    if std is None:
        return BoresightSigma(adj, None, None)
    ins = ins_common_sigma(std[0], std[1], times, axes, names=names, path=source)
    return BoresightSigma(adj, ins, None if source is None else str(source))
