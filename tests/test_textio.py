"""Tests of the text I/O modules (ins.common.textparse, ins.common.textformat, ins.common.textfiles, ins.common.exactdecimal):
exact parsing against np.loadtxt / float(), formatting against '%'."""
import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ins.common import exactdecimal, textfiles, textformat, textparse
from ins.common.errors import InputError

ENGINES = ["compiled", "python"]


def as_buf(text):
    if isinstance(text, str):
        text = text.encode()
    return np.frombuffer(text + b"\0", np.uint8)


def bits(a):
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def savetxt_bytes(table, fmt, delimiter=" ", newline="\n"):
    f = io.BytesIO()
    np.savetxt(f, table, fmt=fmt, delimiter=delimiter, newline=newline)
    return f.getvalue()


# ----------------------------------------------------------------------------- parsing

@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("fmt", ["%.17e", "%.6f", "%.9g", "%r"])
def test_parse_random_tables_bit_identical_to_loadtxt(engine, fmt):
    rng = np.random.default_rng(7)
    n, m = (3000 if engine == "compiled" else 400), 7
    table = rng.standard_normal((n, m)) * 10.0 ** rng.integers(-12, 12, (n, m))
    if fmt == "%.6f":
        table = np.clip(table, -1e9, 1e9)
    text = ("\n".join(" ".join(fmt % v for v in row) for row in table.tolist()) + "\n").encode()
    ref = np.loadtxt(io.BytesIO(text))
    res = textparse.parse_table(as_buf(text), 7, 7, engine=engine)
    assert res.status == textparse.OK
    assert res.values.shape == (n, m)
    np.testing.assert_array_equal(bits(res.values), bits(ref))
    np.testing.assert_array_equal(res.row_line, np.arange(1, n + 1))


def test_parse_numbers_exactly_like_float():
    """The in-kernel conversion (not strtod) on many digit counts, exponents, near ties."""
    rng = np.random.default_rng(11)
    x = rng.standard_normal(20000) * 10.0 ** rng.integers(-300, 300, 20000)
    strings = ["%.17e" % v for v in x] + ["%.15g" % v for v in x[:5000]]
    strings += [repr(float(v)) for v in x[:5000]] + ["%.19e" % v for v in x[:2000]]
    # random mantissas of 1..18 digits, exponents over the whole range
    digits = rng.integers(0, 10, (20000, 18))
    nd = rng.integers(1, 19, 20000)
    ex = rng.integers(-330, 320, 20000)
    for row, k, e in zip(digits, nd, ex):
        m = "".join(map(str, row[:k]))
        strings.append(f"{m[:1]}.{m[1:]}e{e}")
        strings.append(f"-{m}e{e}")
    # decimal numbers just around the midpoint of two doubles (18 digits)
    from decimal import Decimal
    for v in x[:3000]:
        a = Decimal(float(abs(v)))
        b = Decimal(float(np.nextafter(abs(v), np.inf)))
        strings.append(format((a + b) / 2, ".17e"))
    # decimals exactly halfway between two doubles (ties to even), e.g. 2**52 + 0.5:
    # only the ambiguity check of the in-kernel conversion gets these right
    odd = rng.integers(2 ** 53, 2 ** 54, 4000) | 1
    strings += [f"{m // 2}.5" for m in odd[:2000].tolist()]
    strings += [f"{m // 4}.{25 if m % 4 == 1 else 75}" for m in odd[2000:].tolist()]
    strings += [f"-{m // 2}.50e0" for m in odd[:500].tolist()]
    # exact ties between doubles, integers and special forms
    strings += ["9007199254740993", "9007199254740995", "18014398509481989", "1e23", "8e23",
                "4.9406564584124654e-324", "2.2250738585072011e-308", "1.7976931348623157e308",
                "1.7976931348623159e308", "1e-400", "1e400", "-0.0", "0e5", ".5", "5.", "+.5e-3",
                "000000000000000000000123.456", "0.000000000000000000000000000001",
                "123456789012345678901234567890", "inf", "-Infinity", "NaN", "+nan",
                "1" * 40 + "e-20"]
    text = "\n".join(strings) + "\n"
    res = textparse.parse_table(as_buf(text), 1, 1)
    assert res.status == textparse.OK, (res.status, res.err_line)
    ref = np.array([float(s) for s in strings])
    got = res.values[:, 0]
    fin = np.isfinite(ref)
    np.testing.assert_array_equal(bits(got[fin]), bits(ref[fin]))
    np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
    np.testing.assert_array_equal(got[np.isinf(ref)], ref[np.isinf(ref)])


def test_fast_conversion_defers_exact_ties_to_strtod():
    hi, lo = exactdecimal.pow10_table()
    # 4503599627370496.5 is halfway between two doubles: the double-double product
    # cannot decide, so the kernel must hand it to strtod
    v, ok = textparse._fast_decimal(np.int64(45035996273704965), -1, hi, lo)
    assert not ok
    v, ok = textparse._fast_decimal(np.int64(663487338564133501), -22, hi, lo)
    assert ok and v == 6.63487338564133501e-05
    v, ok = textparse._fast_decimal(np.int64(300000005), -3, hi, lo)       # Clinger's exact path
    assert ok and v == 300000.005


def test_two_prod_is_exact():
    from fractions import Fraction
    rng = np.random.default_rng(11)
    for a, b in (rng.standard_normal((2000, 2)) * 10.0 ** rng.integers(-100, 100, (2000, 2))):
        p, e = exactdecimal.two_prod(a, b)
        assert p == a * b and Fraction(p) + Fraction(e) == Fraction(a) * Fraction(b)


@pytest.mark.parametrize("engine", ENGINES)
def test_parse_layout_variants(engine):
    text = (b"# comment line\r\n"
            b"\r\n"
            b"1 2 3\r\n"
            b"   \t \n"
            b"% another comment\n"
            b"4,5,6\n"
            b"7\t8\t9   # trailing comment\n"
            b"10 , 11 ,\t12\n"
            b"  13,14 15\r\n"
            b"16 17 18")                         # no final newline
    res = textparse.parse_table(as_buf(text), 3, 3, engine=engine)
    assert res.status == textparse.OK
    np.testing.assert_array_equal(res.values, np.arange(1, 19, dtype=float).reshape(6, 3))
    np.testing.assert_array_equal(res.row_line, [3, 6, 7, 8, 9, 10])
    assert res.first_line == 3 and res.width == 3


@pytest.mark.parametrize("engine", ENGINES)
def test_parse_skip_header_and_nan_inf(engine):
    text = b"time_s,a,b\nnot numbers at all\n1,nan,inf\n2,-inf,3\n"
    res = textparse.parse_table(as_buf(text), 3, 3, skip_header_lines=2, engine=engine)
    assert res.status == textparse.OK
    assert np.isnan(res.values[0, 1]) and res.values[0, 2] == np.inf
    assert res.values[1, 1] == -np.inf
    np.testing.assert_array_equal(res.row_line, [3, 4])


BAD_CASES = [
    # text, ncols_min, ncols_max, status, line, col
    ("", 1, 9, textparse.NO_DATA, 0, 0),
    ("# only\n\n   \n% comments\n", 1, 9, textparse.NO_DATA, 0, 0),
    ("# c\n1 2\n", 3, 9, textparse.TOO_FEW_COLUMNS, 2, 2),
    ("1 2 3 4\n", 1, 3, textparse.TOO_MANY_COLUMNS, 1, 4),
    ("1 2 3\n4 5 6\n\n# x\n7 8\n", 3, 3, textparse.COLUMN_COUNT, 5, 2),
    ("1 2 3\n4 5 6 7\n", 3, 9, textparse.COLUMN_COUNT, 2, 4),
    ("1 2 3\r\n4 5 6\r\n7 1.2.3 9\r\n", 3, 3, textparse.BAD_NUMBER, 3, 2),
    ("1 2 3\n4 abc 6\n", 3, 3, textparse.BAD_NUMBER, 2, 2),
    ("1 2 3\n4 5 1e\n", 3, 3, textparse.BAD_NUMBER, 2, 3),
    ("1 2 3\n4 5 0x1p3\n", 3, 3, textparse.BAD_NUMBER, 2, 3),
    ("1 2 3\n4 5 nan(1)\n", 3, 3, textparse.BAD_NUMBER, 2, 3),
    ("1 2 3\n4 5 6#c\n", 3, 3, textparse.BAD_NUMBER, 2, 3),
    ("1 2 3\n4 5 1_0\n", 3, 3, textparse.BAD_NUMBER, 2, 3),
    ("1 2 3\n4 \v5 6\n", 3, 3, textparse.BAD_NUMBER, 2, 2),
    ("1 2 3\n4 5 6\x00\n", 3, 3, textparse.BAD_NUMBER, 2, 3),
    ("1 2 3\n4 \"5\" 6\n", 3, 3, textparse.BAD_NUMBER, 2, 2),
    ("1 2 3\n4 - 6\n", 3, 3, textparse.BAD_NUMBER, 2, 2),
    ("1 2 3\n4 infinit 6\n", 3, 3, textparse.BAD_NUMBER, 2, 2),
    ("1,2,3\n4,,6\n", 3, 3, textparse.EMPTY_FIELD, 2, 2),
    ("1,2,3\n4,5,6,\n", 3, 3, textparse.EMPTY_FIELD, 2, 4),
    ("1,2,3\n,4,5,6\n", 3, 3, textparse.EMPTY_FIELD, 2, 1),
    ("1,2,3\n4,5, # c\n", 3, 3, textparse.EMPTY_FIELD, 2, 3),
    ("1 2 3\n4 5 6\n7 8 9x", 3, 3, textparse.BAD_NUMBER, 3, 3),
]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("text,nmin,nmax,status,line,col", BAD_CASES)
def test_parse_errors(engine, text, nmin, nmax, status, line, col):
    res = textparse.parse_table(as_buf(text), nmin, nmax, engine=engine)
    assert (res.status, res.err_line, res.err_col) == (status, line, col)
    assert res.values.shape[0] == 0


@pytest.mark.parametrize("text,nmin,nmax,status,line,col", BAD_CASES)
def test_engines_agree_on_errors(text, nmin, nmax, status, line, col):
    a = textparse.parse_table(as_buf(text), nmin, nmax, engine="compiled")
    b = textparse.parse_table(as_buf(text), nmin, nmax, engine="python")
    assert a[1:4] == b[1:4] and a[5:] == b[5:]


def test_engines_agree_on_a_messy_file():
    rng = np.random.default_rng(3)
    lines = []
    for k in range(500):
        r = rng.random()
        if r < 0.05:
            lines.append("# comment %d" % k)
        elif r < 0.1:
            lines.append("  \t")
        else:
            vals = rng.standard_normal(4) * 10.0 ** rng.integers(-5, 5, 4)
            sep = rng.choice([" ", "\t", ",", " , ", "  "])
            lines.append(sep.join("%.*g" % (int(rng.integers(1, 18)), v) for v in vals)
                         + rng.choice(["", "\r", " # x"]))
    text = "\n".join(lines)
    a = textparse.parse_table(as_buf(text), 4, 4, engine="compiled")
    b = textparse.parse_table(as_buf(text), 4, 4, engine="python")
    assert a.status == b.status == textparse.OK
    np.testing.assert_array_equal(bits(a.values), bits(b.values))
    np.testing.assert_array_equal(a.row_line, b.row_line)


def test_error_messages_name_field_and_text():
    buf = as_buf("1 2 3\n4 1.2.3 6\n")
    res = textparse.parse_table(buf, 3, 3)
    msg = textparse.table_error_message(res, buf, 3, 3, ["t", "a", "b"])
    assert "field 2 (a)" in msg and "'1.2.3'" in msg
    buf = as_buf("1 2 3\n4 5\n")
    res = textparse.parse_table(buf, 3, 3)
    assert "2 columns, expected 3" in textparse.table_error_message(res, buf, 3, 3)


def test_read_table_raises_input_error_with_path_and_line(tmp_path):
    p = tmp_path / "table.txt"
    p.write_bytes(b"# header\n1 2\n3 x\n")
    with pytest.raises(InputError) as e:
        textfiles.read_table(p, 2, 2)
    assert e.value.line == 3 and e.value.path == str(p)
    assert str(e.value).startswith(f"{p}:3: ")
    p.write_bytes(b"")
    with pytest.raises(InputError, match="no data lines") as e:
        textfiles.read_table(p, 2, 2)
    assert e.value.line is None and str(e.value).startswith(f"{p}: ")


def test_file_buffer_bom_and_nul(tmp_path):
    p = tmp_path / "bom.txt"
    p.write_bytes(b"\xef\xbb\xbf1 2\n3 4\n")
    buf = textfiles.file_buffer(p)
    assert buf[-1] == 0 and buf.size == p.stat().st_size + 1
    values, lines = textfiles.read_table(p, 2, 2)
    np.testing.assert_array_equal(values, [[1, 2], [3, 4]])
    assert p.read_bytes().startswith(b"\xef\xbb\xbf")    # the file itself is untouched


def test_parse_does_not_modify_buffer():
    buf = as_buf("1 2 3\n4 5 6\n")
    before = buf.copy()
    textparse.parse_table(buf, 3, 3)
    np.testing.assert_array_equal(buf, before)
    with pytest.raises(ValueError):
        textparse.parse_table(np.frombuffer(b"1 2", np.uint8), 1, 3)


# ----------------------------------------------------------------------------- formatting

def test_format_fixed_matches_percent_f_on_random_data():
    rng = np.random.default_rng(5)
    n = 20000
    total = same = 0
    for d in range(0, 16):
        x = rng.standard_normal(n) * 10.0 ** rng.integers(-d - 2, 17 - d, n)
        out = textformat.format_fixed(x[:, None], [d]).tobytes().decode().split("\n")[:-1]
        ref = ["%.*f" % (d, v) for v in x]
        same += sum(a == b for a, b in zip(out, ref))
        total += n
        back = np.array([float(s) for s in out])
        # at most half a unit of the last place (+ 1e-15 relative) from the exact value
        tol = 0.5 * 10.0 ** -d * (1 + 1e-12) + 1e-15 * np.abs(x)
        assert np.all(np.abs(back - x) <= tol)
    # measured: 100 % identical (exact products, ties to even as Python does)
    assert same / total >= 0.9999, same / total
    assert same == total


def test_format_fixed_19_to_22_decimals_match_percent_f():
    """Decimals 19..22 (10**d beyond int64): the numba kernel read 10**d past the end of
    its integer table there and wrote e.g. '1.1229999999999997613' for 0.123."""
    rng = np.random.default_rng(7)
    for d in range(17, 23):
        x = rng.standard_normal(3000) * 10.0 ** rng.integers(-d, 0, 3000)
        x = np.where(np.abs(x) * 10.0 ** d < 8.9e18, x, 0.5 * 10.0 ** -d)
        x[:4] = np.array([0.123, -0.5, 3.25e-5, -0.0]) * 10.0 ** min(0, 18 - d)
        out = textformat.format_fixed(x[:, None], [d]).tobytes().decode().split("\n")[:-1]
        assert out == ["%.*f" % (d, v) for v in x], d


def test_kernels_release_the_gil():
    """Parsing and formatting run without the GIL (the reader thread of ins process runs
    beside the filter): a Python thread counts on while the kernels run.

    With a switch interval of 0.5 s the main thread keeps the GIL through its own Python
    code, so the counting thread can run during ``work()`` only if a kernel releases it.
    """
    import sys
    import threading
    import time
    rng = np.random.default_rng(3)
    table = rng.standard_normal((200000, 4))
    buf = np.append(textformat.format_table(table, [9, 9, 9, 9]), np.uint8(0))
    interval = sys.getswitchinterval()
    sys.setswitchinterval(0.5)
    try:
        for work in (lambda: textparse.parse_table(buf, 4, 4),
                     lambda: textformat.format_table(table, [9, 9, 9, 9])):
            count = [0]
            stop = threading.Event()

            def spin():
                while not stop.is_set():
                    count[0] += 1
            th = threading.Thread(target=spin)
            th.start()
            time.sleep(0.01)              # the main thread takes the GIL back after this
            before = count[0]
            work()                        # tens of ms, well within the interval
            during = count[0] - before
            stop.set()
            th.join()
            assert during > 100, during
    finally:
        sys.setswitchinterval(interval)


def test_format_fixed_table_and_ties():
    vals = np.array([[0.5, 1.5, 2.5, -0.0, -1e-9, 1.005, 0.125, 123.456, -2.675, 1e15]])
    dec = [0, 0, 0, 3, 3, 2, 2, 0, 2, 1]
    out = textformat.format_fixed(vals, dec).tobytes().decode()
    assert out == " ".join("%.*f" % (d, v) for d, v in zip(dec, vals[0])) + "\n"
    assert out == "0 2 2 -0.000 -0.000 1.00 0.12 123 -2.67 1000000000000000.0\n"
    rng = np.random.default_rng(1)
    table = np.column_stack([np.arange(1000.0), 300000 + rng.random(1000),
                             rng.standard_normal((1000, 3)) * 100])
    dec = [0, 6, 12, 3, 9]
    out = textformat.format_fixed(table, np.array(dec)).tobytes().decode()
    ref = "".join(" ".join("%.*f" % (d, v) for d, v in zip(dec, row)) + "\n"
                  for row in table.tolist())
    assert out == ref
    csv = textformat.format_fixed(table[:2], dec, sep=",").tobytes().decode()
    assert csv == ref.replace(" ", ",").split("\n", 2)[0] + "\n" + \
        ref.replace(" ", ",").split("\n", 2)[1] + "\n"


def test_format_fixed_errors():
    with pytest.raises(ValueError, match="non-finite"):
        textformat.format_fixed(np.array([[1.0, np.nan]]), [1, 1])
    with pytest.raises(ValueError, match="row 1, column 0"):
        textformat.format_fixed(np.array([[1.0], [np.inf]]), [1])
    with pytest.raises(ValueError, match="too large"):
        textformat.format_fixed(np.array([[1e12]]), [7])
    with pytest.raises(ValueError, match="decimals"):
        textformat.format_fixed(np.array([[1.0]]), [-1])
    with pytest.raises(ValueError, match="shape"):
        textformat.format_fixed(np.ones((2, 3)), [1, 2])
    assert textformat.format_fixed(np.empty((0, 3)), [1, 1, 1]).size == 0


def test_format_table_scientific_matches_percent_e():
    rng = np.random.default_rng(9)
    x = rng.standard_normal(50000) * 10.0 ** rng.integers(-300, 300, 50000)
    x[:6] = [0.0, -0.0, 1.0, 9.999999999999999e22, 5e-324, 1.7976931348623157e308]
    out = textformat.format_table(x[:, None], [-1]).tobytes().decode().split("\n")[:-1]
    assert out == ["%.17e" % v for v in x]
    back = np.array([float(s) for s in out])
    np.testing.assert_array_equal(bits(back), bits(x))


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2, max_side=6),
                  elements=st.floats(allow_nan=False, allow_infinity=False, width=64)))
def test_format_table_roundtrip_property(table):
    text = textformat.format_table(table, [-1] * table.shape[1])
    res = textparse.parse_table(np.append(text, np.uint8(0)), 1, 99)
    assert res.status == textparse.OK
    np.testing.assert_array_equal(bits(res.values), bits(table))


def test_roundtrip_decimals():
    assert textformat.roundtrip_decimals(300000 + np.arange(2000) * 0.005) == 3
    assert textformat.roundtrip_decimals([0.25, 1.5]) == 2
    assert textformat.roundtrip_decimals([1.0, 2.0]) == 0
    assert textformat.roundtrip_decimals([1.0, 2.0], min_decimals=3) == 3
    assert textformat.roundtrip_decimals([9e15], min_decimals=3) == -1      # 9e18 > 2**53
    assert textformat.roundtrip_decimals([1 / 3]) == -1
    assert textformat.roundtrip_decimals([1e17]) == -1          # beyond 2**53: not claimed
    assert textformat.roundtrip_decimals([np.nan]) == -1
    t = 456300.0 + np.arange(100) * 0.01
    d = textformat.roundtrip_decimals(t)
    text = textformat.format_fixed(t[:, None], [d])
    back = textparse.parse_table(np.append(text, np.uint8(0)), 1, 1).values[:, 0]
    np.testing.assert_array_equal(bits(back), bits(t))


def test_is_number():
    assert textparse.is_number("1.5e-3") and textparse.is_number(b"-inf") and textparse.is_number("nan")
    assert not textparse.is_number("time_s") and not textparse.is_number("1.2.3") and not textparse.is_number("")


# --- read_table in blocks: the same table and line numbers whatever the block size ------

def _block_file(tmp_path, crlf=False):
    rng = np.random.default_rng(5)
    rows = rng.normal(size=(300, 7)) * 10.0 ** rng.integers(-8, 4, size=(300, 7))
    lines = ["# header comment", "", "  "]
    for i, r in enumerate(rows):
        lines.append(" ".join(f"{v:.17e}" for v in r))
        if i % 37 == 5:
            lines += ["# a comment in the middle", ""]
    text = ("\r\n" if crlf else "\n").join(lines)          # no newline after the last line
    p = tmp_path / "blocks.txt"
    p.write_bytes(text.encode())
    return p, rows, lines


@pytest.mark.parametrize("block_bytes", [1, 50, 200, 4096, 1 << 24])
@pytest.mark.parametrize("crlf", [False, True])
def test_read_table_blocks_same_result(tmp_path, block_bytes, crlf):
    p, rows, lines = _block_file(tmp_path, crlf)
    values, row_line = textfiles.read_table(p, 7, 7, block_bytes=block_bytes)
    np.testing.assert_array_equal(values, rows)
    expect = [i + 1 for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")]
    np.testing.assert_array_equal(row_line, expect)


@pytest.mark.parametrize("block_bytes", [64, 333, 1 << 24])
def test_read_table_blocks_error_lines(tmp_path, block_bytes):
    p, rows, lines = _block_file(tmp_path)
    for k, bad in [(250, lines[250] + " 1.0"), (251, " ".join(lines[251].split()[:5])),
                   (190, lines[190].replace("e", "x", 1))]:
        mod = list(lines)
        mod[k] = bad
        q = tmp_path / "bad.txt"
        q.write_text("\n".join(mod) + "\n")
        with pytest.raises(InputError) as exc:
            textfiles.read_table(q, 7, 64, block_bytes=block_bytes)
        assert exc.value.line == k + 1, str(exc.value)
    empty = tmp_path / "comments.txt"
    empty.write_text("# only\n\n# comments\n" * 50)
    with pytest.raises(InputError, match="no data lines"):
        textfiles.read_table(empty, 7, 7, block_bytes=block_bytes)


def test_read_table_blocks_skip_header(tmp_path):
    p = tmp_path / "h.csv"
    p.write_text("time_s,a,b\n" + "".join(f"{i},{2 * i},{3 * i}\n" for i in range(100)))
    values, row_line = textfiles.read_table(p, 3, 3, skip_header_lines=1, block_bytes=7)
    np.testing.assert_array_equal(values[:, 1], 2.0 * np.arange(100))
    assert row_line[0] == 2 and row_line[-1] == 101
