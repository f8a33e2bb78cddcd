"""Refined EO into a COLMAP database as pose priors (pycolmap 4.x, extra ``colmap``).

COLMAP keeps one ``PosePrior`` per image in the ``pose_priors`` table of its SQLite
database: ``corr_data_id`` (the image id), ``corr_sensor_id`` (its camera id),
``corr_sensor_type``, ``position`` (3 float64), ``position_covariance`` (3 x 3
float64, Eigen column-major), ``gravity`` (3 float64) and ``coordinate_system``
(-1 undefined, 0 ``WGS84``, 1 ``CARTESIAN``).  ``colmap pose_prior_mapper`` and the
spatial matcher read it.  What we write for each EO image found in the database:

- ``WGS84`` (the default for an EO in an ``enu`` or ``EPSG:`` frame, and what COLMAP's
  own EXIF reader writes): ``position = (latitude deg, longitude deg, ellipsoidal
  height m)``; ``position_covariance`` in m^2 on the local east, north, up axes at the
  image (the EO's sigmas, given on the mapping-frame axes, turned into them: the ENU
  frame's axes differ from the local ones by the meridians' convergence, a projected
  frame's by the grid convergence; the grid scale, under 0.04 % in UTM, is left out).
  ``pose_prior_mapper`` turns WGS84 priors into ENU metres at the first image and uses
  the covariance as metres there.
- ``CARTESIAN`` (``coordinates="cartesian"``, and the only choice for an EO in a COLMAP
  model's own frame): the EO's positions and covariance as they are (m, mapping-frame
  axes).  A projected frame's grid scale (0.9996-1.0004 in UTM) is then in the priors.
- ``gravity``: the unit downward vertical at the image in the computer-vision camera
  frame (x right, y down, z along the view): ``R_cw @ d_m`` with ``d_m`` the local
  down direction in the mapping frame; the roll and pitch part of the refined rotation
  (glomap's gravity-aligned rotation averaging uses it).  Not written for an EO in a
  COLMAP model's frame (its vertical is unknown).

COLMAP's pose prior (pycolmap 4.2) has no rotation field beyond ``gravity``: the full
refined rotation (heading included) goes to the text model of
:func:`photogrammetry.sfm.colmap.write_colmap_text` (``images.txt``).  An EO without
sigmas leaves the covariance unset (NaN: COLMAP then uses its
``--prior_position_std_*`` options).

Images are matched by name: a database image ``a.jpg`` (or ``sub/a.jpg``) is the EO's
``a`` (or ``a.jpg``).  EO images missing from the database are refused, listed, unless
``add_missing`` adds them (named ``id + suffix``, with one camera of ours, its rig and
a frame per image, as COLMAP's feature extraction lays them out).
"""
import os
import re
import sqlite3
import tempfile

import numpy as np

from ins.common.errors import InputError
from photogrammetry.orientation.mapping import EnuFrame, ProjectedFrame
from photogrammetry.orientation.rotation import P_NED_ENU, to_cv_rotation

__all__ = ["mapping_frame_of", "pose_priors", "write_pose_priors", "PosePriorExport"]

_EXTRA = "pip install 'insphoto[colmap]'"


def _need_pycolmap():
    try:
        import pycolmap
    except ImportError:
        raise InputError(f"writing a COLMAP database needs pycolmap 4: {_EXTRA}") from None
    if not (hasattr(pycolmap, "PosePriorCoordinateSystem") and hasattr(pycolmap, "Rig")
            and hasattr(pycolmap.PosePrior, "corr_data_id")):
        raise InputError(f"pycolmap {getattr(pycolmap, '__version__', '?')} lacks the pose "
                         f"priors of data ids (rigs, frames); a COLMAP database needs "
                         f"pycolmap 4: pip install -U 'insphoto[colmap]'")
    return pycolmap


def mapping_frame_of(header):
    """The mapping frame (:class:`EnuFrame`, :class:`ProjectedFrame`) of an EO's
    ``# frame =`` value, or None for another frame (a COLMAP model's own)."""
    text = str(header).strip()
    parts = [p.strip() for p in text.split(";")]
    if parts[0].lower() == "enu":
        kv = dict(p.split("=", 1) for p in parts[1:] if "=" in p)
        kv = {k.strip(): float(v) for k, v in kv.items()}
        try:
            return EnuFrame.from_degrees(kv["origin_lat_deg"], kv["origin_lon_deg"],
                                         kv.get("origin_h_m", 0.0))
        except KeyError:
            raise InputError(f"EO frame {text!r}: an enu frame needs origin_lat_deg and "
                             "origin_lon_deg") from None
    if parts[0].upper().startswith("EPSG:"):
        m = re.search(r"undulation N = ([-+0-9.eE]+)", text)
        return ProjectedFrame(parts[0].upper(), float(m.group(1)) if m else None)
    return None


def pose_priors(eo, coordinates="auto"):
    """Positions, covariances and gravity directions of the pose priors of an EO.

    Parameters
    ----------
    eo : photogrammetry.orientation.exposure.ExposureOrientation
    coordinates : {"auto", "wgs84", "cartesian"}
        ``auto``: WGS84 when the EO's frame is ``enu`` or ``EPSG:``, else cartesian.

    Returns
    -------
    system : str
        ``"WGS84"`` or ``"CARTESIAN"``.
    position : ndarray (n, 3)
        (lat deg, lon deg, h m) or mapping-frame m.
    covariance : ndarray (n, 3, 3)
        m^2 (local ENU axes for WGS84, mapping-frame axes for cartesian); NaN without
        sigmas.
    gravity : ndarray (n, 3)
        Unit down vector in the CV camera frame; NaN when the frame has no known vertical.
    """
    if coordinates not in ("auto", "wgs84", "cartesian"):
        raise InputError(f"coordinates must be auto, wgs84 or cartesian, got {coordinates!r}")
    frame = mapping_frame_of(eo.frame)
    if coordinates == "wgs84" and frame is None:
        raise InputError(f"WGS84 pose priors need an EO in an enu or EPSG frame, the EO is "
                         f"in {eo.frame!r} (use cartesian)")
    n = len(eo)
    pos = np.asarray(eo.position, float)
    cov = np.full((n, 3, 3), np.nan)
    if eo.position_sigma is not None:
        cov = np.einsum("ni,ij->nij", np.square(eo.position_sigma), np.eye(3))
    gravity = np.full((n, 3), np.nan)
    if frame is None:
        return "CARTESIAN", pos.copy(), cov, gravity
    lla = frame.to_lla(pos)
    C_mn = frame.C_mn(lla)                         # local NED -> mapping axes
    R_cw = to_cv_rotation(eo.matrices())
    gravity = np.einsum("nij,nj->ni", R_cw, C_mn[:, :, 2])
    gravity /= np.linalg.norm(gravity, axis=1, keepdims=True)
    if coordinates == "cartesian":
        return "CARTESIAN", pos.copy(), cov, gravity
    C_m_enu = C_mn @ P_NED_ENU.T                   # local ENU -> mapping axes
    cov = np.einsum("nji,njk,nkl->nil", C_m_enu, cov, C_m_enu)
    position = np.column_stack([np.rad2deg(lla[:, 0]), np.rad2deg(lla[:, 1]), lla[:, 2]])
    return "WGS84", position, cov, gravity


class PosePriorExport:
    """What :func:`write_pose_priors` did.

    Attributes
    ----------
    system : str
        ``WGS84`` or ``CARTESIAN``.
    written, replaced, added : list of str
        EO ids given a prior; those whose earlier prior was replaced; those added to the
        database as new images.
    without_prior : list of str
        Database images that are not in the EO (left as they were).
    """

    def __init__(self, system, written, replaced, added, without_prior):
        self.system, self.written, self.replaced = system, written, replaced
        self.added, self.without_prior = added, without_prior


def _copy_database(src, dst):
    """Copy an SQLite database through its backup API (a WAL journal included)."""
    try:
        with sqlite3.connect(f"file:{os.path.abspath(src)}?mode=ro", uri=True) as a, \
                sqlite3.connect(dst) as b:
            a.backup(b)
        a.close()
        b.close()
    except sqlite3.DatabaseError as exc:
        raise InputError(f"not a COLMAP (SQLite) database: {exc}", path=src) from None


def _name_index(images):
    """EO id -> database image, by name without folders and extension (or with it)."""
    index = {}
    for im in images:
        base = os.path.basename(im.name)
        for key in {base, os.path.splitext(base)[0]}:
            index.setdefault(key, []).append(im)
    return index


def _add_images(pycolmap, db, names, camera):
    """Add images of one new camera (its rig, a frame per image), as COLMAP's feature
    extraction does; return them as read back."""
    from photogrammetry.sfm.colmap import camera_to_colmap
    model, params = camera_to_colmap(camera)
    camera_id = db.write_camera(pycolmap.Camera(model=model, width=camera.width_px,
                                                height=camera.height_px, params=params))
    sensor = pycolmap.sensor_t(type=pycolmap.SensorType.CAMERA, id=camera_id)
    rig = pycolmap.Rig()
    rig.add_ref_sensor(sensor)
    rig_id = db.write_rig(rig)
    out = []
    for name in names:
        image_id = db.write_image(pycolmap.Image(name=name, camera_id=camera_id))
        frame = pycolmap.Frame()
        frame.rig_id = rig_id
        frame.add_data_id(pycolmap.data_t(sensor, image_id))
        db.write_frame(frame)
        out.append(db.read_image(image_id))
    return out


def _fill(pycolmap, db, eo, camera, coordinates, add_missing, suffix, db_path):
    system, position, cov, gravity = pose_priors(eo, coordinates)
    images = db.read_all_images()
    index = _name_index(images)
    twice = [i for i in eo.image_id if len(index.get(i, [])) > 1]
    if twice:
        raise InputError(f"{len(twice)} EO images match two database images each (e.g. "
                         f"{twice[0]!r}: " + ", ".join(im.name for im in index[twice[0]])
                         + ")", path=db_path)
    missing = [i for i in eo.image_id if i not in index]
    if missing and not add_missing:
        raise InputError(f"{len(missing)} of {len(eo)} EO images are not in the database: "
                         + ", ".join(missing[:10]) + (", ..." if len(missing) > 10 else "")
                         + " (database image names without extension must be the EO ids;"
                         " --add-missing adds them)", path=db_path)
    added = []
    if missing:
        if camera is None:
            raise InputError("adding images to the database needs the camera (--camera)")
        new = _add_images(pycolmap, db, [iid + suffix for iid in missing], camera)
        for iid, im in zip(missing, new):
            index[iid] = [im]
            added.append(iid)
    old = {p.corr_data_id.id: p for p in db.read_all_pose_priors()}
    kind = getattr(pycolmap.PosePriorCoordinateSystem, system)
    replaced = []
    for k, iid in enumerate(eo.image_id):
        im = index[iid][0]
        prior = pycolmap.PosePrior(corr_data_id=im.data_id, position=position[k],
                                   position_covariance=cov[k], coordinate_system=kind,
                                   gravity=gravity[k])
        if im.image_id in old:
            prior.pose_prior_id = old[im.image_id].pose_prior_id
            db.update_pose_prior(prior)
            replaced.append(iid)
        else:
            db.write_pose_prior(prior)
    known = set(eo.image_id)
    rest = [im.name for im in images
            if not ({os.path.basename(im.name), os.path.splitext(os.path.basename(im.name))[0]}
                    & known)]
    return PosePriorExport(system, list(eo.image_id), replaced, added, rest)


def write_pose_priors(output, eo, database=None, camera=None, coordinates="auto",
                      add_missing=False, suffix=".jpg"):
    """Write the EO as COLMAP pose priors into a database (module docstring).

    Parameters
    ----------
    output : str
        The database written (atomically: a temporary copy renamed at the end).
    eo : ExposureOrientation
    database : str, optional
        The database to start from (its images, features, matches are kept; its own
        pose priors of the EO's images replaced).  It is not modified unless it is
        `output`.  Without it a new database holds the EO's images (needs `camera`).
    camera : FrameCamera, optional
        The camera of added images.
    coordinates : {"auto", "wgs84", "cartesian"}
    add_missing : bool
        Add EO images missing from `database` (named ``id + suffix``).

    Returns
    -------
    PosePriorExport
    """
    pycolmap = _need_pycolmap()
    output = os.fspath(output)
    if database is not None and not os.path.isfile(database):
        raise InputError("COLMAP database not found", path=os.fspath(database))
    directory = os.path.dirname(os.path.abspath(output))
    if os.path.isdir(output):
        raise InputError("is a directory, not a database file", path=output)
    if not os.path.isdir(directory):
        raise InputError("the output's directory does not exist", path=output)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix="." + os.path.basename(output) + ".",
                               suffix=".part")
    os.close(fd)
    try:
        if database is not None:
            _copy_database(database, tmp)
        else:
            os.remove(tmp)
            add_missing = True
        try:
            db = pycolmap.Database.open(tmp)
        except Exception as exc:
            raise InputError(f"pycolmap cannot open the database: {exc}",
                             path=os.fspath(database or output)) from None
        try:
            res = _fill(pycolmap, db, eo, camera, coordinates, add_missing, suffix,
                        os.fspath(database) if database else output)
        finally:
            db.close()
        os.replace(tmp, output)
    finally:
        for f in (tmp, tmp + "-journal", tmp + "-wal", tmp + "-shm"):
            if os.path.exists(f):
                os.remove(f)
    return res
