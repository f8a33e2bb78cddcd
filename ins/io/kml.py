"""KML 2.2 (OGC 07-147r2) of a :class:`~ins.io.track.Track` for Google Earth and GIS:
the track as LineString segments coloured by class, and one Point placemark per epoch
with its time stamp, the same colour and the values in ``ExtendedData``.

Classes: by GNSS quality (``color_by="quality"``: fix green, float yellow, SBAS/DGPS
orange, single red, PPP blue, no GNSS near the epoch grey) or by the horizontal sigma
(``"sigma"``: < 5 cm green, < 20 cm yellow, < 1 m orange, else red).  Heights: KML's
``absolute`` altitude is above mean sea level (Google Earth takes EGM96), so an
orthometric height system is what a viewer expects; the document's description names
the system written (ellipsoidal heights put the track tens of metres off).  Time stamps
are UTC (``TimeStamp``/``TimeSpan``), written only when the GPS week is known.
Written in a stream and atomically.
"""
from xml.sax.saxutils import escape

import numpy as np

from ins.common.fileio import atomic_open

__all__ = ["write_kml", "classify", "CLASSES"]

#: Class name -> (KML colour aabbggrr, label), by colouring.
CLASSES = {
    "quality": {1: ("ff00c800", "fix"), 2: ("ff00ffff", "float"), 3: ("ff0080ff", "SBAS"),
                4: ("ff0080ff", "DGPS"), 5: ("ff0000ff", "single"), 6: ("ffff8000", "PPP"),
                0: ("ff808080", "no GNSS")},
    "sigma": {1: ("ff00c800", "sigma_h < 0.05 m"), 2: ("ff00ffff", "sigma_h < 0.2 m"),
              3: ("ff0080ff", "sigma_h < 1 m"), 4: ("ff0000ff", "sigma_h >= 1 m")},
    "none": {0: ("ffff00ff", "track")},
}
_SIGMA_EDGES = (0.05, 0.2, 1.0)


def classify(track, color_by):
    """The class of each epoch (int array) for ``color_by`` (quality, sigma, none)."""
    if color_by == "quality":
        if track.quality is None:
            raise ValueError("color_by='quality' needs the GNSS quality of the epochs")
        return np.asarray(track.quality, np.int64)
    if color_by == "sigma":
        if track.sigma_ned_m is None:
            raise ValueError("color_by='sigma' needs the sigmas of the epochs")
        return 1 + np.searchsorted(np.array(_SIGMA_EDGES), track.sigma_h_m, side="right")
    if color_by == "none":
        return np.zeros(len(track), np.int64)
    raise ValueError(f"color_by must be quality, sigma or none, got {color_by!r}")


def _coord(lon, lat, h):
    return f"{lon:.9f},{lat:.9f},{h:.4f}"


def write_kml(path, track, color_by="quality", points=True, name=None):
    """Write ``track`` as KML (module notes); returns the number of point placemarks."""
    cls = classify(track, color_by)
    styles = CLASSES[color_by]
    lon, lat, alt = track.lon_deg, track.lat_deg, track.height_m
    utc = track.utc_iso()
    sig = track.sigma_h_m
    qn = track.quality_names()
    title = escape(name or track.source or "trajectory")
    desc = (f"source: {track.source}; heights: {track.height.description()}; colour: "
            f"{color_by}; {len(track)} epochs")
    out = []
    w = out.append
    with atomic_open(path, "w") as f:
        def flush():
            f.write("".join(out))
            out.clear()
        w('<?xml version="1.0" encoding="UTF-8"?>\n'
          '<kml xmlns="http://www.opengis.net/kml/2.2">\n<Document>\n'
          f"<name>{title}</name>\n<description>{escape(desc)}</description>\n")
        for k, (colour, label) in styles.items():
            # the order of the KML 2.2 schema: IconStyle, LabelStyle, LineStyle
            w(f'<Style id="c{k}"><IconStyle><color>{colour}</color><scale>0.5</scale><Icon>'
              '<href>http://maps.google.com/mapfiles/kml/shapes/shaded_dot.png</href></Icon>'
              '</IconStyle><LabelStyle><scale>0</scale></LabelStyle><LineStyle><color>'
              f'{colour}</color><width>3</width></LineStyle></Style>\n')
        w("<Folder><name>track</name>\n")
        # one LineString per run of epochs of one class, sharing the boundary epochs
        n = len(track)
        start = 0
        while start < n:
            end = start
            while end + 1 < n and cls[end + 1] == cls[start]:
                end += 1
            stop = min(end + 1, n - 1)            # join to the next segment's first epoch
            k = int(cls[start])
            # the schema's order: name, time primitive, styleUrl, ..., geometry
            w(f"<Placemark><name>{escape(styles[k][1])}</name>")
            if utc is not None:
                w(f"<TimeSpan><begin>{utc[start]}</begin><end>{utc[stop]}</end></TimeSpan>")
            w(f"<styleUrl>#c{k}</styleUrl>")
            w("<LineString><altitudeMode>absolute</altitudeMode><coordinates>"
              + " ".join(_coord(lon[i], lat[i], alt[i]) for i in range(start, stop + 1))
              + "</coordinates></LineString></Placemark>\n")
            start = end + 1
            if len(out) > 256:
                flush()
        w("</Folder>\n")
        count = 0
        if points:
            w("<Folder><name>epochs</name>\n")
            hname = escape(track.height.column())
            for i in range(n):
                k = int(cls[i])
                w("<Placemark>")
                if utc is not None:
                    w(f"<TimeStamp><when>{utc[i]}</when></TimeStamp>")
                w(f"<styleUrl>#c{k}</styleUrl>")
                data = [("gps_time_s", f"{track.time[i]:.4f}"),
                        (hname, f"{alt[i]:.4f}")]
                if sig is not None:
                    data.append(("sigma_h_m", f"{sig[i]:.4f}"))
                    data.append(("sigma_v_m", f"{track.sigma_v_m[i]:.4f}"))
                if qn is not None:
                    data.append(("gnss_quality", qn[i]))
                w("<ExtendedData>" + "".join(f'<Data name="{a}"><value>{b}</value></Data>'
                                             for a, b in data) + "</ExtendedData>")
                w("<Point><altitudeMode>absolute</altitudeMode><coordinates>"
                  f"{_coord(lon[i], lat[i], alt[i])}</coordinates></Point></Placemark>\n")
                count += 1
                if len(out) > 4096:
                    flush()
            w("</Folder>\n")
        w("</Document>\n</kml>\n")
        flush()
    return count
