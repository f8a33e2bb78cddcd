"""Text files for the readers: bytes with a NUL end, UTF-8 text, TOML, and numeric
tables read in blocks of whole lines with line-numbered errors.

:func:`read_table` and :func:`iter_table` read a numeric table (rules of
:func:`ins.common.textparse.parse_table`) with the memory of one block of text; any error is an
:class:`~ins.common.errors.InputError` naming the file and the line.  :func:`read_text` and
:func:`read_toml` read small text files, refusing binary data with the line of the first
bad byte.
"""
import os

import numpy as np

from ins.common.errors import InputError
from ins.common.textparse import (
    COLUMN_COUNT,
    NO_DATA,
    OK,
    TOO_FEW_COLUMNS,
    TOO_MANY_COLUMNS,
    parse_table,
    table_error_message,
)

__all__ = ["file_buffer", "read_text", "read_toml", "read_table", "iter_table", "BLOCK_BYTES"]

_NL, _SP = 10, 32


def file_buffer(path):
    """Bytes of the file at ``path`` as a uint8 array with a NUL byte appended.

    A UTF-8 byte-order mark at the start is blanked (in the returned copy only).
    The file is opened read-only and never modified.
    """
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        buf = np.empty(size + 1, np.uint8)
        view = memoryview(buf)
        got = 0
        while got < size:
            k = f.readinto(view[got:size])
            if not k:
                break
            got += k
        extra = f.read()          # the file grew while being read
    if extra:
        buf = np.concatenate([buf[:got], np.frombuffer(extra, np.uint8), [0]]).astype(np.uint8)
    else:
        buf = buf[:got + 1]
        buf[got] = 0
    if buf.size >= 4 and buf[0] == 0xEF and buf[1] == 0xBB and buf[2] == 0xBF:
        buf[:3] = _SP
    return buf


def read_text(path, expected="text"):
    """The whole text of a (small) text file, decoded as UTF-8 (a BOM is dropped).

    For the line-oriented readers of CSV and TOML files, which would otherwise stop
    with a ``UnicodeDecodeError`` on a binary file.  Line ends are left as they are.

    Parameters
    ----------
    expected : str
        What the file should hold, for the message (e.g. ``"a TOML camera file"``).

    Raises
    ------
    InputError
        When the bytes are not UTF-8 or hold a NUL byte (binary data), naming the file
        and the line of the first bad byte.
    """
    path_s = os.fspath(path)
    with open(path_s, "rb") as f:
        data = f.read()
    try:
        text = data.decode("utf-8-sig")
        bad = text.find("\x00")
        if bad >= 0:
            raise UnicodeDecodeError("utf-8", data, bad, bad + 1, "NUL byte")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"binary data, not UTF-8 text (byte 0x{data[exc.start]:02x} at "
                         f"offset {exc.start}); expected {expected}", path=path_s,
                         line=line) from None
    return text


def read_toml(path, expected="a TOML file"):
    """A TOML file as a dict; :class:`InputError` naming the file for binary data or
    invalid TOML (the TOML parser's message gives the line and column)."""
    import tomllib
    text = read_text(path, expected)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}; expected {expected}",
                         path=os.fspath(path)) from None


def _last_newline(buf, total):
    """Index of the last newline byte in ``buf[:total]`` (-1 when none)."""
    stop = total
    while stop > 0:
        start = max(0, stop - 65536)
        hit = np.flatnonzero(buf[start:stop] == _NL)
        if hit.size:
            return start + int(hit[-1])
        stop = start
    return -1


def _count_lines(path, block_bytes):
    """Number of lines in the file (newlines + 1): an upper bound of its data rows."""
    buf = np.empty(max(int(block_bytes), 16), np.uint8)
    count = 1
    with open(path, "rb") as f:
        while True:
            got = f.readinto(memoryview(buf))
            if not got:
                return count
            count += int(np.count_nonzero(buf[:got] == _NL))


#: Bytes read and parsed at a time by :func:`read_table` (bounds its memory).
BLOCK_BYTES = 1 << 24


def read_table(path, ncols_min=1, ncols_max=1 << 30, skip_header_lines=0, column_names=None,
               hint=None, block_bytes=BLOCK_BYTES):
    """Read a numeric text table from a file, in blocks of whole lines.

    Memory: the table plus one block of text (``block_bytes``, 16 MiB by default), not
    the whole file's text.  A first pass counts the lines to size the table.

    Parameters
    ----------
    hint : str, optional
        Appended in parentheses to column-count errors (e.g. the expected layout).

    Returns
    -------
    values : ndarray, shape (nrows, width), float64
    row_line : ndarray, shape (nrows,), int64
        1-based line number of each row in the file.

    Raises
    ------
    InputError
        On any of the :func:`parse_table` errors, naming the file and line.
    """
    max_rows = _count_lines(path, block_bytes)
    table = row_lines = None
    nrows = 0
    for values, lines in iter_table(path, ncols_min, ncols_max, column_names, hint,
                                    block_bytes, skip_header_lines):
        if table is None:
            table = np.empty((max_rows, values.shape[1]))
            row_lines = np.empty(max_rows, np.int64)
        m = len(values)
        if nrows + m > max_rows:                     # the file grew meanwhile
            raise InputError("the file changed while being read", path=os.fspath(path))
        table[nrows:nrows + m] = values
        row_lines[nrows:nrows + m] = lines
        nrows += m
    if table is None:
        raise InputError("no data lines (the file is empty or holds only blank and comment "
                         "lines)", path=os.fspath(path))
    if nrows < 0.8 * max_rows:
        return table[:nrows].copy(), row_lines[:nrows].copy()
    return table[:nrows], row_lines[:nrows]


def iter_table(path, ncols_min=1, ncols_max=1 << 30, column_names=None, hint=None,
               block_bytes=BLOCK_BYTES, skip_header_lines=0):
    """Read a numeric text table block by block (bounded memory: one block of text).

    Same rules and errors as :func:`read_table`, but the
    rows are yielded as they are parsed, so a file of any length is read with the memory
    of one block.  The parsing kernel releases the GIL (a reader thread can run beside
    numerical work).

    Yields
    ------
    values : ndarray, shape (nrows, width), float64
        The rows of one block of whole lines (at least one row).
    row_line : ndarray, shape (nrows,), int64
        1-based line number of each row in the file.
    """
    lo, hi = int(ncols_min), int(ncols_max)
    line_offset = first_line = 0
    skip = int(skip_header_lines)
    buf = np.empty(max(int(block_bytes), 16) + 1, np.uint8)
    have = 0
    first_block = True
    seen = False
    with open(path, "rb") as f:
        while True:
            if have == buf.size - 1:                         # a line longer than buf
                grown = np.empty(2 * buf.size, np.uint8)
                grown[:have] = buf[:have]
                buf = grown
            got = f.readinto(memoryview(buf)[have:buf.size - 1])
            total = have + got
            if total == 0:
                break
            cut = _last_newline(buf, total) + 1 if got else total
            if got and cut == 0:
                have = total
                continue
            if first_block and cut >= 3 and buf[0] == 0xEF and buf[1] == 0xBB and buf[2] == 0xBF:
                buf[:3] = _SP
            first_block = False
            saved = buf[cut]
            buf[cut] = 0
            block = buf[:cut + 1]
            res = parse_table(block, lo, hi, skip)
            nl = int(np.count_nonzero(block[:cut] == _NL))
            skip = max(0, skip - nl)
            if res.status == OK:
                if not seen:
                    first_line = res.first_line + line_offset
                seen = True
                lo = hi = res.width           # later blocks must keep the first width
                yield res.values, res.row_line + line_offset
            elif res.status != NO_DATA:
                msg = table_error_message(res, block, lo, hi, column_names)
                if res.status in (TOO_FEW_COLUMNS, TOO_MANY_COLUMNS) and seen:
                    msg = (f"{res.err_col} columns, expected {lo} as on the first data "
                           f"line (line {first_line})")
                if hint and (res.status in (TOO_FEW_COLUMNS, TOO_MANY_COLUMNS, COLUMN_COUNT)
                             or msg.startswith("binary data")):
                    msg += f" ({hint})"
                raise InputError(msg, path=os.fspath(path),
                                 line=(res.err_line + line_offset) if res.err_line else None)
            buf[cut] = saved
            line_offset += nl
            have = total - cut
            if have:
                buf[:have] = buf[cut:total].copy()
            if not got:
                break
    if not seen:
        raise InputError("no data lines (the file is empty or holds only blank and comment "
                         "lines)", path=os.fspath(path))
