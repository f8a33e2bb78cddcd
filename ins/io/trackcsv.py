"""CSV of a :class:`~ins.io.track.Track` in a chosen coordinate reference system.

Header comment lines (``#``) name the source, the CRS (its EPSG code and name) and the
height system with its geoid model; then one line of column names and one line an epoch,
comma separated.  Columns, each named with its unit:

- ``gps_week`` (when known), ``gps_time_s`` (seconds of that week), ``utc`` (ISO 8601,
  when the week is known);
- the horizontal coordinates in the CRS's axis order: a geographic CRS gives
  ``lat_deg``, ``lon_deg`` (9 decimals); a projected CRS ``easting_m``, ``northing_m``
  (or ``x_m``/``y_m`` for axes that are neither; 4 decimals), through pyproj from WGS84
  (EPSG:4326; a CRS on another datum goes through the transformation pyproj chooses);
- the height: ``h_ellipsoidal_m`` or ``H_egm2008_m`` / ``H_egm96_m`` (orthometric,
  H = h - N), with ``geoid_undulation_m``;
- ``sigma_n_m``, ``sigma_e_m``, ``sigma_d_m``, ``sigma_h_m``; ``gnss_quality`` (RTKLIB Q,
  0 none) and ``gnss_quality_name``; ``roll_deg``, ``pitch_deg``, ``yaw_deg``,
  ``speed_mps``: when the run gives them.

Written atomically.
"""
import numpy as np

from ins.common.errors import InputError
from ins.common.fileio import atomic_open

__all__ = ["write_track_csv", "crs_columns", "parse_crs"]


def parse_crs(text, option="--crs"):
    """A horizontal ``pyproj.CRS`` (geographic 2-D or projected) from ``text``;
    an :class:`InputError` naming ``option`` for anything else (a compound or vertical
    CRS: the heights are chosen by ``--height``)."""
    import pyproj
    try:
        crs = pyproj.CRS.from_user_input(text)
    except pyproj.exceptions.CRSError as exc:
        raise InputError(f"{option} {text!r}: not a CRS pyproj knows ({exc})") from None
    if crs.is_compound or crs.is_vertical:
        raise InputError(f"{option} {text!r}: give a horizontal CRS (geographic or "
                         "projected); the heights are chosen by --height")
    if crs.is_geographic and len(crs.axis_info) != 2:
        crs2 = crs.to_2d()
        crs = crs2 if len(crs2.axis_info) == 2 else crs
    if not (crs.is_projected or crs.is_geographic):
        raise InputError(f"{option} {text!r}: expected a geographic or projected CRS, got "
                         f"{crs.type_name}")
    return crs


def crs_columns(crs):
    """Names of the two horizontal columns of ``crs``, in its axis order."""
    names = []
    for ax in crs.axis_info[:2]:
        d = ax.direction.lower()
        if crs.is_geographic:
            names.append("lat_deg" if d in ("north", "south") else "lon_deg")
        elif d in ("east", "west"):
            names.append("easting_m")
        elif d in ("north", "south"):
            names.append("northing_m")
        else:
            names.append(f"{ax.abbrev.lower() or 'x'}_m")
    if len(set(names)) != 2:
        names = ["x_m", "y_m"] if crs.is_projected else ["lat_deg", "lon_deg"]
    return names


def write_track_csv(path, track, crs):
    """Write ``track`` as CSV in ``crs`` (a ``pyproj.CRS``, see :func:`parse_crs`);
    returns the number of epochs written."""
    import pyproj
    to = pyproj.Transformer.from_crs("EPSG:4326", crs)      # the CRS's own axis order
    a, b = to.transform(track.lat_deg, track.lon_deg, errcheck=True)
    a, b = np.asarray(a, float), np.asarray(b, float)
    xy_names = crs_columns(crs)
    dec_xy = 9 if crs.is_geographic else 4
    cols, fmts = [], []

    def add(name, values, fmt):
        cols.append((name, values))
        fmts.append(fmt)

    if track.week is not None:
        add("gps_week", (track.week + track.time // 604800).astype(np.int64), "{:d}")
        add("gps_time_s", np.mod(track.time, 604800.0), "{:.4f}")
        add("utc", track.utc_iso(), "{}")
    else:
        add("gps_time_s", track.time, "{:.4f}")
    add(xy_names[0], a, f"{{:.{dec_xy}f}}")
    add(xy_names[1], b, f"{{:.{dec_xy}f}}")
    add(track.height.column(), track.height_m, "{:.4f}")
    if track.height.orthometric:
        add("geoid_undulation_m", track.lla[:, 2] - track.height_m, "{:.4f}")
    if track.sigma_ned_m is not None:
        for j, ax in enumerate("ned"):
            add(f"sigma_{ax}_m", track.sigma_ned_m[:, j], "{:.4f}")
        add("sigma_h_m", track.sigma_h_m, "{:.4f}")
    if track.quality is not None:
        add("gnss_quality", np.asarray(track.quality, np.int64), "{:d}")
        add("gnss_quality_name", track.quality_names(), "{}")
    if track.rpy_deg is not None:
        for j, ax in enumerate(("roll", "pitch", "yaw")):
            add(f"{ax}_deg", track.rpy_deg[:, j], "{:.6f}")
    if track.speed_mps is not None:
        add("speed_mps", track.speed_mps, "{:.4f}")
    epsg = crs.to_epsg()
    head = [f"# source = {track.source}",
            f"# crs = {'EPSG:%d' % epsg if epsg else crs.to_string()} ({crs.name}); "
            f"columns {xy_names[0]}, {xy_names[1]} in its axis order",
            f"# heights = {track.height.description()}",
            "# time = GPS" + ("" if track.week is not None else
                              " seconds (week unknown: no UTC)"),
            ",".join(name for name, _ in cols)]
    line = ",".join(fmts)
    values = [v for _, v in cols]
    with atomic_open(path, "w") as f:
        f.write("\n".join(head) + "\n")
        chunk = []
        for i in range(len(track)):
            chunk.append(line.format(*(v[i] for v in values)))
            if len(chunk) >= 8192:
                f.write("\n".join(chunk) + "\n")
                chunk = []
        if chunk:
            f.write("\n".join(chunk) + "\n")
    return len(track)
