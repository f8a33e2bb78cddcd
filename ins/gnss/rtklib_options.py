"""The settings of RTKLIB's positioning engine, read from the ``[rtklib]`` table of a TOML
file with strict keys, and put into a COPY of RTKLIB's own defaults.

``[rtklib]`` (every key optional; the default is RTKLIB demo5's own unless stated)::

    mode               = "single"|"dgnss"|"kinematic"|"static"|"ppp-kinematic"|
                         "ppp-static"    ("kinematic"; where no base is given and the
                         table names no mode, "single": :func:`mode_without_base`; the
                         two PPP modes need no base but precise orbits and clocks)
    direction          = "forward"|"backward"|"combined"          ("combined"; RTKLIB's
                         default is "forward": the combined forward-backward smoother is
                         what post-processing is for)
    elevation_mask_deg = 15                                       (deg, 0 .. 90)
    frequencies        = 2                                        (1: L1, 2: L1+L2, 3: +L5)
    systems            = ["gps", "glonass", "galileo"]            (also "qzss", "beidou",
                         "sbas", "navic")
    dynamics           = false       (receiver velocity/acceleration states in kinematic
                         mode; RTKLIB demo5's default is true, but its 2.5.0 then writes
                         sigma columns that are no covariance: on the GEONET pair 114 of
                         120 records, which ``ins.io.pos_screen`` has to repair, and 44
                         instead of 115 epochs fixed.  Set true for a vehicle whose
                         motion the velocity states help to follow)
    ambiguity          = "fix-and-hold"|"continuous"|"instantaneous"|"off"
                         ("off" in the PPP modes: RTKLIB 2.5.0's PPP ambiguity
                         resolution needs satellite phase biases that final SP3/CLK
                         products do not carry)
    ar_ratio           = 3.0         (ratio test threshold of the integer fix, >= 1)
    ionosphere         = "broadcast"|"iono-free"|"off"   ("iono-free" in the PPP modes:
                         the dual-frequency combination, needs frequencies >= 2)
    troposphere        = "saastamoinen"|"estimate"|"off"   ("estimate" in the PPP
                         modes: the zenith delay as a random walk)
    base_position      = "rinex"|"single"   ("rinex": the base file's APPROX POSITION
                         header; "single": the mean of the base's single-point solutions)
    base_lla_deg       = [lat_deg, lon_deg, h_m]   (the base antenna, WGS84 ellipsoidal;
                         instead of base_position)
    rover_format       = "rtcm3"|"oem4"|"ubx"|"sbf"|...|"rinex"   (the receiver format of
    base_format          the rover's / base's observations; default: detected from the
                         content, :mod:`ins.gnss.receiver_formats`)

The precise ephemeris (SP3/CLK) is used when such files are given (RTKLIB's
``pos1-sateph = precise``); the broadcast navigation file is still needed for the
ionosphere model and the satellites' health, and RTKLIB drops every satellite without a
broadcast ephemeris even with precise products (its ``satposs`` takes the signal's
transmission time from the broadcast clock): a system without a broadcast file is
not used.

A single-point solution (``mode = "single"``) carries RTKLIB's Doppler velocity of each
epoch (``pntpos``'s least squares over the Doppler shifts: ``vn ve vu`` and their sigmas
in the ``.pos``): a receiver of metre noise (a phone) has no other velocity worth the
name, its positions differenced over 1 s scatter by metres per second, so that its
start at rest went unseen and a start while moving was levelled 9 deg off by the
acceleration of those differences (the simulated phone walk of
:mod:`ins.simulate.gnsslogger_writer`).  The other modes write no velocity (without
``dynamics`` their filter has no velocity state to write).

The PPP modes (RTKLIB's ``ppp-kine`` / ``ppp-static``) also switch on solid Earth
tides, the carrier phase wind-up and the exclusion of satellites in eclipse; with an
ANTEX file (``--atx``) the satellites' and the receiver's antenna phase centres (the
receiver antenna type from the RINEX header).  The pre-fit phase innovation threshold
is raised from RTKLIB's 5 m to 30 m (:data:`PPP_MAX_INNOVATION_M`): the receiver clock of
each epoch starts from the single-point solution, some metres off the iono-free one,
and at 5 m every phase measurement was rejected (4 of 241 epochs solved on the SLAC
station).

:func:`fill_prcopt` starts from ``resetsysopts``/``getsysopts`` (RTKLIB's own copy of
``prcopt_default`` into a new struct): ``pyrtklib5.prcopt_default`` is a shared object
of the binding and is never written to.
"""
import math
import os
from dataclasses import dataclass

from ins.common.errors import InputError
from ins.common.tomlschema import Table

__all__ = ["RtklibOptions", "read_rtklib_options", "MODES", "DIRECTIONS", "SYSTEMS",
           "fill_prcopt", "CARRIER_MODES", "PPP_MODES", "mode_without_base"]

MODES = ("single", "dgnss", "kinematic", "static", "ppp-kinematic", "ppp-static")
#: Modes that use the carrier phase (and so fix integer ambiguities).
CARRIER_MODES = ("kinematic", "static")
#: Precise point positioning: carrier phase with float ambiguities, no base.
PPP_MODES = ("ppp-kinematic", "ppp-static")
#: RTKLIB's pre-fit phase innovation threshold in the PPP modes, m (module notes).
PPP_MAX_INNOVATION_M = 30.0
DIRECTIONS = ("forward", "backward", "combined")
SYSTEMS = ("gps", "sbas", "glonass", "galileo", "qzss", "beidou", "navic")
AMBIGUITY = ("off", "continuous", "instantaneous", "fix-and-hold")
IONOSPHERE = ("off", "broadcast", "iono-free")
TROPOSPHERE = ("off", "saastamoinen", "estimate")
BASE_POSITION = ("rinex", "single")

KEYS = ("mode", "direction", "elevation_mask_deg", "frequencies", "systems", "dynamics",
        "ambiguity", "ar_ratio", "ionosphere", "troposphere", "base_position",
        "base_lla_deg", "rover_format", "base_format")


@dataclass(frozen=True)
class RtklibOptions:
    """Settings of one RTKLIB run (module notes; angles in deg as in the TOML file)."""

    mode: str = "kinematic"
    direction: str = "combined"
    elevation_mask_deg: float = 15.0
    frequencies: int = 2
    systems: tuple = ("gps", "glonass", "galileo")
    dynamics: bool = False
    ambiguity: str = None          # None: "fix-and-hold", "off" in the PPP modes
    ar_ratio: float = 3.0
    ionosphere: str = None         # None: "broadcast", "iono-free" in the PPP modes
    troposphere: str = None        # None: "saastamoinen", "estimate" in the PPP modes
    base_position: str = "rinex"
    base_lla_deg: tuple = None
    rover_format: str = None
    base_format: str = None

    def __post_init__(self):
        for name, allowed in (("mode", MODES), ("direction", DIRECTIONS),
                              ("ambiguity", AMBIGUITY), ("ionosphere", IONOSPHERE),
                              ("troposphere", TROPOSPHERE), ("base_position", BASE_POSITION)):
            if getattr(self, name) not in allowed and not (
                    getattr(self, name) is None and name in _BY_MODE):
                raise InputError(f"rtklib {name}: expected one of {', '.join(allowed)}, "
                                 f"got {getattr(self, name)!r}")
        bad = [s for s in self.systems if s not in SYSTEMS]
        if bad or not self.systems:
            raise InputError(f"rtklib systems: expected a non-empty list of "
                             f"{', '.join(SYSTEMS)}, got {list(self.systems)!r}")
        if not 0.0 <= self.elevation_mask_deg < 90.0:
            raise InputError(f"rtklib elevation_mask_deg: expected deg in [0, 90), got "
                             f"{self.elevation_mask_deg!r}")
        if self.frequencies not in (1, 2, 3):
            raise InputError(f"rtklib frequencies: expected 1, 2 or 3, got {self.frequencies!r}")
        if not (math.isfinite(self.ar_ratio) and self.ar_ratio >= 1.0):
            raise InputError(f"rtklib ar_ratio: expected a number >= 1, got {self.ar_ratio!r}")
        if self.setting("ionosphere") == "iono-free" and self.frequencies < 2:
            why = f" (the default of mode {self.mode!r})" if self.ionosphere is None else ""
            raise InputError(f"rtklib ionosphere 'iono-free'{why}: needs frequencies >= 2, "
                             f"got {self.frequencies}")
        if self.base_lla_deg is not None:
            lat, lon, h = self.base_lla_deg
            if not (abs(lat) <= 90 and abs(lon) <= 360 and math.isfinite(h)):
                raise InputError(f"rtklib base_lla_deg: expected [lat deg, lon deg, h m], got "
                                 f"{list(self.base_lla_deg)!r}")

    @property
    def uses_base(self):
        """Whether the mode needs a base station's observations."""
        return self.mode != "single" and self.mode not in PPP_MODES

    @property
    def is_ppp(self):
        """Whether the mode is precise point positioning (precise products, no base)."""
        return self.mode in PPP_MODES

    def setting(self, name):
        """The value of ``ambiguity``, ``ionosphere`` or ``troposphere`` in force: the
        one given, else the mode's default (module notes)."""
        value = getattr(self, name)
        if value is None:
            return _BY_MODE[name][1 if self.is_ppp else 0]
        return value


#: Settings whose default depends on the mode: (other modes, PPP modes).
_BY_MODE = {"ambiguity": ("fix-and-hold", "off"), "ionosphere": ("broadcast", "iono-free"),
            "troposphere": ("saastamoinen", "estimate")}


def mode_without_base(table, base, mode=None):
    """The positioning mode to override with: ``mode`` when given (the command line);
    ``"single"`` when no base station is given and the ``[rtklib]`` table names no mode
    (the default "kinematic" needs a base: a rover alone, as for tight coupling, is
    positioned point by point); else None (the table's or the default)."""
    if mode is not None:
        return mode
    if base is None and (table is None or "mode" not in table):
        return "single"
    return None


def read_rtklib_options(table, path=None, sections=None, **overrides):
    """The :class:`RtklibOptions` of a parsed ``[rtklib]`` TOML table (``None``: all
    defaults); ``overrides`` (e.g. ``mode`` from the command line) replace its values.

    Raises
    ------
    InputError
        Naming the file and ``[rtklib] key``: an unknown key (with the known ones), a
        value of the wrong type or out of range.
    """
    t = Table(table, "rtklib", path, known=KEYS, sections=sections)
    d = RtklibOptions()
    t.either("base_position", "base_lla_deg")
    kw = dict(
        mode=t.choice("mode", d.mode, MODES),
        direction=t.choice("direction", d.direction, DIRECTIONS),
        elevation_mask_deg=t.number("elevation_mask_deg", d.elevation_mask_deg,
                                    "deg in [0, 90)", lo=0.0, hi=89.999),
        frequencies=t.number("frequencies", d.frequencies, "1, 2 or 3", lo=1, hi=3,
                             integer=True),
        dynamics=t.boolean("dynamics", d.dynamics),
        ambiguity=_by_mode(t, "ambiguity", AMBIGUITY),
        ar_ratio=t.number("ar_ratio", d.ar_ratio, ">= 1", lo=1.0),
        ionosphere=_by_mode(t, "ionosphere", IONOSPHERE),
        troposphere=_by_mode(t, "troposphere", TROPOSPHERE),
        base_position=t.choice("base_position", d.base_position, BASE_POSITION),
    )
    systems = t.raw("systems", None)
    if systems is not None:
        if (not isinstance(systems, list) or not systems
                or not all(isinstance(s, str) and s.lower() in SYSTEMS for s in systems)):
            raise t.error("systems", f"expected a non-empty list of {', '.join(SYSTEMS)}, "
                                     f"got {systems!r}")
        kw["systems"] = tuple(dict.fromkeys(s.lower() for s in systems))
    lla = t.numbers("base_lla_deg", None, "[lat deg, lon deg, h m]", length=3, scalar=False)
    if lla is not None:
        if abs(lla[0]) > 90:
            raise t.error("base_lla_deg", f"latitude {lla[0]!r} outside +-90",
                          "[lat deg, lon deg, h m]")
        kw["base_lla_deg"] = lla
    from ins.gnss.receiver_formats import format_names
    for key in ("rover_format", "base_format"):
        value = t.raw(key, None)
        if value is not None:
            if not isinstance(value, str) or value.lower() not in format_names().split(", "):
                raise t.error(key, f"unknown GNSS receiver format {value!r}", format_names())
            kw[key] = value.lower()
    t.finish()
    kw.update({k: v for k, v in overrides.items() if v is not None})
    return RtklibOptions(**kw)


def system_bits(rtk):
    """``{system name: RTKLIB's SYS_ bit}`` (``rtk``: the imported ``pyrtklib5``)."""
    return {"gps": rtk.SYS_GPS, "sbas": rtk.SYS_SBS, "glonass": rtk.SYS_GLO,
            "galileo": rtk.SYS_GAL, "qzss": rtk.SYS_QZS, "beidou": rtk.SYS_CMP,
            "navic": rtk.SYS_IRN}


def _by_mode(t, key, options):
    """``[rtklib] key`` when given (one of ``options``), else None (the mode's default)."""
    return t.choice(key, options[0], options) if key in t.table else None


def fill_prcopt(opts, rtk, precise=False, atx=None, dcb=None):
    """RTKLIB's (prcopt, solopt, filopt) for ``opts``: fresh structs filled by RTKLIB
    from its defaults (``resetsysopts`` + ``getsysopts``, a C struct copy of
    ``prcopt_default``), then the settings of ``opts``.  ``rtk`` is the imported
    ``pyrtklib5`` module; ``precise`` selects the SP3/CLK ephemeris; ``atx`` (an ANTEX
    file: satellite and receiver antenna phase centres) and ``dcb`` (code biases, a
    file RTKLIB's ``readdcb`` reads) are paths or None."""
    rtk.resetsysopts()
    po, so, fo = rtk.prcopt_t(), rtk.solopt_t(), rtk.filopt_t()
    rtk.getsysopts(po, so, fo)
    po.mode = {"single": rtk.PMODE_SINGLE, "dgnss": rtk.PMODE_DGPS,
               "kinematic": rtk.PMODE_KINEMA, "static": rtk.PMODE_STATIC,
               "ppp-kinematic": rtk.PMODE_PPP_KINEMA,
               "ppp-static": rtk.PMODE_PPP_STATIC}[opts.mode]
    po.soltype = {"forward": rtk.SOLTYPE_FORWARD, "backward": rtk.SOLTYPE_BACKWARD,
                  "combined": rtk.SOLTYPE_COMBINED}[opts.direction]
    po.elmin = math.radians(opts.elevation_mask_deg)
    po.nf = int(opts.frequencies)
    sys_bits = system_bits(rtk)
    navsys = 0
    for s in opts.systems:
        navsys |= sys_bits[s]
    po.navsys = navsys
    po.dynamics = 1 if opts.dynamics else 0
    po.modear = {"off": rtk.ARMODE_OFF, "continuous": rtk.ARMODE_CONT,
                 "instantaneous": rtk.ARMODE_INST, "fix-and-hold": rtk.ARMODE_FIXHOLD
                 }[opts.setting("ambiguity")]
    po.thresar[0] = float(opts.ar_ratio)          # index 0 of 8: within bounds
    po.ionoopt = {"off": rtk.IONOOPT_OFF, "broadcast": rtk.IONOOPT_BRDC,
                  "iono-free": rtk.IONOOPT_IFLC}[opts.setting("ionosphere")]
    po.tropopt = {"off": rtk.TROPOPT_OFF, "saastamoinen": rtk.TROPOPT_SAAS,
                  "estimate": rtk.TROPOPT_EST}[opts.setting("troposphere")]
    po.sateph = rtk.EPHOPT_PREC if precise else rtk.EPHOPT_BRDC
    if opts.is_ppp:
        po.tidecorr = 1                           # solid Earth tides
        po.posopt[2] = 1                          # phase wind-up
        po.posopt[3] = 1                          # exclude satellites in eclipse
        po.maxinno[0] = PPP_MAX_INNOVATION_M      # phase (module notes); 2 elements
    if atx is not None:
        po.posopt[0] = 1                          # satellite antenna PCO/PCV
        po.posopt[1] = 1                          # receiver antenna PCO/PCV
        po.anttype[0, 0] = "*"                    # the rover's type from its RINEX header
        po.anttype[0, 1] = "\0"
        rtk.setstr(fo.satantp, os.fspath(atx), 1023)
        rtk.setstr(fo.rcvantp, os.fspath(atx), 1023)
    if dcb is not None:
        rtk.setstr(fo.dcb, os.fspath(dcb), 1023)
    if opts.base_lla_deg is not None:
        lat, lon, h = opts.base_lla_deg
        po.refpos = rtk.POSOPT_POS_LLH
        from ins.nav.earth import lla_to_ecef
        xyz = lla_to_ecef(math.radians(lat), math.radians(lon), h)
        for k in range(3):                        # rb has 3 elements
            po.rb[k] = float(xyz[k])
    else:
        po.refpos = {"rinex": rtk.POSOPT_RINEX, "single": rtk.POSOPT_SINGLE}[opts.base_position]
    # solution file: lat/lon/height (deg, ellipsoidal, WGS84), GPS week and seconds,
    # the header (column names, ref pos); velocity only in single mode (module notes)
    so.posf = rtk.SOLF_LLH
    so.times = rtk.TIMES_GPST
    so.timef = 0
    so.timeu = 3
    so.height = 0
    so.datum = 0
    so.outhead = 1
    so.outopt = 1
    so.outvel = 1 if opts.mode == "single" else 0
    return po, so, fo
