"""Photogrammetric orientation: exterior orientation of exposures from an INS
trajectory, coplanarity adjustment of their angles with an INS assessment and boresight,
tie points from images, SfM projects in and out, and heading from fisheye images of the
Moon.

Subpackages, lowest first: :mod:`~photogrammetry.imagery` (images, features, tie points),
:mod:`~photogrammetry.orientation` (angle systems, camera, exposures, mapping frames,
drone metadata), :mod:`~photogrammetry.adjustment` (coplanarity pairs and blocks,
assessment, batches and tiles, report), :mod:`~photogrammetry.sfm`,
:mod:`~photogrammetry.lunar`, :mod:`~photogrammetry.simulate` and
:mod:`~photogrammetry.cli`.  The names below are the public API, imported on first use.
"""

__version__ = "0.1.0"

from ins.common.lazy import lazy_api  # noqa: E402

_LAZY = {
    "FrameCamera": "orientation.camera", "CameraMounting": "orientation.camera",
    "read_camera": "orientation.camera", "write_camera": "orientation.camera",
    "ExposureOrientation": "orientation.exposure", "compute_eo": "orientation.exposure",
    "read_events": "orientation.exposure", "read_solution_std": "orientation.exposure",
    "read_eo_csv": "orientation.exposure", "write_eo_csv": "orientation.exposure",
    "parse_frame": "orientation.mapping", "boresight_sigma": "orientation.boresight_sigma",
    "angles_to_matrix": "orientation.rotation", "matrix_to_angles": "orientation.rotation",
    "TiePoints": "imagery.tiepoints", "read_tiepoints": "imagery.tiepoints",
    "write_tiepoints": "imagery.tiepoints",
    "refine": "adjustment.batch", "RefineResult": "adjustment.batch",
    "adjust_pairs": "adjustment.coplanarity", "adjust_block": "adjustment.block",
    "assess": "adjustment.assessment", "write_report": "adjustment.report",
    "heading_from_images": "lunar", "heading_from_centres": "lunar",
    "simulate_flight": "simulate.folder",
}


__getattr__, __dir__ = lazy_api(__name__, _LAZY)

__all__ = sorted(_LAZY)
