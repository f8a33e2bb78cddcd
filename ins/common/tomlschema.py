"""Strict reading of the toolkit's TOML files: one set of rules and messages for all.

Every TOML file the toolkit reads (camera file, lunar fisheye camera file, flight plan,
processing config) is checked against the sections (tables) and keys its reader knows.
A misspelt key is never ignored: ``lever_arm = [...]`` for ``lever_arm_m`` would
otherwise give a result computed with the default (a zero lever arm) without a word.

Rules and messages (:class:`ins.common.errors.InputError`, ``str(exc)`` starts with the file):

- an unknown section or key (one line each)::

      camera.toml: [mounting] lever_arm: unknown key (did you mean lever_arm_m?);
          known keys of [mounting]: axes, boresight_deg, lever_arm_m
      camera.toml: [mount]: unknown section (did you mean [mounting]?);
          known sections: [camera], [mounting]

  A key that belongs to another section says so (``... (it belongs in [mounting])``);
  a key outside any section (before the first ``[section]`` line) is named as such.
- a missing required key: ``[camera] pixel_size_mm: missing required key (expected mm)``;
- a value of the wrong type or out of range names the expected unit:
  ``[camera] focal_length_mm: expected a number, got '100' (expected mm > 0)``.

Two ways to use it, with the same messages:

- :func:`check_keys` checks the names only, in one call, against a mapping
  ``{section: keys}`` (the readers then take the values as they like)::

      check_keys(doc, {"files": {"imu", "gnss"}, "filter": {"start_s", "end_s"}}, path)

- :class:`Table` gives typed access to one section (``number``, ``numbers``, ``boolean``,
  ``choice``, ``string``, ``matrix``) and refuses the keys that were not read in
  :meth:`Table.finish`.
"""
import difflib
import math

from ins.common.errors import InputError

__all__ = ["check_keys", "Table", "unknown_key", "unknown_section", "missing_key",
           "REQUIRED"]


class _Required:
    def __repr__(self):
        return "REQUIRED"


#: Default meaning "the key must be present".
REQUIRED = _Required()


def _close(word, candidates):
    match = difflib.get_close_matches(word, sorted(candidates), n=1, cutoff=0.6)
    if match:
        return match[0]
    # a unit suffix left out or changed: lever_arm -> lever_arm_m, focal_px -> focal_mm
    stem = word.rsplit("_", 1)[0] if "_" in word else word
    for c in sorted(candidates):
        if c.startswith(word + "_") or (len(stem) >= 4 and c.rsplit("_", 1)[0] == stem):
            return c
    return None


def _known_list(keys):
    return ", ".join(sorted(keys)) if keys else "(none)"


def _where(section, key):
    if section is None:
        return f"{key}"
    return f"[{section}] {key}" if key is not None else f"[{section}]"


def unknown_key(path, section, key, known, other_sections=None):
    """The :class:`InputError` for ``key`` not among ``known`` in ``[section]``.

    Parameters
    ----------
    path : str or None
        The file.
    section : str
        Section name (``None``: a key outside any section).
    key : str
    known : iterable of str
        The keys of that section.
    other_sections : mapping, optional
        ``{section: keys}`` of the whole file, to say where a key belongs.
    """
    known = set(known)
    hint = ""
    owners = sorted(s for s, keys in (other_sections or {}).items()
                    if keys is not None and s != section and key in keys)
    if owners:
        hint = f" (it belongs in [{owners[0]}])"
    else:
        near = _close(key, known)
        if near is None and other_sections:
            pool = {k: s for s, keys in other_sections.items() if keys is not None
                    for k in keys}
            near_any = _close(key, pool)
            if near_any is not None:
                hint = f" (did you mean [{pool[near_any]}] {near_any}?)"
        elif near is not None:
            hint = f" (did you mean {near}?)"
    if section is None:
        return InputError(f"{key}: unknown key outside any section{hint}; known sections: "
                          + ", ".join(f"[{s}]" for s in sorted(other_sections or {})),
                          path=path)
    return InputError(f"[{section}] {key}: unknown key{hint}; known keys of [{section}]: "
                      f"{_known_list(known)}", path=path)


def unknown_section(path, section, known_sections):
    """The :class:`InputError` for a section not among ``known_sections``."""
    near = _close(section, known_sections)
    hint = f" (did you mean [{near}]?)" if near else ""
    return InputError(f"[{section}]: unknown section{hint}; known sections: "
                      + ", ".join(f"[{s}]" for s in sorted(known_sections)), path=path)


def missing_key(path, section, key, unit=""):
    """The :class:`InputError` for a required key that is absent."""
    tail = f" (expected {unit})" if unit else ""
    return InputError(f"{_where(section, key)}: missing required key{tail}", path=path)


def check_keys(doc, known, path=None, top_keys=(), required=()):
    """Refuse unknown sections and keys of a parsed TOML file (names only).

    Parameters
    ----------
    doc : dict
        The parsed file (``tomllib``).
    known : mapping
        ``{section: iterable of keys}``; ``None`` instead of the keys accepts any key in
        that section (free-form text tables).
    path : str or os.PathLike, optional
        The file, named in the messages.
    top_keys : iterable of str
        Keys allowed outside any section (e.g. ``format``).
    required : iterable
        Required sections (``"camera"``) or keys (``("camera", "focal_length_mm")``).

    Returns
    -------
    dict
        ``doc`` itself.

    Raises
    ------
    InputError
        Naming the file and the ``[section] key``, with the known keys of the section
        and "did you mean ..." where a known key is close.
    """
    path = None if path is None else str(path)
    if not isinstance(doc, dict):
        raise InputError("expected a TOML document of sections", path=path)
    sections = {s: (None if keys is None else set(keys)) for s, keys in known.items()}
    top_keys = set(top_keys)
    for name, value in doc.items():
        if name in top_keys:
            continue
        if name not in sections:
            if isinstance(value, dict):
                raise unknown_section(path, name, sections)
            raise unknown_key(path, None, name, top_keys, sections)
        if not isinstance(value, dict):
            raise InputError(f"[{name}]: expected a section (table), got "
                             f"{type(value).__name__} {value!r}", path=path)
        keys = sections[name]
        if keys is None:
            continue
        for key in value:
            if key not in keys:
                raise unknown_key(path, name, key, keys, sections)
    for item in required:
        section, key = (item, None) if isinstance(item, str) else item
        table = doc.get(section)
        if not isinstance(table, dict):
            raise InputError(f"[{section}]: missing required section", path=path)
        if key is not None and key not in table:
            raise missing_key(path, section, key)
    return doc


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class Table:
    """Typed access to one section of a TOML file; refuses the keys it did not read.

    Parameters
    ----------
    table : dict or None
        The section's content (``None``: an absent optional section, read as empty).
    name : str
        Section name, for the messages.
    path : str or os.PathLike, optional
        The file, for the messages.
    known : iterable of str, optional
        Every key of this section (listed in the unknown-key message; default: the keys
        read before :meth:`finish`).
    sections : mapping, optional
        ``{section: keys}`` of the whole file (to say where a misplaced key belongs).

    Notes
    -----
    Each accessor takes ``unit``, the expected unit or range as the user should read
    it (``"mm > 0"``, ``"deg in [-85, 85]"``); it appears in every message about that key.
    ``default=REQUIRED`` makes the key required.
    """

    def __init__(self, table, name, path=None, known=None, sections=None):
        self.path = None if path is None else str(path)
        self.name = name
        if table is None:
            table = {}
        if not isinstance(table, dict):
            raise InputError(f"[{name}]: expected a section (table), got "
                             f"{type(table).__name__} {table!r}", path=self.path)
        self.table = table
        self.used = set()
        self.known = None if known is None else set(known)
        self.sections = sections

    # -- messages
    def error(self, key, message, unit=None):
        """An :class:`InputError` ``"[section] key: message (expected unit)"``."""
        tail = f" (expected {unit})" if unit else ""
        return InputError(f"{_where(self.name, key)}: {message}{tail}", path=self.path)

    def _declare(self, key):
        if self.known is not None and key not in self.known:     # a reader's bug
            raise KeyError(f"[{self.name}] {key} is read but not among the declared keys")
        self.used.add(key)

    def has(self, key):
        """Whether the section holds ``key`` (marks it as known)."""
        self._declare(key)
        return key in self.table

    def _get(self, key, default, unit):
        self._declare(key)
        if key in self.table:
            return self.table[key], True
        if default is REQUIRED:
            raise missing_key(self.path, self.name, key, unit)
        return default, False

    # -- accessors
    def raw(self, key, default=REQUIRED, unit=""):
        """The value as parsed by TOML (no check)."""
        return self._get(key, default, unit)[0]

    def number(self, key, default=REQUIRED, unit="", lo=None, hi=None, lo_open=False,
               integer=False):
        """A finite number (int or float), optionally within ``[lo, hi]``."""
        v, given = self._get(key, default, unit)
        if not given:
            return v
        if not _is_number(v):
            raise self.error(key, f"expected a number, got {v!r}", unit)
        if integer and not float(v).is_integer():
            raise self.error(key, f"expected an integer, got {v!r}", unit)
        if not math.isfinite(v):
            raise self.error(key, f"must be finite, got {v!r}", unit)
        if lo is not None and (v <= lo if lo_open else v < lo):
            raise self.error(key, f"must be {'>' if lo_open else '>='} {lo}, got {v!r}", unit)
        if hi is not None and v > hi:
            raise self.error(key, f"must be <= {hi}, got {v!r}", unit)
        return int(v) if integer else float(v)

    def numbers(self, key, default=(), unit="", length=None, lo=None, scalar=True, bound=None):
        """A list of finite numbers as a tuple of floats (a single number is a list of
        one when ``scalar``); ``length`` fixes the count, ``lo`` the smallest value and
        ``bound`` the largest magnitude (e.g. 100 m of a lever arm)."""
        v, given = self._get(key, default, unit)
        if not given:
            return v if v is None else tuple(v)
        if scalar and _is_number(v):
            v = [v]
        if not isinstance(v, list) or not all(_is_number(x) and math.isfinite(x) for x in v):
            what = f"{length} finite numbers" if length else "a list of finite numbers"
            raise self.error(key, f"expected {what}, got {v!r}", unit)
        if length is not None and len(v) != length:
            raise self.error(key, f"expected {length} numbers, got {len(v)}", unit)
        if lo is not None and any(x < lo for x in v):
            raise self.error(key, f"values must be >= {lo}, got {v!r}", unit)
        if bound is not None and any(abs(x) > bound for x in v):
            big = next(float(x) for x in v if abs(x) > bound)
            raise self.error(key, f"{big:g} is beyond +-{bound:g} (a typo or another unit?), "
                             f"got {v!r}", unit)
        return tuple(float(x) for x in v)

    def matrix(self, key, default=REQUIRED, shape=(3, 3), unit=""):
        """A list of rows of finite numbers, as a tuple of tuples of floats."""
        v, given = self._get(key, default, unit)
        if not given:
            return v
        rows, cols = shape
        if (not isinstance(v, list) or len(v) != rows
                or not all(isinstance(r, list) and len(r) == cols
                           and all(_is_number(x) and math.isfinite(x) for x in r) for r in v)):
            raise self.error(key, f"expected {rows} rows of {cols} finite numbers, got {v!r}",
                             unit)
        return tuple(tuple(float(x) for x in r) for r in v)

    def boolean(self, key, default=REQUIRED):
        """``true`` or ``false``."""
        v, _ = self._get(key, default, "true or false")
        if not isinstance(v, bool):
            raise self.error(key, f"expected true or false, got {v!r}")
        return v

    def string(self, key, default=REQUIRED, unit="a string"):
        """A string."""
        v, given = self._get(key, default, unit)
        if given and not isinstance(v, str):
            raise self.error(key, f"expected a string, got {v!r}", unit)
        return v

    def choice(self, key, default, options):
        """One of ``options``."""
        v, given = self._get(key, default, "one of " + ", ".join(map(repr, options)))
        if v not in options or isinstance(v, bool):
            raise self.error(key, f"expected one of {', '.join(map(repr, options))}, got {v!r}")
        return v

    def either(self, a, b):
        """Refuse a section that gives both ``a`` and ``b``."""
        self._declare(a)
        self._declare(b)
        if a in self.table and b in self.table:
            raise self.error(b, f"give either {a} or {b}, not both")

    def finish(self):
        """Raise on the first key of the section that was not read (sorted by name)."""
        known = self.known if self.known is not None else set()
        known = known | self.used
        unknown = sorted(set(self.table) - known)
        if unknown:
            raise unknown_key(self.path, self.name, unknown[0], known, self.sections)
