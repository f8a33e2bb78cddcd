"""Accuracy of a block adjustment and assessment of the INS angles against it.

Per image ``i`` the INS-minus-adjusted angle differences ``d_i`` (rad, system order).
With the INS attitude ``R_ins = R_true @ B^T`` (``B = Rx(rx) Ry(ry) Rz(rz)`` the boresight
misalignment of the camera file, ``C_bc = axes @ B``) plus white noise, to first order
``d_i = -J_i beta + e_i`` with ``beta = (rx, ry, rz)`` and ``J_i = M_i^-1 R_i`` (``M_i``
the model-frame axes of the angles): the boresight is the least-squares fit of that
model over the images (for a single-heading block it reduces to the mean of ``d``; for
strips flown back and forth the mean of phi and omega cancels, the fit does not).
The INS angle noise is ``sqrt(mean(e^2) - sigma_adj^2)``: the scatter of the
differences after the boresight, with the adjustment's own variance removed.

The boresight is only observable when the block's orientation does not come from the
INS (``known-base`` with GNSS bases); with datum ``first`` or ``ins`` it is absorbed by
the datum and the report says so; the fit then also takes out a common model-frame
rotation of the block (the datum's own INS error), so the noise estimate stays valid.
"""
from dataclasses import dataclass

import numpy as np

from ins.rotation import rotvec_to_dcm, wrap_to_pi

from . import _coplanarity_kernels as K
from .rotation import matrix_to_angles

__all__ = ["Assessment", "assess"]


@dataclass
class Assessment:
    """INS assessment of a block (all angles rad, system order unless stated).

    Attributes
    ----------
    names : tuple of str
        Angle names in system order.
    used : ndarray of bool (m,)
        Images compared (adjusted, not the datum image).
    diff : ndarray (m, 3)
        INS minus adjusted angles (0 where not used).
    mean, mean_sigma, rms : ndarray (3,)
        Per angle over the used images.
    boresight : ndarray (3,)
        Estimated misalignment (rx, ry, rz), rad, as ``boresight_deg`` of the camera file.
    boresight_sigma : ndarray (3,)
    boresight_observable : bool
    ins_noise : ndarray (3,)
        Per-angle INS noise with the adjustment's own uncertainty removed (0 if negative).
    residual_rms : ndarray (3,)
        RMS of the differences after removing the boresight.
    adj_sigma_rms : ndarray (3,)
        RMS of the adjustment's own per-angle sigma over the used images.
    correlations : ndarray (m, 3, 3)
        Correlation of each image's three adjusted angles.
    """
    names: tuple
    used: np.ndarray
    diff: np.ndarray
    mean: np.ndarray
    mean_sigma: np.ndarray
    rms: np.ndarray
    boresight: np.ndarray
    boresight_sigma: np.ndarray
    boresight_observable: bool
    ins_noise: np.ndarray
    residual_rms: np.ndarray
    adj_sigma_rms: np.ndarray
    correlations: np.ndarray


def _image_correlations(cov, m):
    blocks = np.stack([cov[3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(m)])
    s = np.sqrt(np.einsum("mii->mi", blocks))
    inv = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 0.0)
    return blocks * inv[:, :, None] * inv[:, None, :]


def assess(result, angles_ins, system, datum, method):
    """Compare the INS angles with a block adjustment.

    Parameters
    ----------
    result : photogrammetry.block.BlockResult
    angles_ins : array_like (m, 3)
        INS angles, rad, system order.
    system : str
    datum : {"first", "ins", "none"}
    method : {"known-base", "relative", "base-free"}

    Returns
    -------
    Assessment
    """
    ins = np.asarray(angles_ins, dtype=float)
    m = len(ins)
    used = result.adjusted & (result.sigma.max(axis=1) > 0)
    diff = np.where(used[:, None], wrap_to_pi(ins - result.angles), 0.0)
    d = diff[used]
    k = len(d)
    mean = d.mean(axis=0) if k else np.zeros(3)
    spread = d.std(axis=0, ddof=1) if k > 1 else np.zeros(3)
    mean_sigma = spread / np.sqrt(max(k, 1))
    rms = np.sqrt(np.mean(d ** 2, axis=0)) if k else np.zeros(3)
    R, M = K.rotation_and_axes(result.angles[used], system)
    J = np.linalg.solve(M, R)                   # d_angles = J @ camera-frame rotation
    observable = method == "known-base" and datum != "first"
    beta, beta_sigma, e = np.zeros(3), np.zeros(3), d - mean
    if k > 6:
        # regressors: the camera-frame boresight, and (when the datum comes from the INS)
        # a common model-frame rotation of the whole block as well
        X = -J if observable else np.concatenate([-J, np.linalg.inv(M)], axis=2)
        A = X.reshape(3 * k, -1)
        v, *_ = np.linalg.lstsq(A, d.ravel(), rcond=1e-10)
        e = d - (A @ v).reshape(k, 3)
        if observable:
            s2 = np.sum(e ** 2) / max(3 * k - 3, 1)
            beta_sigma = np.sqrt(s2 * np.diag(np.linalg.inv(A.T @ A)))
            beta = matrix_to_angles(rotvec_to_dcm(v), "omega-phi-kappa")   # Rx Ry Rz angles
    adj_var = np.mean(result.sigma[used] ** 2, axis=0) if k else np.zeros(3)
    n_fit = 3 if observable else 6
    res_ms = np.sum(e ** 2, axis=0) / max(k - n_fit / 3.0, 1)
    ins_noise = np.sqrt(np.maximum(res_ms - adj_var, 0.0))
    names = tuple(system.split("-"))
    return Assessment(names, used, diff, mean, mean_sigma, rms, beta, beta_sigma, observable,
                      ins_noise, np.sqrt(res_ms), np.sqrt(adj_var),
                      _image_correlations(result.cov, m))
