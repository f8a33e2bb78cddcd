"""Tie-point files and the overlapping pairs they define.

File (``docs/interfaces.md``): comment lines starting with ``#`` (the simulator states
``sigma_px = ...`` and ``sigma_mm = ...`` there), a header ``image_id,point_id,x_mm,y_mm``
(observed photo coordinates in mm, origin at the principal point, x along the image
rows, y up) or ``image_id,point_id,u_px,v_px`` (pixel column and row; needs the camera),
then one observation per line.  Observed coordinates are distorted; :meth:`TiePoints.pairs`
undistorts them with the camera.
"""
import re
from dataclasses import dataclass

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.fileio import atomic_open

__all__ = ["TiePoints", "read_tiepoints", "write_tiepoints"]

#: The largest photo coordinate read without a camera, mm (an aerial film is 230 mm).
MAX_PHOTO_MM = 1000.0
#: The largest pixel coordinate read, px.
MAX_PIXEL = 1e6

_HEADERS = {("image_id", "point_id", "x_mm", "y_mm"): "mm",
            ("image_id", "point_id", "u_px", "v_px"): "px"}


@dataclass(frozen=True, eq=False)
class TiePoints:
    """Tie-point observations.

    Attributes
    ----------
    path : str
    image_id : tuple of str (k,)
    point_id : tuple of str (k,)
    xy_mm : ndarray (k, 2)
        Observed (distorted) photo coordinates, mm.
    line : ndarray of int (k,)
        1-based line of each observation in the file.
    sigma_mm : float or None
        Photo-coordinate sigma from the header comment, mm.
    """
    path: str
    image_id: tuple
    point_id: tuple
    xy_mm: np.ndarray
    line: np.ndarray
    sigma_mm: float = None

    def __len__(self):
        return len(self.image_id)

    def check_images(self, known_ids, eo_path="the EO file"):
        """Raise InputError (file:line) at the first observation of an unknown image."""
        known = set(known_ids)
        for k, iid in enumerate(self.image_id):
            if iid not in known:
                raise InputError(f"image_id {iid!r} is not in {eo_path}", path=self.path,
                                 line=int(self.line[k]))

    def pairs(self, image_ids, camera=None, min_common=5):
        """Overlapping pairs of images and their common points.

        Parameters
        ----------
        image_ids : sequence of str
            The images of the block, in order (pair indices refer to it).
        camera : photogrammetry.orientation.camera.FrameCamera, optional
            Undistorts the observations (ideal photo coordinates); none: taken as ideal.
        min_common : int
            Pairs with fewer common points are left out.

        Returns
        -------
        pairs : ndarray of int (P, 2), i < j
        points : list of (xy_i, xy_j) ideal photo coordinates (n, 2) mm
        point_ids : list of tuple of str
        """
        self.check_images(image_ids)
        index = {iid: i for i, iid in enumerate(image_ids)}
        xy = self.xy_mm if camera is None else _undistort(camera, self.xy_mm, self.path)
        by_point = {}
        for k, (iid, pid) in enumerate(zip(self.image_id, self.point_id)):
            by_point.setdefault(pid, []).append((index[iid], k))
        pair_obs = {}
        for pid, obs in by_point.items():
            obs.sort()
            for a in range(len(obs)):
                for b in range(a + 1, len(obs)):
                    pair_obs.setdefault((obs[a][0], obs[b][0]), []).append(
                        (obs[a][1], obs[b][1]))
        pairs, points, pids = [], [], []
        for key in sorted(pair_obs):
            ks = np.array(pair_obs[key])
            if len(ks) < min_common:
                continue
            pairs.append(key)
            points.append((xy[ks[:, 0]], xy[ks[:, 1]]))
            pids.append(tuple(self.point_id[k] for k in ks[:, 0]))
        return np.array(pairs, dtype=int).reshape(-1, 2), points, pids


def _undistort(camera, xy, path):
    try:
        return camera.undistort(xy)
    except ValueError as exc:
        raise InputError(f"tie points cannot be undistorted with the camera: {exc}",
                         path=path) from None


def _sigma_from_comments(comments, key, path):
    """The value of ``key = ...`` (sigma_mm or sigma_px) in the leading comment lines
    (``comments[i]`` is line i + 1), or None; a value that is not a number >= 0 is
    refused (0, a noise-free simulation, is kept: the refinement then asks for a sigma)."""
    for k, text in enumerate(comments):
        m = re.search(rf"\b{key}\s*=\s*([^\s,;)]*)", text)
        if m:
            try:
                value = float(m.group(1))
            except ValueError:
                value = None
            if value is None or not (np.isfinite(value) and value >= 0):
                unit = "mm" if key == "sigma_mm" else "px"
                raise InputError(f"{key} = {m.group(1)!r}: expected a number >= 0 ({unit})",
                                 path=path, line=k + 1)
            return value
    return None


def read_tiepoints(path, camera=None):
    """Read a tie-point CSV.

    Parameters
    ----------
    path : str
    camera : photogrammetry.orientation.camera.FrameCamera, optional
        Needed for a file in pixels (``u_px,v_px``), to convert to photo mm (and a
        ``sigma_px`` of the header without ``sigma_mm``).

    Returns
    -------
    TiePoints

    Raises
    ------
    InputError
        Wrong header, a malformed or non-finite line, a repeated (image, point), a pixel
        file without camera, a header ``sigma_mm``/``sigma_px`` that is not a number
        >= 0; the message names the file and line.
    """
    path = str(path)
    text = textfiles.read_text(path, "a tie-point CSV file (image_id,point_id,x_mm,y_mm)"
                             ).splitlines()
    comments, k = [], 0
    while k < len(text) and (text[k].startswith("#") or not text[k].strip()):
        comments.append(text[k])
        k += 1
    if k == len(text):
        raise InputError("no header line (image_id,point_id,x_mm,y_mm)", path=path)
    header = tuple(c.strip() for c in text[k].split(","))
    unit = _HEADERS.get(header)
    if unit is None:
        raise InputError("header must be image_id,point_id,x_mm,y_mm (photo mm) or "
                         f"image_id,point_id,u_px,v_px (pixels), got {text[k]!r}",
                         path=path, line=k + 1)
    if unit == "px" and camera is None:
        raise InputError("tie points in pixels need the camera file (--camera)", path=path)
    if unit == "px":
        bound, what = MAX_PIXEL, f"{MAX_PIXEL:g} px"
    elif camera is not None:
        # a photo coordinate is inside the frame: its radius at most the sensor diagonal
        bound = float(np.hypot(camera.width_px, camera.height_px) * camera.pixel_size_mm)
        what = f"{bound:.4g} mm, the diagonal of the camera's frame"
    else:
        bound, what = MAX_PHOTO_MM, f"{MAX_PHOTO_MM:g} mm"
    ids, pids, rows, lines, seen = [], [], [], [], set()
    for j in range(k + 1, len(text)):
        if not text[j].strip() or text[j].startswith("#"):
            continue
        parts = [c.strip() for c in text[j].split(",")]
        if len(parts) != 4:
            raise InputError(f"expected 4 fields (image_id,point_id,x,y), got {len(parts)}",
                             path=path, line=j + 1)
        try:
            x, y = float(parts[2]), float(parts[3])
        except ValueError:
            raise InputError(f"coordinates must be numbers ({unit}), got {parts[2]!r}, "
                             f"{parts[3]!r}", path=path, line=j + 1) from None
        if not (np.isfinite(x) and np.isfinite(y)):
            raise InputError(f"non-finite coordinate ({unit}): {parts[2]!r}, {parts[3]!r}",
                             path=path, line=j + 1)
        if not (abs(x) <= bound and abs(y) <= bound):
            raise InputError(f"coordinate {x:g}, {y:g} {unit} is beyond {what} (not a "
                             "point of the image)", path=path, line=j + 1)
        if not parts[0] or not parts[1]:
            raise InputError("empty image_id or point_id", path=path, line=j + 1)
        key = (parts[0], parts[1])
        if key in seen:
            raise InputError(f"point {parts[1]!r} observed twice in image {parts[0]!r}",
                             path=path, line=j + 1)
        seen.add(key)
        ids.append(parts[0])
        pids.append(parts[1])
        rows.append((x, y))
        lines.append(j + 1)
    if not rows:
        raise InputError("no tie-point observations", path=path)
    xy = np.array(rows)
    sigma = _sigma_from_comments(comments, "sigma_mm", path)
    sigma_px = _sigma_from_comments(comments, "sigma_px", path)
    if sigma is None and sigma_px is not None and camera is not None:
        sigma = sigma_px * camera.pixel_size_mm
    if unit == "px":
        xy = camera.pixel_to_photo(xy)
    xy.setflags(write=False)
    return TiePoints(path, tuple(ids), tuple(pids), xy, np.array(lines), sigma)


def write_tiepoints(path, image_ids, point_ids, xy_mm, sigma_px=None, pixel_size_mm=None,
                    comments=()):
    """Write a tie-point CSV (``image_id,point_id,x_mm,y_mm``, atomically).

    Parameters
    ----------
    path : str
    image_ids, point_ids : sequence of str (k,)
    xy_mm : array_like (k, 2)
        Observed (distorted) photo coordinates, mm.
    sigma_px : float, optional
        Photo-coordinate sigma stated in the header (``sigma_px = ...``, and
        ``sigma_mm = ...`` with `pixel_size_mm`), which ``refine`` takes as the weight.
    pixel_size_mm : float, optional
    comments : iterable of str
        Further ``# ...`` lines.
    """
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    if not (len(image_ids) == len(point_ids) == len(xy)):
        raise ValueError("image_ids, point_ids and xy_mm must have the same length")
    lines = ["# tie points: observed photo coordinates (mm, origin at the principal point, "
             "x right, y up, distorted as the camera file states)"]
    if sigma_px is not None:
        s = f"# sigma_px = {sigma_px:.4g}"
        if pixel_size_mm is not None:
            s += f" (sigma_mm = {sigma_px * pixel_size_mm:.6g}) per coordinate"
        lines.append(s)
    lines += [f"# {c}" for c in comments]
    lines.append("image_id,point_id,x_mm,y_mm")
    lines += [f"{i},{p},{x:.7f},{y:.7f}" for i, p, (x, y) in zip(image_ids, point_ids, xy)]
    with atomic_open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
