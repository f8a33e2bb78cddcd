"""The image products of a simulated flight folder: camera file, exposure events, true
exterior orientation, tie points and their ground points.

:func:`write_images` is a product writer of :func:`ins.simulate.folder.simulate_flight`
(``writer(flight) -> manifest tables``): it reads the plan's ``[camera]``,
``[terrain]``, ``[tie_points]`` and the exposure interval, evaluates the true trajectory
at the events, and writes (``docs/interfaces.md``)

``camera.toml``
    the frame camera and its mounting (:func:`photogrammetry.orientation.camera.write_camera`);
``events.csv``
    ``image_id,time_s`` (mid-exposure, 1 us);
``eo_true.csv``, ``eo_true_omega-phi-kappa.csv``
    the true EO (:mod:`photogrammetry.simulate.exposures`) in both angle systems
    (:func:`photogrammetry.orientation.exposure.write_eo_csv`);
``tiepoints.csv``, ``ground_points.csv``
    tie points on the seeded terrain (:mod:`photogrammetry.simulate.terrain`,
    :mod:`photogrammetry.simulate.tiepoints`) and their ground truth.

It returns the manifest's ``[files]`` entries, the counts of ``[flight]``, the frames
``c`` and ``m``, ``[mapping_frame]`` and ``[tie_points]``.  The terrain and the tie
points draw from their own generators (``product_rng(seed, "terrain/<offset>")``,
``product_rng(seed, "tiepoints")``), so they do not depend on the INS products.
"""
import numpy as np

from ins.common import textformat
from ins.simulate.folder import product_rng, write_bytes
from photogrammetry.orientation.camera import CameraMounting, FrameCamera, write_camera
from photogrammetry.orientation.exposure import ExposureOrientation, write_eo_csv
from photogrammetry.orientation.mapping import EnuFrame
from photogrammetry.simulate.exposures import event_times, true_exposures
from photogrammetry.simulate.terrain import make_terrain
from photogrammetry.simulate.tiepoints import simulate_tiepoints

__all__ = ["FILES", "write_images", "camera_of"]

#: Manifest ``[files]`` key -> file name of the image products.
FILES = {"events": "events.csv", "camera": "camera.toml", "eo_true": "eo_true.csv",
         "eo_true_omega_phi_kappa": "eo_true_omega-phi-kappa.csv",
         "tiepoints": "tiepoints.csv", "ground_points": "ground_points.csv"}


def camera_of(plan):
    """(FrameCamera, CameraMounting) of the plan's ``[camera]``."""
    c = plan.camera
    camera = FrameCamera(c.focal_length_mm, c.pixel_size_mm, c.width_px, c.height_px,
                         c.principal_point_px, c.radial_k, c.tangential_p)
    mounting = CameraMounting(axes=np.array(c.axes), lever_arm_m=np.array(c.lever_arm_m),
                              boresight_rad=np.deg2rad(c.boresight_deg))
    return camera, mounting


def write_images(flight):
    """Write the image products of a flight (module docstring).

    Parameters
    ----------
    flight : ins.simulate.folder.FlightProducts
        The plan, the truth, the folder being built, the seed and a progress callback.

    Returns
    -------
    dict
        The manifest tables this writer adds.
    """
    plan, truth, folder, seed = flight.plan, flight.truth, flight.folder, flight.seed
    camera, mounting = camera_of(plan)
    write_camera(folder / FILES["camera"], camera, mounting)
    b = plan.block
    origin = np.array([b.origin_lat, b.origin_lon, b.origin_h])
    exposures = true_exposures(truth, *event_times(truth.strips, plan.exposure_interval_s),
                               mounting.C_bc, mounting.lever_arm_m, origin)
    _write_events(folder / FILES["events"], exposures)
    _write_eo(folder / FILES["eo_true"], exposures, "phi-omega-kappa")
    _write_eo(folder / FILES["eo_true_omega_phi_kappa"], exposures, "omega-phi-kappa")
    flight.progress(0.25)
    t = plan.terrain
    terrain = make_terrain(t.relief_m, t.wavelength_m,
                           product_rng(seed, f"terrain/{t.seed_offset}"))
    tp = simulate_tiepoints(exposures, camera, terrain, plan.tie_points.per_image,
                            plan.tie_points.sigma_px, product_rng(seed, "tiepoints"),
                            progress=lambda d, n: flight.progress(0.25 + 0.625 * d / max(n, 1)))
    _write_tiepoints(folder / FILES["tiepoints"], tp, exposures, camera.pixel_size_mm)
    _write_ground(folder / FILES["ground_points"], tp, exposures)
    flight.progress(1.0)
    return {
        "flight": {"n_images": len(exposures), "n_tiepoint_observations": len(tp)},
        "files": dict(FILES),
        "frames": {
            "c": "camera: x, y image axes (x right, y up), z opposite to the view; "
                 "ray (x, y, -f)",
            "m": "ENU at block origin"},
        "mapping_frame": {"type": "enu", "origin_lat_deg": float(np.rad2deg(b.origin_lat)),
                          "origin_lon_deg": float(np.rad2deg(b.origin_lon)),
                          "origin_h_m": float(b.origin_h)},
        "tie_points": {"sigma_px": float(plan.tie_points.sigma_px),
                       "per_image": int(plan.tie_points.per_image)},
    }


# ---------------------------------------------------------------------------------------
# the files

def _csv_rows(ids, values, decimals):
    """Lines ``id,v1,v2,...`` (bytes): string ids, fixed-point numbers."""
    if len(ids) == 0:
        return b""
    text = textformat.format_fixed(values, np.asarray(decimals, np.int64), sep=",").tobytes()
    lines = text.split(b"\n")[:-1]
    return b"".join(i.encode() + b"," + line + b"\n" for i, line in zip(ids, lines))


def _frame_text(exposures):
    return EnuFrame(*exposures.origin_lla).header()


def _write_eo(path, exposures, system):
    """EO CSV of ``docs/interfaces.md`` (:func:`photogrammetry.orientation.exposure.write_eo_csv`)."""
    eo = ExposureOrientation(exposures.image_id, exposures.time, exposures.X_m,
                             exposures.angles(system), system, _frame_text(exposures))
    write_eo_csv(path, eo, comments=("true exterior orientation of the simulated flight",))


def _write_events(path, exposures):
    write_bytes(path, b"image_id,time_s\n" + _csv_rows(exposures.image_id,
                                                      exposures.time[:, None], [6]))


def _write_tiepoints(path, tp, exposures, pixel_size_mm):
    header = (f"# tie points: observed photo coordinates (mm, origin at the principal point, "
              f"distorted as in camera.toml) with white Gaussian noise sigma_px = "
              f"{tp.sigma_px:g} (sigma_mm = {tp.sigma_px * pixel_size_mm:g}) per "
              f"coordinate\nimage_id,point_id,x_mm,y_mm\n")
    ids = [exposures.image_id[i] for i in tp.image_index]
    values = np.column_stack([tp.point_id, tp.xy_mm])
    write_bytes(path, header.encode() + _csv_rows(ids, values, [0, 7, 7]))


def _write_ground(path, tp, exposures):
    header = (f"# ground truth of the tie points, mapping frame {_frame_text(exposures)}\n"
              "point_id,X_m,Y_m,Z_m\n")
    text = textformat.format_fixed(np.column_stack([tp.ground_id, tp.ground_m]),
                                np.array([0, 6, 6, 6], np.int64), sep=",").tobytes()
    write_bytes(path, header.encode() + text)
