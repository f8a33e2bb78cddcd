"""One refinement run (a block from its files' contents) and many of them on Dask.

:func:`refine` is the unit of work: EO, tie points and camera in, refined EO, block
adjustment and INS assessment out.  :func:`refine_many` runs several blocks or flights as
tasks on ``dask.distributed`` (a local cluster by default, or an existing scheduler's
address; :func:`ins.common.dask_tasks.map_tasks`, re-exported here); the tasks are pure
functions of their inputs, so the results are identical to running :func:`refine` on each
block in one process.
"""
from dataclasses import dataclass, field, replace

import numpy as np

from ins.common.dask_tasks import map_tasks
from ins.common.errors import InputError, QualityError
from ins.nav.rotation import wrap_to_pi
from photogrammetry.adjustment.assessment import assess
from photogrammetry.adjustment.block import adjust_block

__all__ = ["RefineResult", "refine", "refine_many", "check_quality", "prepare",
           "map_tasks"]


@dataclass
class RefineResult:
    """Result of :func:`refine`.

    Attributes
    ----------
    eo : photogrammetry.orientation.exposure.ExposureOrientation
        Refined angles (wrapped to (-pi, pi]) with their sigmas (positions as given).
    prior : photogrammetry.orientation.exposure.ExposureOrientation
        The input in the working system.
    block : photogrammetry.adjustment.block.BlockResult
    assessment : photogrammetry.adjustment.assessment.Assessment
    pairs : ndarray (P, 2)
    pair_points : list of (xy_i, xy_j)
    settings : dict
    warnings : list of (category, str)
        The warnings of the run (re-issued by :func:`refine_many` in the caller).
    """
    eo: object
    prior: object
    block: object
    assessment: object
    pairs: np.ndarray
    pair_points: list
    settings: dict
    warnings: list = field(default_factory=list)


def refine(eo, tiepoints, camera=None, system=None, method="base-free", datum="first",
           sigma_mm=None, prior_sigma_rad=None, position_sigma_m=None, snooping=True,
           progress=None, accept_poor=False, assess_progress=None):
    """Refine the angles of one block.

    Parameters
    ----------
    eo : photogrammetry.orientation.exposure.ExposureOrientation
        INS exterior orientation (angles rad, positions m in the mapping frame).
    tiepoints : photogrammetry.imagery.tiepoints.TiePoints
    camera : photogrammetry.orientation.camera.FrameCamera, optional
        Principal distance and distortion (required).
    system : str, optional
        Working and output angle system (default: the EO's).
    method : {"known-base", "relative", "base-free"}
    datum : {"first", "ins", "none"}
    sigma_mm : float, optional
        Photo-coordinate sigma, mm (default: the tie-point file's header, else 0.5 px).
    prior_sigma_rad : float or array_like (3,), optional
        INS angle sigma for datum "ins" (default: the EO file's sigmas, else 0.005 rad).
    position_sigma_m : float, optional
        Sigma of the EO positions, m, per coordinate (known-base: propagated into the
        angles' covariance; default: the EO file's position sigmas, else exact bases).
    progress : callable(done, total), optional
        Called after each iteration of the block adjustment.
    accept_poor : bool
        Return a result whose pairs or images are flagged as implausible
        (``result.block.quality``, :mod:`photogrammetry.adjustment.quality`) instead of raising.
    assess_progress : callable(done, total), optional
        Called after each round of the INS assessment's boresight fit.

    Returns
    -------
    RefineResult

    Raises
    ------
    ins.common.errors.QualityError
        A pair's or the block's sigma0, or an image's angle change, is implausible
        (without `accept_poor`); the message names them.
    """
    eo, sigma_mm, prior_sigma_rad, position_sigma_m, pairs, points, point_ids = prepare(
        eo, tiepoints, camera, system, method, sigma_mm, prior_sigma_rad, position_sigma_m)
    system = eo.system
    block = adjust_block(eo.angles, pairs, points, camera.focal_length_mm, system, method,
                         datum, positions=eo.position, prior_sigma=prior_sigma_rad,
                         sigma_mm=sigma_mm, position_sigma=position_sigma_m, point_ids=point_ids,
                         snooping=snooping, progress=progress,
                         image_ids=[str(i) for i in eo.image_id])
    check_quality(block.quality, accept_poor)
    result_eo, settings = refined_eo_and_settings(eo, block, camera, method, datum, sigma_mm,
                                                  snooping, position_sigma_m, pairs, tiepoints)
    return RefineResult(result_eo, eo, block, assess(block, eo.angles, system, datum, method,
                                                    progress=assess_progress),
                        pairs, points, settings)


def prepare(eo, tiepoints, camera, system=None, method="base-free", sigma_mm=None,
            prior_sigma_rad=None, position_sigma_m=None):
    """The defaults of :func:`refine` resolved and the block's pairs formed.

    Returns
    -------
    eo : ExposureOrientation
        In the working system.
    sigma_mm : float
    prior_sigma_rad : float or ndarray
    position_sigma_m : float, ndarray or None
    pairs, points, point_ids
        As from :meth:`photogrammetry.imagery.tiepoints.TiePoints.pairs` (``min_common`` 3 for
        known-base, else 5).
    """
    if camera is None:
        raise InputError("the camera (principal distance) is required: --camera CAM.toml")
    if system is not None:
        eo = eo.in_system(system)
    if sigma_mm is None:
        if tiepoints.sigma_mm == 0:
            raise InputError("the tie points state a photo-coordinate sigma of 0 "
                             "(noise-free); the conditions need a weight: give a sigma > 0 "
                             "(--sigma-px)", path=tiepoints.path)
        sigma_mm = (tiepoints.sigma_mm if tiepoints.sigma_mm is not None
                    else 0.5 * camera.pixel_size_mm)
    if prior_sigma_rad is None:
        prior_sigma_rad = eo.angle_sigma if eo.angle_sigma is not None else 0.005
    if position_sigma_m is None and eo.position_sigma is not None:
        position_sigma_m = eo.position_sigma
    min_common = 3 if method == "known-base" else 5
    pairs, points, point_ids = tiepoints.pairs(list(eo.image_id), camera, min_common=min_common)
    if len(pairs) == 0:
        raise InputError(f"no pair of images shares {min_common} or more tie points",
                         path=tiepoints.path)
    return eo, sigma_mm, prior_sigma_rad, position_sigma_m, pairs, points, point_ids


def refined_eo_and_settings(eo, block, camera, method, datum, sigma_mm, snooping,
                            position_sigma_m, pairs, tiepoints):
    """The refined EO (the block's angles and sigmas, positions as given) and the
    settings of a refinement (the report's header)."""
    # the adjustment may carry unwrapped angles (kappa 180.05 deg beside -179.93 deg in a
    # strip flown at 180 deg); the refined EO holds them wrapped to (-pi, pi]
    result_eo = replace(eo, angles=wrap_to_pi(block.angles), angle_sigma=block.sigma,
                        position_sigma=(eo.position_sigma if eo.position_sigma is not None
                                        else np.zeros((len(eo), 3))))
    settings = {"method": method, "datum": datum, "system": eo.system, "sigma_mm": sigma_mm,
                "pixel_size_mm": camera.pixel_size_mm, "f_mm": camera.focal_length_mm,
                "snooping": snooping, "position_sigma_m": (
                    0.0 if position_sigma_m is None
                    else float(np.sqrt(np.mean(np.square(position_sigma_m))))),
                "n_images": len(eo), "n_pairs": len(pairs),
                "n_observations": len(tiepoints)}
    return result_eo, settings


def check_quality(quality, accept_poor=False, where=""):
    """Raise QualityError for a poor result unless `accept_poor` (the first findings)."""
    if quality is None or not quality.poor or accept_poor:
        return
    more = len(quality.reasons) - 3
    raise QualityError(f"{where}refinement not to be trusted: "
                       + "; ".join(quality.reasons[:3])
                       + (f" (and {more} more)" if more > 0 else "")
                       + " (rule: photogrammetry refine --help, 'trust')")


def refine_many(tasks, workers=None, scheduler=None, progress=None, processes=True):
    """Run :func:`refine` on many blocks as Dask tasks.

    Parameters
    ----------
    tasks : sequence of dict
        Keyword arguments of :func:`refine`, one dict per block.
    workers : int, optional
        Size of the local cluster (default: the number of cores); ``1`` with no
        scheduler runs in this process without Dask.
    scheduler : str, optional
        Address of a running ``dask.distributed`` scheduler (``tcp://host:8786``).
    progress : callable(done, total), optional
    processes : bool
        Local cluster of processes (default) or of threads in this process.

    Returns
    -------
    list of RefineResult, in the order of `tasks`.
    """
    return map_tasks(refine, tasks, workers, scheduler, progress, processes)
