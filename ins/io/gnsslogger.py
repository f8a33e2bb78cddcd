"""Android GnssLogger logs (Google's GnssLogger app, ``gnss_log_*.txt``): the raw GNSS
measurements (``Raw`` records of ``android.location.GnssMeasurement`` and its clock), the
phone's own fixes (``Fix``) and the inertial sensors (``UncalAccel``, ``UncalGyro``,
``Accel``, ``Gyro``).

The file is text: ``#`` comment lines, among them one header per record type
(``# Raw,utcTimeMillis,TimeNanos,...``) naming its columns, then data lines
``Raw,1650000000000,1234,...`` (comma separated, empty fields allowed).  Columns are
taken by name, so logs of every GnssLogger version read the same way.

Pseudoranges (Google's "Raw GNSS measurements" white paper, 2017, and the
``GnssMeasurement`` reference):

- receive time, GNSS time scale: ``t_rx = TimeNanos + TimeOffsetNanos - (FullBiasNanos
  + BiasNanos)`` ns since the GPS epoch (each epoch's own biases: the epoch time is the
  phone's estimate of GPS time, the pseudoranges stay consistent with it); its time of
  week (GPS, QZSS, Galileo), of the BeiDou week (GPS - 14 s) or of the GLONASS day
  (UTC + 3 h: GPS - leap seconds + 3 h);
- ``pseudorange = (t_rx - ReceivedSvTimeNanos) * c``, kept when the ``State`` says the
  satellite time is known: TOW decoded or known (bits 3, 14) for GPS/QZSS/Galileo/
  BeiDou, time of day decoded or known (bits 7, 15) for GLONASS, and the code locked
  (bit 0), and ``ReceivedSvTimeUncertaintyNanos`` is at most
  :data:`MAX_SV_TIME_UNCERTAINTY_NS` (500 ns, 150 m: the default of Google's GPS
  Measurement Tools; the 600-700 ns of a weak signal in the phones' logs are a
  pseudorange in error by hundreds of m);
- carrier phase ``AccumulatedDeltaRangeMeters / wavelength`` (cycles) when
  ``AccumulatedDeltaRangeState`` has VALID (bit 0); RESET or CYCLE_SLIP (bits 1, 2), or
  a change of ``HardwareClockDiscontinuityCount`` since the previous epoch (the
  receiver's clock restarted: no phase is continuous across it), set the loss-of-lock
  indicator;
- Doppler ``-PseudorangeRateMetersPerSecond / wavelength`` (Hz), signal strength
  ``Cn0DbHz``.

The signal from ``CarrierFrequencyHz`` (L1/E1/B1C 1575.42 MHz, B1I 1561.098 MHz,
GLONASS G1 1602 + k 0.5625 MHz, L5/E5a 1176.45 MHz) with the RINEX 3 codes of phone
chips: ``1C`` (GPS, QZSS, Galileo E1C, GLONASS), ``2I`` (BeiDou B1I), ``5Q`` (L5/E5a).
"""
import os

import numpy as np

from ins.common.errors import InputError

__all__ = ["read_gnsslogger", "GnssLoggerLog", "raw_observations", "RawObservations",
           "sensor_to_gps", "unix_ms_to_gps", "leap_seconds_at_gps_ns", "CLIGHT", "SIGNALS",
           "MAX_SV_TIME_UNCERTAINTY_NS"]

CLIGHT = 299792458.0
WEEK_NS = 604800 * 10 ** 9
DAY_NS = 86400 * 10 ** 9
#: ConstellationType -> RINEX system letter.
SYSTEMS = {1: "G", 2: "S", 3: "R", 4: "J", 5: "C", 6: "E", 7: "I"}
#: (system letter, band) -> RINEX 3 signal code of phone chipsets.
SIGNALS = {("G", "L1"): "1C", ("G", "L5"): "5Q", ("J", "L1"): "1C", ("J", "L5"): "5Q",
           ("E", "L1"): "1C", ("E", "L5"): "5Q", ("C", "B1I"): "2I", ("C", "L1"): "1P",
           ("C", "L5"): "5P", ("R", "G1"): "1C", ("S", "L1"): "1C", ("S", "L5"): "5I",
           ("I", "L5"): "5A"}
_STATE_CODE_LOCK, _STATE_TOW_DECODED, _STATE_TOW_KNOWN = 1, 8, 16384
_STATE_GLO_TOD_DECODED, _STATE_GLO_TOD_KNOWN = 128, 32768
_ADR_VALID, _ADR_RESET, _ADR_SLIP = 1, 2, 4
#: Largest ReceivedSvTimeUncertaintyNanos kept (150 m of pseudorange; the default of
#: Google's GPS Measurement Tools, SetDataFilter.m).
MAX_SV_TIME_UNCERTAINTY_NS = 500.0
_TYPES = ("Raw", "Fix", "UncalAccel", "UncalGyro", "Accel", "Gyro")


class GnssLoggerLog:
    """The records of a GnssLogger file: ``tables[type]`` a dict ``{column: ndarray}``
    (numbers as float, NaN where empty; ``Provider`` and ``CodeType`` as str) with
    ``lines[type]`` the 1-based line of each record; ``path``; ``skipped`` the records
    left out as malformed, a list of ``(line, reason)``."""

    def __init__(self, path, tables, lines, skipped=()):
        self.path, self.tables, self.lines = path, tables, lines
        self.skipped = list(skipped)

    def has(self, kind):
        return kind in self.tables and len(self.lines[kind]) > 0


_TEXT_COLUMNS = ("Provider", "CodeType")
_INT_COLUMNS = ("TimeNanos", "FullBiasNanos", "ReceivedSvTimeNanos", "elapsedRealtimeNanos",
                "ChipsetElapsedRealtimeNanos", "utcTimeMillis", "UnixTimeMillis")
#: Column names of early GnssLogger versions (1.4, 2016) -> today's.
_ALIASES = {"Fix": {"Latitude": "LatitudeDegrees", "Longitude": "LongitudeDegrees",
                    "Altitude": "AltitudeMeters", "Speed": "SpeedMps",
                    "Accuracy": "AccuracyMeters", "(UTC)TimeInMs": "UnixTimeMillis"}}


def read_gnsslogger(path):
    """Read a GnssLogger text file (module notes).

    Columns are taken by the names of their header, those of early app versions
    (``Fix,Provider,Latitude,Longitude,Altitude,Speed,Accuracy,(UTC)TimeInMs``) under
    today's names.  A record whose number of fields differs from its header's (a line
    cut short when the app stopped) or with a field that is no number (a corrupt
    line) is left out and listed in ``skipped``: one bad line does not lose the log.

    Raises
    ------
    InputError
        Naming the file and line: a record before its header (not a GnssLogger log);
        naming the file: no usable record at all.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read().splitlines()
    except OSError as e:
        raise InputError(f"cannot read the GnssLogger log: {e.strerror}", path=path) from None
    headers, rows, skipped = {}, {k: [] for k in _TYPES}, []
    for no, line in enumerate(text, 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s.lstrip("#").strip()
            kind = body.split(",", 1)[0].strip()
            if kind in _TYPES and "," in body:
                alias = _ALIASES.get(kind, {})
                headers[kind] = [alias.get(c.strip(), c.strip()) for c in body.split(",")[1:]]
            continue
        kind = s.split(",", 1)[0]
        if kind not in _TYPES:
            continue                       # Status, OrientationDeg, Nav, Agc, ...: unused
        if kind not in headers:
            raise InputError(f"line {no}: a {kind} record before its '# {kind},...' header "
                             f"(not a GnssLogger log?)", path=path)
        fields = s.split(",")[1:]
        if len(fields) != len(headers[kind]):
            skipped.append((no, f"{kind} record with {len(fields)} fields, its header "
                                f"names {len(headers[kind])}"))
            continue
        rows[kind].append((no, [v.strip() for v in fields]))
    tables, lines = {}, {}
    for kind, recs in rows.items():
        cols = headers.get(kind, [])
        bad = {}
        for j, name in enumerate(cols):
            if name in _TEXT_COLUMNS:
                continue
            for i, (no, fields) in enumerate(recs):
                if fields[j] and not _is_number(fields[j]) and i not in bad:
                    bad[i] = (no, f"{kind} {name}: expected a number, got {fields[j]!r}")
        skipped += bad.values()
        recs = [r for i, r in enumerate(recs) if i not in bad]
        if not recs:
            continue
        lines[kind] = np.array([no for no, _ in recs])
        table = {}
        for j, name in enumerate(cols):
            values = [r[1][j] for r in recs]
            if name in _TEXT_COLUMNS:
                table[name] = np.array(values, dtype=object)
            elif name in _INT_COLUMNS:         # ns counts beyond float's 2^53
                table[name] = np.array([_int(v) for v in values], dtype=object)
            else:
                table[name] = np.array([float(v) if v else np.nan for v in values])
        tables[kind] = table
    skipped.sort()
    if not tables:
        what = (f"; {len(skipped)} malformed records, the first: line {skipped[0][0]}: "
                f"{skipped[0][1]}") if skipped else ""
        raise InputError("no Raw, Fix, UncalAccel/UncalGyro or Accel/Gyro record that "
                         "could be read (expected a GnssLogger log: '# Raw,utcTimeMillis,"
                         f"TimeNanos,...' headers and records){what}", path=path)
    return GnssLoggerLog(path, tables, lines, skipped)


_MISSING = None


def _int(v):
    """An integer column's field: exact for integers, a float written as 1.5E9 rounded."""
    if not v:
        return _MISSING
    try:
        return int(v)
    except ValueError:
        return int(round(float(v)))


def _is_number(v):
    try:
        float(v)
        return True
    except ValueError:
        return False


def _ints(table, name, path, kind):
    if name not in table:
        raise InputError(f"{kind} records have no {name} column (GnssLogger header)", path=path)
    return table[name]


def _band(sys, f_hz):
    if sys == "R" and 1590e6 < f_hz < 1615e6:
        return "G1"
    if abs(f_hz - 1575.42e6) < 1e5:
        return "L1"
    if abs(f_hz - 1561.098e6) < 1e5:
        return "B1I"
    if abs(f_hz - 1176.45e6) < 1e5:
        return "L5"
    return None


class RawObservations:
    """Observations of the Raw records, by epoch.

    Attributes
    ----------
    week : int
        GPS week of the first epoch.
    time_s : ndarray, shape (n,)
        Epochs, GPS seconds of ``week`` (the phone's GPS time estimate).
    epochs : list of dict
        Per epoch ``{(sys, prn, code): (C m, L cycles, D Hz, S dB-Hz, lli)}`` (NaN: not
        valid).
    elapsed_ns : ndarray, shape (n,)
        The epoch's ``ChipsetElapsedRealtimeNanos`` (or ``elapsedRealtimeNanos``),
        NaN-free int64 or None when the log has none.
    leap_s : int
        GPS - UTC of the log (its ``LeapSecond`` column, else the leap-second table at
        its first epoch).
    dropped : int
        Measurements left out (time unknown, no code lock, an unknown signal, a
        ReceivedSvTimeUncertaintyNanos above 500 ns).
    glonass_fcn : dict
        ``{slot: frequency channel k}`` of the GLONASS satellites, from their G1
        ``CarrierFrequencyHz`` = 1602 MHz + k 0.5625 MHz (the RINEX header's
        ``GLONASS SLOT / FRQ #``).
    """

    def __init__(self, week, time_s, epochs, elapsed_ns, leap_s, dropped, glonass_fcn=None):
        self.week, self.time_s, self.epochs = week, time_s, epochs
        self.elapsed_ns, self.leap_s, self.dropped = elapsed_ns, leap_s, dropped
        self.glonass_fcn = dict(glonass_fcn or {})


def raw_observations(log, leap_s=None):
    """The pseudoranges, phases, Dopplers and C/N0 of the ``Raw`` records (module
    notes) as :class:`RawObservations`.

    Raises
    ------
    InputError
        Naming the file: no Raw record, a column missing, no valid clock
        (``FullBiasNanos``).
    """
    path = log.path
    if not log.has("Raw"):
        raise InputError("no Raw record (GnssLogger: enable 'Raw' measurements)", path=path)
    t = log.tables["Raw"]
    lines = log.lines["Raw"]
    time_ns = _ints(t, "TimeNanos", path, "Raw")
    full = _ints(t, "FullBiasNanos", path, "Raw")
    rx_sv = _ints(t, "ReceivedSvTimeNanos", path, "Raw")
    for c in ("BiasNanos", "TimeOffsetNanos", "State", "Svid", "ConstellationType",
              "Cn0DbHz", "PseudorangeRateMetersPerSecond"):
        _ints(t, c, path, "Raw")
    if leap_s is None:
        ls = t.get("LeapSecond", np.array([np.nan]))
        ls = ls[np.isfinite(ls)]
        first = next((i for i in range(len(lines)) if full[i] is not None
                      and time_ns[i] is not None), None)
        leap_s = int(ls[0]) if ls.size else (
            leap_seconds_at_gps_ns(time_ns[first] - full[first]) if first is not None else 18)
    elapsed = t.get("ChipsetElapsedRealtimeNanos")
    if elapsed is None or all(v is None for v in elapsed):
        elapsed = t.get("elapsedRealtimeNanos")
    ok_clock = [v is not None for v in full]
    if not any(ok_clock):
        raise InputError("Raw records without FullBiasNanos: the phone never had GPS time "
                         "(no fix during the log?)", path=path)
    freq = t.get("CarrierFrequencyHz", np.full(len(lines), 1575.42e6))
    freq = np.where(np.isfinite(freq), freq, 1575.42e6)
    adr = t.get("AccumulatedDeltaRangeMeters", np.full(len(lines), np.nan))
    adr_state = t.get("AccumulatedDeltaRangeState", np.zeros(len(lines)))
    hcd = t.get("HardwareClockDiscontinuityCount", np.full(len(lines), np.nan))
    sv_unc = np.nan_to_num(t.get("ReceivedSvTimeUncertaintyNanos", np.zeros(len(lines))),
                           nan=0.0)
    epochs, times, els = [], [], []
    key_prev = None
    hcd_prev, hcd_jump = None, False
    fcn = {}
    dropped = 0
    week0 = None
    for i in range(len(lines)):
        if full[i] is None or time_ns[i] is None or rx_sv[i] is None:
            dropped += 1
            continue
        bias = t["BiasNanos"][i] if np.isfinite(t["BiasNanos"][i]) else 0.0
        offset = t["TimeOffsetNanos"][i] if np.isfinite(t["TimeOffsetNanos"][i]) else 0.0
        # integer ns first (exact), then the sub-ns parts
        t_rx_int = time_ns[i] - full[i]
        t_rx_frac = offset - bias
        if week0 is None:
            week0 = int(t_rx_int // WEEK_NS)
        key = time_ns[i]
        if key != key_prev:
            epochs.append({})
            times.append((t_rx_int - week0 * WEEK_NS) * 1e-9 - bias * 1e-9)
            els.append(None if elapsed is None else elapsed[i])
            key_prev = key
            # a hardware clock discontinuity breaks every carrier phase
            hcd_jump = hcd_prev is not None and np.isfinite(hcd[i]) and hcd[i] != hcd_prev
            hcd_prev = hcd[i] if np.isfinite(hcd[i]) else hcd_prev
        sys = SYSTEMS.get(int(t["ConstellationType"][i]))
        band = _band(sys, freq[i]) if sys else None
        code = SIGNALS.get((sys, band))
        state = int(t["State"][i]) if np.isfinite(t["State"][i]) else 0
        if sys == "R":
            known = state & (_STATE_GLO_TOD_DECODED | _STATE_GLO_TOD_KNOWN)
            period, shift = DAY_NS, 3 * 3600 * 10 ** 9 - leap_s * 10 ** 9
        else:
            known = state & (_STATE_TOW_DECODED | _STATE_TOW_KNOWN)
            period = WEEK_NS
            shift = -14 * 10 ** 9 if sys == "C" else 0
        if (code is None or not known or not state & _STATE_CODE_LOCK
                or sv_unc[i] > MAX_SV_TIME_UNCERTAINTY_NS):
            dropped += 1
            continue
        t_sys = (t_rx_int + shift) % period
        pr = ((t_sys - rx_sv[i]) + t_rx_frac) * 1e-9 * CLIGHT
        if pr < -period * 0.5e-9 * CLIGHT:                 # across the week/day rollover
            pr += period * 1e-9 * CLIGHT
        lam = CLIGHT / freq[i]
        st = int(adr_state[i]) if np.isfinite(adr_state[i]) else 0
        phase = adr[i] / lam if st & _ADR_VALID and np.isfinite(adr[i]) and adr[i] else np.nan
        lli = 1 if st & (_ADR_RESET | _ADR_SLIP) or hcd_jump else 0
        dop = -t["PseudorangeRateMetersPerSecond"][i] / lam
        epochs[-1][(sys, int(t["Svid"][i]), code)] = (pr, phase, dop, t["Cn0DbHz"][i], lli)
        if sys == "R":
            k = (freq[i] - 1602e6) / 0.5625e6
            if abs(k - round(k)) < 0.01 and -7 <= round(k) <= 6:
                fcn[int(t["Svid"][i])] = int(round(k))
    if not epochs:
        raise InputError("no Raw record with a known clock", path=path)
    el = None if any(v is None for v in els) else np.array(els, dtype=np.int64)
    return RawObservations(week0, np.array(times), epochs, el, leap_s, dropped, fcn)


def sensor_to_gps(raw, log):
    """A map from the phone's ``elapsedRealtimeNanos`` (boot clock, ns) to GPS seconds
    of ``raw.week``: the least-squares line (offset and the boot clock's rate error)
    through, in this order of preference,

    1. the Raw epochs' ``ChipsetElapsedRealtimeNanos`` and their GPS times (GNSS time,
       microseconds);
    2. the GPS fixes' ``elapsedRealtimeNanos`` and ``UnixTimeMillis`` (UTC + leap
       seconds; GNSS time in millisecond stamps);
    3. the inertial records' own ``elapsedRealtimeNanos`` and ``utcTimeMillis`` (logs
       before Android 10 carry neither of the above): the phone's system clock (NTP,
       UTC + leap seconds), not GNSS time: its offset from GPS time is unknown (tens of
       ms, more without a network), see ``source``.

    Returns
    -------
    func : callable
        ``func(elapsed_ns int array) -> GPS s``.
    source : tuple
        ``(what the line went through, RMS of its residuals s)``.

    Raises
    ------
    InputError
        Naming the file: none of the three pairs is in the log twice.
    """
    x = y = None
    if raw.elapsed_ns is not None and len(raw.elapsed_ns) >= 2:
        x = raw.elapsed_ns.astype(np.int64)
        y = raw.time_s
        src = "Raw ChipsetElapsedRealtimeNanos"
    if x is None and log.has("Fix") and "elapsedRealtimeNanos" in log.tables["Fix"]:
        f = log.tables["Fix"]
        prov = f.get("Provider", np.array(["gps"] * len(log.lines["Fix"]), dtype=object))
        keep = [i for i, (e, u) in enumerate(zip(f["elapsedRealtimeNanos"],
                                                 f["UnixTimeMillis"]))
                if e is not None and u is not None and str(prov[i]).lower() == "gps"]
        if len(keep) >= 2:
            x = np.array([f["elapsedRealtimeNanos"][i] for i in keep], dtype=np.int64)
            unix_ms = np.array([f["UnixTimeMillis"][i] for i in keep], dtype=np.int64)
            y = unix_ms_to_gps(unix_ms, raw.week, raw.leap_s)
            src = "Fix elapsedRealtimeNanos/UnixTimeMillis"
    if x is None:
        pairs = [(e, u) for kind in ("UncalGyro", "Gyro", "UncalAccel", "Accel")
                 if log.has(kind) and "utcTimeMillis" in log.tables[kind]
                 and "elapsedRealtimeNanos" in log.tables[kind]
                 for e, u in zip(log.tables[kind]["elapsedRealtimeNanos"],
                                 log.tables[kind]["utcTimeMillis"])
                 if e is not None and u is not None and u > 0]
        if len(pairs) >= 2:
            x = np.array([p[0] for p in pairs], dtype=np.int64)
            y = unix_ms_to_gps(np.array([p[1] for p in pairs], dtype=np.int64), raw.week,
                               raw.leap_s)
            src = ("the sensors' utcTimeMillis: the phone's system clock, not GNSS time "
                   "(its offset from GPS time is unknown: tens of ms; estimate it with "
                   "ins time-offset)")
    if x is None:
        raise InputError("cannot put the sensors on GPS time: neither the Raw records "
                         "(ChipsetElapsedRealtimeNanos) nor 2 GPS fixes "
                         "(elapsedRealtimeNanos) nor the sensor records (utcTimeMillis) "
                         "tie the boot clock to a time scale", path=log.path)
    x0 = int(x.min())
    dx = (x - x0) * 1e-9
    if np.ptp(dx) > 0:
        a, b = np.polyfit(dx, y, 1)
    else:
        a, b = 1.0, float(np.mean(y))
    rms = float(np.sqrt(np.mean((a * dx + b - y) ** 2)))
    return (lambda e: a * ((np.asarray(e, dtype=np.int64) - x0) * 1e-9) + b), (src, rms)


def leap_seconds_at_gps_ns(gps_ns):
    """GPS - UTC, s, at a GPS time in ns since the GPS epoch (the table
    :data:`ins.io.rtklib.LEAP_SECONDS` by UTC date; GnssLogger logs before 2017, and
    many since, leave their ``LeapSecond`` column empty)."""
    from ins.io.rtklib import LEAP_SECONDS
    import datetime as dt
    gps = dt.datetime(1980, 1, 6) + dt.timedelta(microseconds=int(gps_ns) // 1000)
    leap = 0
    for y, m, d, n in LEAP_SECONDS:
        if gps - dt.timedelta(seconds=n) >= dt.datetime(y, m, d):
            leap = n
    return leap


def unix_ms_to_gps(unix_ms, week, leap_s):
    """GPS seconds of ``week`` of Unix milliseconds (UTC), with ``leap_s``."""
    gps_epoch_unix_ms = 315964800000
    gps_ms = unix_ms - gps_epoch_unix_ms + leap_s * 1000
    return (gps_ms - week * 604800000) * 1e-3
