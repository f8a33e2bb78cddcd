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
  (bit 0);
- carrier phase ``AccumulatedDeltaRangeMeters / wavelength`` (cycles) when
  ``AccumulatedDeltaRangeState`` has VALID (bit 0); RESET or CYCLE_SLIP (bits 1, 2) set
  the loss-of-lock indicator;
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
           "sensor_to_gps", "unix_ms_to_gps", "CLIGHT", "SIGNALS"]

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
_TYPES = ("Raw", "Fix", "UncalAccel", "UncalGyro", "Accel", "Gyro")


class GnssLoggerLog:
    """The records of a GnssLogger file: ``tables[type]`` a dict ``{column: ndarray}``
    (numbers as float, NaN where empty; ``Provider`` and ``CodeType`` as str) with
    ``lines[type]`` the 1-based line of each record; ``path``."""

    def __init__(self, path, tables, lines):
        self.path, self.tables, self.lines = path, tables, lines

    def has(self, kind):
        return kind in self.tables and len(self.lines[kind]) > 0


_TEXT_COLUMNS = ("Provider", "CodeType")
_INT_COLUMNS = ("TimeNanos", "FullBiasNanos", "ReceivedSvTimeNanos", "elapsedRealtimeNanos",
                "ChipsetElapsedRealtimeNanos", "utcTimeMillis", "UnixTimeMillis")


def read_gnsslogger(path):
    """Read a GnssLogger text file (module notes).

    Raises
    ------
    InputError
        Naming the file and line: no header for a record type, a record with another
        number of fields than its header, a field that is no number.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read().splitlines()
    except OSError as e:
        raise InputError(f"cannot read the GnssLogger log: {e.strerror}", path=path) from None
    headers, rows = {}, {k: [] for k in _TYPES}
    for no, line in enumerate(text, 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s.lstrip("#").strip()
            kind = body.split(",", 1)[0].strip()
            if kind in _TYPES and "," in body:
                headers[kind] = [c.strip() for c in body.split(",")[1:]]
            continue
        kind = s.split(",", 1)[0]
        if kind not in _TYPES:
            continue                       # Status, OrientationDeg, Nav, Agc, ...: unused
        if kind not in headers:
            raise InputError(f"line {no}: a {kind} record before its '# {kind},...' header "
                             f"(not a GnssLogger log?)", path=path)
        fields = s.split(",")[1:]
        if len(fields) != len(headers[kind]):
            raise InputError(f"line {no}: {kind} record with {len(fields)} fields, its header "
                             f"names {len(headers[kind])}", path=path)
        rows[kind].append((no, fields))
    if not any(rows.values()):
        raise InputError("no Raw, Fix, UncalAccel/UncalGyro or Accel/Gyro record (expected a "
                         "GnssLogger log: '# Raw,utcTimeMillis,TimeNanos,...' headers and "
                         "records)", path=path)
    tables, lines = {}, {}
    for kind, recs in rows.items():
        if not recs:
            continue
        cols = headers[kind]
        lines[kind] = np.array([no for no, _ in recs])
        table = {}
        for j, name in enumerate(cols):
            values = [r[1][j].strip() for r in recs]
            if name in _TEXT_COLUMNS:
                table[name] = np.array(values, dtype=object)
                continue
            try:
                if name in _INT_COLUMNS:     # ns counts beyond float's 2^53
                    table[name] = np.array([int(v) if v else _MISSING for v in values],
                                           dtype=object)
                else:
                    table[name] = np.array([float(v) if v else np.nan for v in values])
            except ValueError:
                bad = next(i for i, v in enumerate(values) if v and not _is_number(v))
                raise InputError(f"line {recs[bad][0]}: {kind} {name}: expected a number, "
                                 f"got {values[bad]!r}", path=path) from None
        tables[kind] = table
    return GnssLoggerLog(path, tables, lines)


_MISSING = None


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
        GPS - UTC of the log (its ``LeapSecond`` column, else 18).
    dropped : int
        Measurements left out (time unknown, no code lock, an unknown signal).
    """

    def __init__(self, week, time_s, epochs, elapsed_ns, leap_s, dropped):
        self.week, self.time_s, self.epochs = week, time_s, epochs
        self.elapsed_ns, self.leap_s, self.dropped = elapsed_ns, leap_s, dropped


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
        leap_s = int(ls[0]) if ls.size else 18
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
    epochs, times, els = [], [], []
    key_prev = None
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
        if code is None or not known or not state & _STATE_CODE_LOCK:
            dropped += 1
            continue
        t_sys = (t_rx_int + shift) % period
        pr = ((t_sys - rx_sv[i]) + t_rx_frac) * 1e-9 * CLIGHT
        if pr < -period * 0.5e-9 * CLIGHT:                 # across the week/day rollover
            pr += period * 1e-9 * CLIGHT
        lam = CLIGHT / freq[i]
        st = int(adr_state[i]) if np.isfinite(adr_state[i]) else 0
        phase = adr[i] / lam if st & _ADR_VALID and np.isfinite(adr[i]) and adr[i] else np.nan
        lli = 1 if st & (_ADR_RESET | _ADR_SLIP) else 0
        dop = -t["PseudorangeRateMetersPerSecond"][i] / lam
        epochs[-1][(sys, int(t["Svid"][i]), code)] = (pr, phase, dop, t["Cn0DbHz"][i], lli)
    if not epochs:
        raise InputError("no Raw record with a known clock", path=path)
    el = None if any(v is None for v in els) else np.array(els, dtype=np.int64)
    return RawObservations(week0, np.array(times), epochs, el, leap_s, dropped)


def sensor_to_gps(raw, log):
    """A map from the phone's ``elapsedRealtimeNanos`` (boot clock, ns) to GPS seconds
    of ``raw.week``: the least-squares line through the Raw epochs' elapsed realtime and
    their GPS times (offset and the boot clock's rate error), else, when the Raw records
    carry no elapsed realtime, through the GPS fixes' ``elapsedRealtimeNanos`` and
    ``UnixTimeMillis`` (UTC + leap seconds; millisecond stamps).

    Returns
    -------
    func : callable
        ``func(elapsed_ns int array) -> GPS s``.
    source : str
        ``"Raw"`` or ``"Fix"``, and the RMS of the line's residuals, s.
    """
    if raw.elapsed_ns is not None and len(raw.elapsed_ns) >= 2:
        x = raw.elapsed_ns.astype(np.int64)
        y = raw.time_s
        src = "Raw ChipsetElapsedRealtimeNanos"
    elif log.has("Fix") and "elapsedRealtimeNanos" in log.tables["Fix"]:
        f = log.tables["Fix"]
        keep = [i for i, (e, u) in enumerate(zip(f["elapsedRealtimeNanos"],
                                                 f["UnixTimeMillis"]))
                if e is not None and u is not None
                and str(f.get("Provider", ["gps"] * (i + 1))[i]).lower() == "gps"]
        if len(keep) < 2:
            raise InputError("cannot put the sensors on GPS time: the Raw records carry no "
                             "ChipsetElapsedRealtimeNanos and fewer than 2 GPS fixes have "
                             "elapsedRealtimeNanos", path=log.path)
        x = np.array([f["elapsedRealtimeNanos"][i] for i in keep], dtype=np.int64)
        unix_ms = np.array([f["UnixTimeMillis"][i] for i in keep], dtype=np.int64)
        y = unix_ms_to_gps(unix_ms, raw.week, raw.leap_s)
        src = "Fix elapsedRealtimeNanos/UnixTimeMillis"
    else:
        raise InputError("cannot put the sensors on GPS time: neither the Raw records nor "
                         "the fixes carry elapsedRealtimeNanos", path=log.path)
    x0 = int(x[0])
    dx = (x - x0) * 1e-9
    a, b = np.polyfit(dx, y, 1)
    rms = float(np.sqrt(np.mean((a * dx + b - y) ** 2)))
    return (lambda e: a * ((np.asarray(e, dtype=np.int64) - x0) * 1e-9) + b), (src, rms)


def unix_ms_to_gps(unix_ms, week, leap_s):
    """GPS seconds of ``week`` of Unix milliseconds (UTC), with ``leap_s``."""
    gps_epoch_unix_ms = 315964800000
    gps_ms = unix_ms - gps_epoch_unix_ms + leap_s * 1000
    return (gps_ms - week * 604800000) * 1e-3
