"""Mapping frames ``m`` of the exterior orientation: ENU tangent plane or map projection.

- :class:`EnuFrame` (default): local east-north-up Cartesian frame at a block origin
  (lat0, lon0, h0).  Positions by ``pymap3d.geodetic2enu``; ``C_mn`` exact
  (:func:`photogrammetry.orientation.rotation.dcm_mn_enu`), so the frame is rigid and the
  photogrammetric collinearity holds in it without corrections.
- :class:`ProjectedFrame`: ``X = easting``, ``Y = northing`` (m) of a projected CRS
  (UTM or any EPSG code, through pyproj), ``Z`` the ellipsoidal height or the
  orthometric height ``H = h - N``: N from a geoid model (EGM2008, EGM96:
  :mod:`ins.io.geoid`, a grid installed locally, never downloaded) at each perspective
  centre, or one stated constant undulation for the block.  The
  camera attitude is referred to the grid axes: ``C_mn = Rz(gamma) @ P`` with ``gamma``
  the meridian convergence at the camera (pyproj ``Proj.get_factors``; positive east
  of the central meridian in the northern hemisphere, where true north points
  ``gamma`` west of grid north) and ``P`` the NED->ENU swap.  Ignoring it 3 deg off the
  central meridian at 45 deg latitude turns kappa by ~7600 arcsec.  A projection is
  not a Cartesian frame (scale factor, Earth curvature): use ENU for adjustments.

No geoid model is downloaded: orthometric heights need an installed geoid grid
(``pip install 'insphoto[geoid]'``) or the undulation of the block.
"""
import numpy as np
import pymap3d
import pyproj

from ins.common.errors import InputError
from ins.nav.rotation import rot_z
from photogrammetry.orientation.rotation import P_NED_ENU, dcm_mn_enu

__all__ = ["EnuFrame", "ProjectedFrame", "parse_frame", "utm_epsg"]


def _lla(lla):
    lla = np.asarray(lla, dtype=float)
    if lla.ndim != 2 or lla.shape[1] != 3:
        raise ValueError(f"lla must have shape (n, 3) (lat rad, lon rad, h m), got {lla.shape}")
    return lla


class EnuFrame:
    """Local ENU tangent plane at a block origin.

    Parameters
    ----------
    origin_lat, origin_lon : float
        Origin, rad.
    origin_h : float
        Origin ellipsoidal height, m.
    """

    kind = "enu"

    def __init__(self, origin_lat, origin_lon, origin_h=0.0):
        self.origin = (float(origin_lat), float(origin_lon), float(origin_h))
        if not np.all(np.isfinite(self.origin)) or abs(self.origin[0]) > np.pi / 2:
            lat, lon = (float(np.rad2deg(v)) for v in self.origin[:2])
            raise InputError(f"mapping-frame origin lat {lat:g} deg, lon {lon:g} deg, h "
                             f"{self.origin[2]:g} m is not a valid geodetic position "
                             "(|lat| <= 90 deg, finite)")

    @classmethod
    def from_degrees(cls, lat_deg, lon_deg, h_m=0.0):
        return cls(np.deg2rad(lat_deg), np.deg2rad(lon_deg), h_m)

    def position(self, lla):
        """Geodetic positions (n, 3) (rad, rad, m) to ENU coordinates (n, 3), m."""
        lla = _lla(lla)
        lat0, lon0, h0 = self.origin
        return np.column_stack(pymap3d.geodetic2enu(lla[:, 0], lla[:, 1], lla[:, 2],
                                                    lat0, lon0, h0, deg=False))

    def to_lla(self, xyz):
        """ENU coordinates (n, 3), m, to geodetic (n, 3) (rad, rad, m)."""
        xyz = np.asarray(xyz, dtype=float)
        lat0, lon0, h0 = self.origin
        return np.column_stack(pymap3d.enu2geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2],
                                                    lat0, lon0, h0, deg=False))

    def C_mn(self, lla):
        """NED at each position to the ENU axes at the origin, (n, 3, 3)."""
        lla = _lla(lla)
        return dcm_mn_enu(lla[:, 0], lla[:, 1], self.origin[0], self.origin[1])

    def header(self):
        """The ``# frame = ...`` value of the EO CSV header."""
        lat, lon = np.rad2deg(self.origin[:2])
        return (f"enu; origin_lat_deg = {lat:.12f}; origin_lon_deg = {lon:.12f}; "
                f"origin_h_m = {self.origin[2]:.6f}")

    def __repr__(self):
        return f"EnuFrame({self.header()})"


def utm_epsg(lat, lon):
    """EPSG code of the WGS84 UTM zone holding (lat, lon) in rad (326zz north, 327zz south)."""
    zone = int(np.floor((np.rad2deg(lon) + 180.0) / 6.0)) % 60 + 1
    return (32600 if lat >= 0 else 32700) + zone


class ProjectedFrame:
    """Map projection (any projected CRS pyproj knows) plus a height.

    Parameters
    ----------
    crs : str or int
        ``"EPSG:32650"``, ``32650`` or any string ``pyproj.CRS`` accepts.
    geoid_undulation_m : float, optional
        Constant geoid undulation N of the block, m: heights become orthometric
        ``H = h - N``.  Default: ellipsoidal heights.
    height : ins.io.geoid.HeightSystem, optional
        Orthometric heights of a geoid model, N at each position (not with
        ``geoid_undulation_m``).
    """

    kind = "projected"

    def __init__(self, crs, geoid_undulation_m=None, height=None):
        try:
            self.crs = pyproj.CRS.from_user_input(crs)
        except pyproj.exceptions.CRSError as exc:
            raise InputError(f"unknown coordinate reference system {crs!r}: {exc}") from None
        if not self.crs.is_projected:
            raise InputError(f"{crs!r} is not a projected CRS (easting/northing); "
                             "use 'enu' for a local Cartesian frame")
        self.name = crs if isinstance(crs, str) else f"EPSG:{crs}"
        epsg = self.crs.to_epsg()
        if epsg is not None:
            self.name = f"EPSG:{epsg}"
        self._to_map = pyproj.Transformer.from_crs("EPSG:4326", self.crs, always_xy=True)
        self._to_geo = pyproj.Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True)
        self._proj = pyproj.Proj(self.crs)
        self.geoid_undulation_m = None if geoid_undulation_m is None else float(
            geoid_undulation_m)
        if height is not None and not height.orthometric:
            height = None
        if height is not None and geoid_undulation_m is not None:
            raise InputError("give a geoid model or a constant geoid undulation, not both")
        self.height = height

    def _h_offset(self, lat, lon):
        """N (m) at lat, lon (rad): the model's, the constant, or 0 (ellipsoidal)."""
        if self.height is not None:
            return self.height.undulation(lat, lon)
        return 0.0 if self.geoid_undulation_m is None else self.geoid_undulation_m

    def position(self, lla):
        """Geodetic positions (n, 3) to (easting, northing, height) (n, 3), m."""
        lla = _lla(lla)
        e, n = self._to_map.transform(np.rad2deg(lla[:, 1]), np.rad2deg(lla[:, 0]))
        return np.column_stack([e, n, lla[:, 2] - self._h_offset(lla[:, 0], lla[:, 1])])

    def to_lla(self, xyz):
        """(easting, northing, height) (n, 3) to geodetic (n, 3) (rad, rad, m ellipsoidal)."""
        xyz = np.asarray(xyz, dtype=float)
        lon, lat = self._to_geo.transform(xyz[:, 0], xyz[:, 1])
        lat, lon = np.deg2rad(lat), np.deg2rad(lon)
        return np.column_stack([lat, lon, xyz[:, 2] + self._h_offset(lat, lon)])

    def convergence(self, lla):
        """Meridian convergence gamma (rad) at each position: the grid azimuth of true
        north is ``-gamma``."""
        lla = _lla(lla)
        f = self._proj.get_factors(np.rad2deg(lla[:, 1]), np.rad2deg(lla[:, 0]))
        return np.deg2rad(np.asarray(f.meridian_convergence, dtype=float))

    def C_mn(self, lla):
        """NED to grid east, grid north, up: ``Rz(gamma) @ P``, (n, 3, 3)."""
        return rot_z(self.convergence(lla)) @ P_NED_ENU

    def header(self):
        if self.height is not None:
            g = self.height.geoid
            heights = (f"orthometric (geoid {g.name}, EPSG:{g.vertical_epsg}, H = h - N; N "
                       f"from {g.source})")
        elif self.geoid_undulation_m is None:
            heights = "ellipsoidal"
        else:
            heights = f"orthometric (constant geoid undulation N = {self.geoid_undulation_m!r} m)"
        return f"{self.name}; heights = {heights}"

    def __repr__(self):
        return f"ProjectedFrame({self.header()})"


def parse_frame(text, origin_lla=None, geoid_undulation_m=None, height=None):
    """Mapping frame from a command-line or header value.

    Parameters
    ----------
    text : str
        ``"enu"``, ``"utm"`` (zone of the origin) or ``"EPSG:xxxx"``.
    origin_lla : array_like, shape (3,), optional
        Block origin (rad, rad, m) for ``enu`` and ``utm``.
    geoid_undulation_m : float, optional
        For projected frames: orthometric heights with this constant undulation.
    height : ins.io.geoid.HeightSystem, optional
        For projected frames: orthometric heights of this geoid model.
    """
    ortho = height is not None and height.orthometric
    t = str(text).strip()
    if t.lower() == "enu":
        if origin_lla is None:
            raise InputError("the enu mapping frame needs an origin (lat, lon, h)")
        if geoid_undulation_m is not None or ortho:
            raise InputError("a geoid undulation applies to projected frames only "
                             "(ENU heights are along the origin's normal)")
        return EnuFrame(*origin_lla)
    if t.lower() == "utm":
        if origin_lla is None:
            raise InputError("the utm mapping frame needs a position to choose the zone")
        return ProjectedFrame(f"EPSG:{utm_epsg(origin_lla[0], origin_lla[1])}",
                              geoid_undulation_m, height)
    if t.upper().startswith("EPSG:"):
        return ProjectedFrame(t.upper(), geoid_undulation_m, height)
    raise InputError(f"unknown mapping frame {text!r}; expected enu, utm or EPSG:<code>")
