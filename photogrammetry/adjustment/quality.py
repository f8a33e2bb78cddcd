"""Trust of a refinement: implausible sigma0 or angle changes, per pair and per block.

The rule (stated in ``photogrammetry refine --help`` and docs/interfaces.md):

- **sigma0**: the a-posteriori sigma of unit weight (1 = the stated photo-coordinate
  sigma) of a pair (its pair-wise screening) or of the block is implausible when it
  exceeds :func:`sigma0_limit` of its redundancy ``r``: ``max(2, sqrt(chi2_q(r) / r))``
  with ``q = 1 - 0.001 / P`` for the P pairs of a block (the 99.9 % point shared by all
  of them: no false alarm from the sheer number of pairs) and ``q = 0.999`` for the
  block -- the residuals are more than twice the stated sigma, and beyond that point of
  their distribution.  Pairs of redundancy below 5 (a few points) are not judged on
  their own (their screening from the prior may end in a far local minimum): the block
  judges their points.
- **redundancy**: a block whose redundancy is below 5 after the outlier tests rejected
  tie points (a pair of 8 points with 2 mismatches: redundancy 1-3) is flagged: the
  tests kept the subset that fits, and the few conditions left can neither tell it from
  a wrong one nor give a sigma0 worth the name (0.2-0.4 seen, so the sigmas, scaled by
  it, shrink; errors of 7-26 of those sigmas passed every test).
- **angle change**: an image's refined angle differs from its prior (INS) angle by more
  than ``5 sqrt(2 s_prior^2 + s_adj^2)`` (any of the three angles; ``s_prior`` the prior
  sigma of the angle, ``s_adj`` its adjusted sigma: the change holds the image's own INS
  error and, through the datum, that of another image).  With ``known-base`` and datum
  ``none`` the changes also hold the boresight misalignment (common to all images, in
  the camera frame): they are judged as the camera-frame rotation from the refined to
  the prior attitude less its median over the images, each component against the
  largest of the image's three limits.  For a pair's screening (image i
  held at its prior) only a change beyond 5 deg and 5 of the screening's sigmas is
  flagged (the pair is left out):
  a boresight changes the relative orientation of a cross-strip pair by up to twice its
  size, and a weak pair (few points, a short overlap) moves far within its own,
  unreliable, sigma; the images are judged in the block.

A flagged pair or image makes the result poor: ``photogrammetry refine`` exits 3
(:class:`ins.common.errors.QualityError`) unless ``--accept-poor``, which writes the outputs
with the flags in the CSV comments and the report.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from ins.nav.rotation import wrap_to_pi

__all__ = ["Quality", "sigma0_limit", "change_limit", "block_quality", "unadjusted_quality",
           "CHANGE_FACTOR", "SIGMA0_FLOOR"]

#: sigma0 is implausible above max(SIGMA0_FLOOR, sqrt(chi2_0.999(r) / r)).
SIGMA0_FLOOR = 2.0
#: An angle change is implausible beyond CHANGE_FACTOR sqrt(2 s_prior^2 + s_adj^2).
CHANGE_FACTOR = 5.0
#: Pairs whose screening has a smaller redundancy are not judged on their own.
WEAK_REDUNDANCY = 5
_AS = 180.0 / np.pi * 3600.0


@dataclass
class Quality:
    """Trust flags of a block.

    Attributes
    ----------
    poor : bool
        Any flag set (the command exits 3 without ``--accept-poor``).
    reasons : list of str
        One line per finding, in the user's units (px, arcsec).
    pair_flags : ndarray of bool (P,)
    image_flags : ndarray of bool (m,)
    sigma0_limit : float
        The block's sigma0 limit.
    """
    poor: bool = False
    reasons: list = field(default_factory=list)
    pair_flags: np.ndarray = None
    image_flags: np.ndarray = None
    sigma0_limit: float = np.nan


def sigma0_limit(redundancy, tests=1):
    """Largest plausible sigma0 at redundancy ``r`` (array or scalar; NaN where r < 1),
    at the 99.9 % point shared by `tests` tests (Bonferroni: each at 0.001 / tests)."""
    r = np.asarray(redundancy, dtype=float)
    safe = np.maximum(r, 1.0)
    lim = np.maximum(SIGMA0_FLOOR, np.sqrt(chi2.isf(0.001 / max(tests, 1), safe) / safe))
    return np.where(r >= 1, lim, np.nan)


def change_limit(prior_sigma, adj_sigma=0.0):
    """Largest plausible change of an angle from its prior, rad."""
    return CHANGE_FACTOR * np.sqrt(2.0 * np.square(prior_sigma) + np.square(adj_sigma))


def _changes(angles, prior, system, common_rotation):
    """Per image the change from the prior (rad, (m, 3)): the angle differences, or with
    `common_rotation` the camera-frame rotation vector from the adjusted to the prior
    attitude less its median over the images (a common camera-frame rotation is the
    boresight misalignment, which a known-base block with datum none estimates)."""
    if not common_rotation:
        return np.abs(wrap_to_pi(angles - prior))
    from ins.nav.rotation import dcm_to_rotvec
    from photogrammetry.orientation.rotation import angles_to_matrix
    v = dcm_to_rotvec(np.swapaxes(angles_to_matrix(angles, system), 1, 2)
                      @ angles_to_matrix(prior, system))
    return np.abs(v - np.median(v, axis=0))


def block_quality(pairs, pair_sigma0, pair_redundancy, pair_change, pair_sigma, sigma0,
                  redundancy, angles, prior, prior_sigma, adj_sigma, adjusted, names=None,
                  system=None, common_rotation=False, strayed=None, n_rejected=0):
    """Flag the pairs and images of a block whose sigma0 or angle change is implausible.

    Parameters
    ----------
    pairs : ndarray (P, 2)
    pair_sigma0, pair_redundancy : ndarray (P,)
        Of each pair's screening (NaN sigma0: not estimable, not flagged).
    pair_change : ndarray (P, 3)
        Screening angles of image j minus its prior, rad (NaN for failed pairs).
    pair_sigma : ndarray (P, 3)
        Their sigmas from the screening, rad.
    sigma0 : float; redundancy : int
        The block's.
    angles, prior : ndarray (m, 3)
        Refined and prior angles, rad.
    prior_sigma, adj_sigma : ndarray (m, 3)
        Rad.
    adjusted : ndarray of bool (m,)
    names : sequence of str, optional
        Image ids for the messages (default: indices).
    system : str
        Angle system (with `common_rotation`).
    common_rotation : bool
        Judge the images' changes after removing a common camera-frame rotation (the
        boresight: known-base, datum none), as rotation-vector components.
    strayed : ndarray of bool (P,), optional
        Pairs left out because their screening went beyond any plausible change
        (flagged).
    n_rejected : int
        Tie points rejected by the screening and the block's snooping: with any, a
        block redundancy below :data:`WEAK_REDUNDANCY` is flagged (the tests chose the
        subset that fits; too few conditions are left to tell it from a wrong one, and
        its sigma0 -- and the sigmas scaled by it -- are biased low).

    Returns
    -------
    Quality
    """
    names = list(range(len(angles))) if names is None else list(names)
    reasons = []
    plim = sigma0_limit(pair_redundancy, tests=len(pairs))
    # a weak pair (redundancy < 5) is judged in the block: its pair-wise screening from
    # the prior may end in a far local minimum (6 points, 36 deg off: sigma0 8.8)
    bad_s0 = (np.isfinite(pair_sigma0) & (np.asarray(pair_redundancy) >= WEAK_REDUNDANCY)
              & (pair_sigma0 > plim))
    pchange = np.abs(wrap_to_pi(pair_change))
    pj = prior_sigma[pairs[:, 1]] if len(pairs) else np.zeros((0, 3))
    plim_change = change_limit(pj, np.nan_to_num(pair_sigma))
    # a pair's own change is not judged (a boresight changes the relative orientation
    # of a cross-strip pair by up to twice its size, and a weak pair moves far within
    # its unreliable sigma): only a screening beyond any plausible change (`strayed`)
    bad_change = np.zeros(len(pairs), bool)
    strayed = np.zeros(len(pairs), bool) if strayed is None else np.asarray(strayed)
    for k in np.flatnonzero(strayed):
        reasons.append(f"pair {names[pairs[k, 0]]}-{names[pairs[k, 1]]}: its screening "
                       f"moved {names[pairs[k, 1]]} beyond 5 deg and 5 sigma from the prior "
                       "(left out)")
    for k in np.flatnonzero(bad_s0 | bad_change):
        i, j = pairs[k]
        what = []
        if bad_s0[k]:
            what.append(f"sigma0 {pair_sigma0[k]:.2f} > {plim[k]:.2f}")
        if bad_change[k]:
            what.append(f"angle change of {names[j]} {pchange[k].max() * _AS:.0f} arcsec > "
                        f"{plim_change[k, np.argmax(pchange[k])] * _AS:.0f}")
        reasons.append(f"pair {names[i]}-{names[j]}: " + ", ".join(what))
    blim = float(sigma0_limit(redundancy))
    if np.isfinite(sigma0) and sigma0 > blim:
        reasons.append(f"block sigma0 {sigma0:.2f} > {blim:.2f} (redundancy {redundancy})")
    if n_rejected and redundancy < WEAK_REDUNDANCY:
        reasons.append(f"block redundancy {redundancy} after rejecting {n_rejected} tie "
                       f"points (< {WEAK_REDUNDANCY}): too few conditions left to tell the "
                       "outliers from a wrong solution")
    change = np.zeros(np.shape(angles))
    if adjusted.any():
        change[adjusted] = _changes(angles[adjusted], prior[adjusted], system,
                                    common_rotation)
    lim = change_limit(prior_sigma, adj_sigma)
    if common_rotation:            # rotation-vector components: the largest sigma each
        lim = np.repeat(np.max(lim, axis=1, keepdims=True), 3, axis=1)
    image_flags = adjusted & np.any(change > lim, axis=1)
    for i in np.flatnonzero(image_flags):
        a = int(np.argmax(change[i] / lim[i]))
        reasons.append(f"image {names[i]}: angle change {change[i, a] * _AS:.0f} arcsec > "
                       f"{lim[i, a] * _AS:.0f}")
    return Quality(bool(reasons), reasons, bad_s0 | bad_change | strayed, image_flags, blim)


def unadjusted_quality(pairs, status, kept, rejected, m, names, why, status_text):
    """The flags of a block whose conditions vanished in the screening (nothing
    adjusted, every image at its prior): poor, `why` first, then each pair left out with
    the points it kept.

    Parameters
    ----------
    pairs : ndarray (P, 2); status : ndarray of int (P,)
    kept, rejected : ndarray of bool (P, n)
        The screening's kept and rejected points.
    m : int
        Images.
    names : sequence of str or None
    why : str
    status_text : dict status -> text
    """
    names = list(range(m)) if names is None else list(names)
    reasons = [f"block not adjusted: {why}; every image left at its prior angles"]
    for k in np.flatnonzero(np.asarray(status) != 0):
        reasons.append(f"pair {names[pairs[k, 0]]}-{names[pairs[k, 1]]}: "
                       f"{status_text.get(int(status[k]), 'left out')} "
                       f"({int(kept[k].sum())} points kept, {int(rejected[k].sum())} "
                       "rejected)")
    return Quality(True, reasons, np.ones(len(pairs), bool), np.ones(m, bool), np.nan)
