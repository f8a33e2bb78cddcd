"""GeoJSON (RFC 7946) of a :class:`~ins.io.track.Track`: one FeatureCollection holding a
LineString feature (the whole track) and one Point feature per epoch.

RFC 7946 fixes the coordinates: WGS84 longitude, latitude (deg) and, as the third
element, the height above the WGS84 ellipsoid (m); it has no ``crs`` member.  So the
coordinates always carry the ellipsoidal height, whatever the height system asked for;
orthometric heights go into the properties (``H_egm2008_m``), with the model named in
the collection's and the line's properties (``height_system``).

Point properties: ``gps_week`` (when known), ``gps_time_s`` (seconds of that week),
``utc`` (ISO 8601, when the week is known), ``h_ellipsoidal_m``, the orthometric height
and the undulation ``geoid_undulation_m`` when asked for, ``sigma_n_m``, ``sigma_e_m``,
``sigma_d_m``, ``sigma_h_m`` (sqrt(sN^2 + sE^2)), ``gnss_quality`` (RTKLIB Q, 0: none
near) and ``gnss_quality_name``, ``roll_deg``, ``pitch_deg``, ``yaw_deg``, ``speed_mps``;
a property the run does not give is left out.  Coordinates with 9 decimals of a degree
(0.1 mm) and 4 of a metre.  Written in a stream (bounded memory) and atomically.
"""
import json

import numpy as np

from ins.common.fileio import atomic_open

__all__ = ["write_geojson", "point_properties"]


def _num(v, nd):
    """A finite float rounded to ``nd`` decimals, None (JSON null) otherwise."""
    v = float(v)
    return round(v, nd) if np.isfinite(v) else None


def point_properties(track):
    """The properties of each epoch's Point feature (a list of dicts)."""
    n = len(track)
    cols = {}
    if track.week is not None:
        cols["gps_week"] = [int(track.week + t // 604800) for t in track.time]
        cols["gps_time_s"] = [_num(t % 604800, 4) for t in track.time]
        cols["utc"] = track.utc_iso()
    else:
        cols["gps_time_s"] = [_num(t, 4) for t in track.time]
    cols["h_ellipsoidal_m"] = [_num(h, 4) for h in track.lla[:, 2]]
    if track.height.orthometric:
        cols[track.height.column()] = [_num(h, 4) for h in track.height_m]
        cols["geoid_undulation_m"] = [_num(a - b, 4) for a, b in
                                      zip(track.lla[:, 2], track.height_m)]
    if track.sigma_ned_m is not None:
        for j, a in enumerate("ned"):
            cols[f"sigma_{a}_m"] = [_num(v, 4) for v in track.sigma_ned_m[:, j]]
        cols["sigma_h_m"] = [_num(v, 4) for v in track.sigma_h_m]
    if track.quality is not None:
        cols["gnss_quality"] = [int(q) for q in track.quality]
        cols["gnss_quality_name"] = track.quality_names()
    if track.rpy_deg is not None:
        for j, a in enumerate(("roll", "pitch", "yaw")):
            cols[f"{a}_deg"] = [_num(v, 6) for v in track.rpy_deg[:, j]]
    if track.speed_mps is not None:
        cols["speed_mps"] = [_num(v, 4) for v in track.speed_mps]
    names = list(cols)
    return [{k: cols[k][i] for k in names} for i in range(n)]


def _coords(track):
    lon, lat, h = track.lon_deg, track.lat_deg, track.lla[:, 2]
    return [[round(float(a), 9), round(float(b), 9), round(float(c), 4)]
            for a, b, c in zip(lon, lat, h)]


def write_geojson(path, track, points=True):
    """Write ``track`` as a GeoJSON FeatureCollection (module notes); returns the number
    of Point features written."""
    coords = _coords(track)
    meta = {"source": track.source, "height_system": track.height.name,
            "heights": track.height.description(),
            "coordinates": "WGS84 lon, lat (deg), height above the WGS84 ellipsoid (m), "
                           "RFC 7946", "epochs": len(track)}
    if track.week is not None and len(track):
        utc = track.utc_iso()
        meta.update(start_utc=utc[0], end_utc=utc[-1])
    if len(track):
        meta.update(start_gps_time_s=float(track.time[0]), end_gps_time_s=float(track.time[-1]))
    line = {"type": "Feature", "properties": {"kind": "track", **meta},
            "geometry": {"type": "LineString", "coordinates": coords}}
    props = point_properties(track) if points else []
    with atomic_open(path, "w") as f:
        f.write('{"type": "FeatureCollection", "name": ' + json.dumps(track.source or "track")
                + ', "features": [\n')
        f.write(json.dumps(line, allow_nan=False))
        for c, p in zip(coords, props):
            f.write(",\n")
            f.write(json.dumps({"type": "Feature", "properties": {"kind": "epoch", **p},
                                "geometry": {"type": "Point", "coordinates": c}},
                               allow_nan=False))
        f.write("\n]}\n")
    return len(props)
