"""A trajectory prepared for export to GIS tools (:mod:`ins.io.geojson`, :mod:`ins.io.kml`,
:mod:`ins.io.trackcsv`): the epochs kept, their times in GPS and UTC, heights in a named
height system, sigmas and the GNSS solution quality, and the decimation of long tracks.

Times: ``time`` is GPS seconds of ``week`` (values past 604800 s run into the next weeks,
as ``ins process`` writes them); UTC = GPS - (GPS - UTC leap seconds of the date,
:data:`ins.io.rtklib.LEAP_SECONDS`).  Without a week (the ``.nav`` week column 0) no UTC
time can be given and none is written.
"""
from dataclasses import dataclass, field

import numpy as np

from ins.io.geoid import ELLIPSOIDAL, HeightSystem
from ins.io.gnss_quality import QUALITY_NAME

__all__ = ["Track", "decimate_indices", "gps_to_utc_iso", "quality_at"]

_WEEK_S = 604800
_GPS_EPOCH_UNIX = 315964800          # 1980-01-06T00:00:00Z in Unix seconds


@dataclass
class Track:
    """Epochs of a trajectory for export.

    Attributes
    ----------
    time : ndarray (n,)
        GPS seconds of ``week`` (s).
    lla : ndarray (n, 3)
        Latitude, longitude (rad), ellipsoidal height (m, WGS84).
    week : int or None
        GPS week of ``time``; None: unknown (no UTC times).
    rpy_deg : ndarray (n, 3) or None
        Roll, pitch, yaw (deg, yaw in [0, 360)).
    speed_mps : ndarray (n,) or None
        Horizontal speed, m/s.
    sigma_ned_m : ndarray (n, 3) or None
        Position standard deviations north, east, down (m).
    quality : ndarray (n,) of int or None
        GNSS solution quality at the epoch (RTKLIB Q 1..6), 0 where no GNSS solution lies
        within the tolerance of :func:`quality_at`; None: the run gives none.
    height : HeightSystem
        The system of :attr:`height_m`.
    source : str
        What the track came from (file names), for the metadata.
    """

    time: np.ndarray
    lla: np.ndarray
    week: int = None
    rpy_deg: np.ndarray = None
    speed_mps: np.ndarray = None
    sigma_ned_m: np.ndarray = None
    quality: np.ndarray = None
    height: HeightSystem = ELLIPSOIDAL
    source: str = ""
    _height_m: np.ndarray = field(default=None, repr=False)

    def __len__(self):
        return len(self.time)

    @property
    def lat_deg(self):
        return np.rad2deg(self.lla[:, 0])

    @property
    def lon_deg(self):
        return (np.rad2deg(self.lla[:, 1]) + 180.0) % 360.0 - 180.0

    @property
    def height_m(self):
        """Heights in :attr:`height` (m): ellipsoidal, or orthometric H = h - N."""
        if self._height_m is None:
            self._height_m = self.height.from_ellipsoidal(self.lla[:, 0], self.lla[:, 1],
                                                          self.lla[:, 2])
        return self._height_m

    @property
    def sigma_h_m(self):
        """Horizontal sigma sqrt(sN^2 + sE^2), m (None without sigmas)."""
        if self.sigma_ned_m is None:
            return None
        return np.hypot(self.sigma_ned_m[:, 0], self.sigma_ned_m[:, 1])

    @property
    def sigma_v_m(self):
        return None if self.sigma_ned_m is None else self.sigma_ned_m[:, 2]

    def utc_iso(self):
        """ISO 8601 UTC times (``2024-05-01T10:00:00.000Z``), or None without a week."""
        if self.week is None:
            return None
        return gps_to_utc_iso(self.week, self.time)

    def quality_names(self):
        """Names of :attr:`quality` (``fix``, ``float``, ..., ``none``), or None."""
        if self.quality is None:
            return None
        return [QUALITY_NAME.get(int(q), "none") for q in self.quality]

    def take(self, index):
        """The track at the epochs ``index`` (heights kept)."""
        index = np.asarray(index)
        sub = lambda a: None if a is None else a[index]  # noqa: E731
        out = Track(self.time[index], self.lla[index], self.week, sub(self.rpy_deg),
                    sub(self.speed_mps), sub(self.sigma_ned_m), sub(self.quality),
                    self.height, self.source)
        out._height_m = sub(self._height_m)
        return out


def gps_to_utc_iso(week, tow):
    """ISO 8601 UTC strings (millisecond resolution, ``Z``) of GPS ``week`` and seconds
    ``tow`` (array): the leap seconds of :data:`ins.io.rtklib.LEAP_SECONDS`."""
    from ins.io.rtklib import gps_to_utc_seconds
    tow = np.asarray(tow, dtype=float)
    ms = np.rint(tow * 1000.0).astype(np.int64)          # milliseconds of the week
    gps_ms = int(week) * _WEEK_S * 1000 + ms
    whole = np.floor_divide(gps_ms, 1000)
    utc = gps_to_utc_seconds(whole)                        # integer s since the GPS epoch
    unix_ms = (utc + _GPS_EPOCH_UNIX) * 1000 + (gps_ms - whole * 1000)
    text = np.datetime_as_string(unix_ms.astype("datetime64[ms]"), unit="ms")
    return [t + "Z" for t in text]


def quality_at(time, gnss_time, gnss_quality, tolerance_s=None):
    """The GNSS quality of the solution nearest each epoch of ``time`` (s), 0 where the
    nearest is farther than ``tolerance_s`` (default: half the median GNSS interval,
    at least 0.05 s): an epoch the INS bridged alone."""
    time = np.asarray(time, dtype=float)
    gt = np.asarray(gnss_time, dtype=float)
    gq = np.asarray(gnss_quality, dtype=np.int64)
    if gt.size == 0:
        return np.zeros(time.shape, np.int64)
    order = np.argsort(gt, kind="stable")
    gt, gq = gt[order], gq[order]
    if tolerance_s is None:
        tolerance_s = max(0.5 * float(np.median(np.diff(gt))) if gt.size > 1 else 0.5, 0.05)
    k = np.clip(np.searchsorted(gt, time), 1, max(gt.size - 1, 1))
    if gt.size == 1:
        k = np.zeros(time.shape, np.int64)
    else:
        k = np.where(np.abs(time - gt[k - 1]) <= np.abs(gt[k] - time), k - 1, k)
    q = gq[k]
    return np.where(np.abs(gt[k] - time) <= tolerance_s, q, 0)


def decimate_indices(track, every=None, min_spacing_m=None):
    """Indices of the epochs kept: every ``every``-th epoch, or epochs at least
    ``min_spacing_m`` apart along the track (3-D path length over all epochs, so a track
    at rest keeps one point), the first and the last epoch always kept."""
    n = len(track)
    if n == 0:
        return np.zeros(0, np.int64)
    if every is not None and min_spacing_m is not None:
        raise ValueError("give every or min_spacing_m, not both")
    if every is not None:
        if int(every) < 1:
            raise ValueError(f"every must be >= 1, got {every!r}")
        idx = np.arange(0, n, int(every))
    elif min_spacing_m is not None:
        if not (np.isfinite(min_spacing_m) and min_spacing_m > 0):
            raise ValueError(f"min_spacing_m must be > 0, got {min_spacing_m!r}")
        from ins.nav.earth import lla_to_ecef
        xyz = lla_to_ecef(track.lla[:, 0], track.lla[:, 1], track.lla[:, 2])
        step = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(step)])
        kept = [0]
        while True:
            j = int(np.searchsorted(cum, cum[kept[-1]] + min_spacing_m, side="left"))
            if j >= n:
                break
            kept.append(j)
        idx = np.array(kept, np.int64)
    else:
        idx = np.arange(n)
    if idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    return idx
