"""A start of the relative orientation that does not depend on the prior: the five-point
essential matrix by RANSAC (OpenCV's ``findEssentialMat``, USAC_MAGSAC) on the normalized
image coordinates, and the pose it holds (``recoverPose``: the rotation and the base
direction that put the points in front of both cameras).

Frames: the camera frame ``c`` of this package has x, y along the image axes and z
opposite to the viewing direction (a ray is ``(x, y, -f)``); OpenCV's camera frame has y
down and z forward: ``v_cv = D v_c`` with ``D = diag(1, -1, -1)``.  OpenCV's pose maps a
point of camera 1 into camera 2, ``X_2cv = R X_1cv + t``; with ``R_k = C_mc`` of image k
that is ``R_2 = R_1 D R^T D`` and the base ``X_2 - X_1`` along ``-R_2 D t`` (unit).

The coplanarity adjustment (:func:`photogrammetry.adjustment.coplanarity.adjust_pairs`)
scores this start beside the minimal samples solved from the prior (MSAC) and keeps the
better one; the refusal of a pair with fewer inliers than its unknowns stays there.
"""
import numpy as np

from photogrammetry.orientation.rotation import matrix_to_angles

__all__ = ["essential_starts", "MIN_POINTS"]

#: Pairs with fewer points get no essential-matrix start (as the MSAC start: a minimal
#: sample of five cannot out-vote anything among fewer than twice its size).
MIN_POINTS = 10
_D = np.diag([1.0, -1.0, -1.0])


def essential_starts(xy1_mm, xy2_mm, mask, f_mm, R1, system, threshold_mm, seed=0,
                     confidence=0.999, max_iters=2000):
    """Image 2's start angles and base direction of every pair from its points alone.

    Parameters
    ----------
    xy1_mm, xy2_mm : ndarray (P, n, 2)
        Ideal photo coordinates, mm (x, y along the image axes).
    mask : ndarray of bool (P, n)
        The real points of each pair.
    f_mm : float or ndarray (P,)
        Principal distance, mm.
    R1 : ndarray (P, 3, 3)
        Image 1's ``C_mc`` (held fixed: the start is relative to it).
    system : str
        Angle system of the returned angles.
    threshold_mm : float or ndarray (P,)
        RANSAC threshold (distance to the epipolar line), mm in the image.
    seed : int
        OpenCV's random generator is seeded with it before every pair (the result does
        not depend on the order or batching of the pairs).

    Returns
    -------
    angles : ndarray (P, 3)
        Rad, `system` order (NaN where no start was found).
    base : ndarray (P, 3)
        Unit base direction in the mapping frame (NaN where none).
    ok : ndarray of bool (P,)
        A start was found: at least :data:`MIN_POINTS` points and an essential matrix
        with at least five points in front of both cameras.
    """
    import cv2
    xy1, xy2 = np.asarray(xy1_mm, float), np.asarray(xy2_mm, float)
    P = xy1.shape[0]
    mask = np.asarray(mask, bool)
    f = np.broadcast_to(np.asarray(f_mm, float), (P,))
    thr = np.broadcast_to(np.asarray(threshold_mm, float), (P,))
    R1 = np.asarray(R1, float).reshape(P, 3, 3)
    angles, base = np.full((P, 3), np.nan), np.full((P, 3), np.nan)
    ok = np.zeros(P, bool)
    eye = np.eye(3)
    for p in range(P):
        idx = np.flatnonzero(mask[p])
        if len(idx) < MIN_POINTS or not (f[p] > 0 and thr[p] > 0):
            continue
        # normalized coordinates in OpenCV's frame: (x / f, -y / f)
        a = np.ascontiguousarray(xy1[p, idx] * [1.0, -1.0] / f[p])
        b = np.ascontiguousarray(xy2[p, idx] * [1.0, -1.0] / f[p])
        cv2.setRNGSeed(int(seed))
        try:
            E, inl = cv2.findEssentialMat(a, b, eye, method=cv2.USAC_MAGSAC,
                                          prob=float(confidence),
                                          threshold=float(thr[p] / f[p]),
                                          maxIters=int(max_iters))
        except cv2.error:
            continue
        if E is None or inl is None or E.shape != (3, 3) or not np.isfinite(E).all():
            continue
        try:
            n_front, R, t, _ = cv2.recoverPose(E, a, b, eye, mask=inl.copy())
        except cv2.error:
            continue
        if n_front < 5:
            continue
        R2 = R1[p] @ _D @ R.T @ _D
        d = -R2 @ _D @ t.ravel()
        norm = np.linalg.norm(d)
        if not norm > 0:
            continue
        angles[p] = matrix_to_angles(R2, system)
        base[p] = d / norm
        ok[p] = True
    return angles, base, ok
