"""Text I/O: our numba table reader/formatter against the well-kept libraries (issue 13).

Reads the shared benchmark's IMU log (302 001 lines x 7 columns, 48 MB of text, 18-digit
numbers) and GNSS log with:
- ours: ``ins.textfiles.read_table`` (whole table, blocks of 16 MiB) and ``iter_table``
  (streaming);
- pandas' C engine (``float_precision="round_trip"`` before pandas 3, the default
  since), whole and in chunks;
- ``pyarrow.csv`` (whole, and its streaming reader);
- ``numpy.loadtxt`` (C implementation since numpy 1.23).
For each: the warm wall time (best of N), whether every value is bit-identical to the
correctly rounded value (Python's ``float()`` on the same text), and, on a copy of the log
with one bad field at 80 % of the file, the time to fail and whether the message names the
line.  Writing: our fixed-point formatter against ``numpy.savetxt`` and pandas ``to_csv``
with the same decimals.

Usage: python bench/bench_textio.py [--repeat N]   (needs the bench extras: pandas, pyarrow)
"""
import argparse
import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from benchdata import ensure_bench_data  # noqa: E402


def best_of(fn, repeat):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def exact_reference(path, rows=20000):
    """float() of the text of the first ``rows`` lines: the correctly rounded values."""
    ref = []
    with open(path) as f:
        for i, line in enumerate(f):
            if i >= rows:
                break
            ref.append([float(x) for x in line.split()])
    return np.array(ref)


def readers(ncols):
    from ins import textfiles
    import pandas as pd
    import pyarrow.csv as pacsv

    names = [f"c{i}" for i in range(ncols)]

    def ours(p):
        return textfiles.read_table(p, ncols, ncols)[0]

    def ours_stream(p):
        return np.concatenate([v for v, _ in textfiles.iter_table(p, ncols, ncols)])

    exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}

    def pandas_c(p):          # pandas >= 3: exact by default (float_precision deprecated)
        return pd.read_csv(p, sep=" ", header=None, names=names, engine="c",
                           dtype=np.float64, **exact).to_numpy()

    def pandas_chunks(p):
        with pd.read_csv(p, sep=" ", header=None, names=names, engine="c",
                         dtype=np.float64, chunksize=200_000, **exact) as it:
            return np.concatenate([c.to_numpy() for c in it])

    def arrow(p):
        t = pacsv.read_csv(p, read_options=pacsv.ReadOptions(column_names=names),
                           parse_options=pacsv.ParseOptions(delimiter=" "))
        return np.column_stack([t.column(i).to_numpy() for i in range(ncols)])

    def arrow_stream(p):
        r = pacsv.open_csv(p, read_options=pacsv.ReadOptions(column_names=names,
                                                             block_size=16 << 20),
                           parse_options=pacsv.ParseOptions(delimiter=" "))
        parts = [np.column_stack([b.column(i).to_numpy() for i in range(ncols)]) for b in r]
        return np.concatenate(parts)

    def numpy_loadtxt(p):
        return np.loadtxt(p, dtype=np.float64)

    return [("ours read_table", ours), ("ours iter_table (stream)", ours_stream),
            ("pandas C engine", pandas_c),
            ("pandas C chunks (stream)", pandas_chunks), ("pyarrow.csv", arrow),
            ("pyarrow.csv open_csv (stream)", arrow_stream), ("numpy.loadtxt", numpy_loadtxt)]


def with_bad_line(path, tmpdir):
    """A copy of ``path`` with the third field of the line at 80 % made invalid."""
    data = Path(path).read_bytes()
    lines = data.split(b"\n")
    k = int(0.8 * (len(lines) - 1))
    fields = lines[k].split(b" ")
    fields[2] = b"1.2.3"
    lines[k] = b" ".join(fields)
    out = Path(tmpdir) / ("bad_" + Path(path).name)
    out.write_bytes(b"\n".join(lines))
    return out, k + 1


def bad_line_report(fn, path, line):
    t0 = time.perf_counter()
    try:
        fn(path)
    except Exception as exc:               # noqa: BLE001 - we report whatever it raises
        dt = time.perf_counter() - t0
        text = str(exc)
        named = str(line) in text
        return dt, f"{'names line' if named else 'no line'}: {text[:70]!r}"
    return time.perf_counter() - t0, "accepted the bad field (no error)"


def bench_reads(path, ncols, repeat, tmpdir):
    ref = exact_reference(path)
    bad, bad_line = with_bad_line(path, tmpdir)
    size = os.path.getsize(path) / 1e6
    print(f"\n{path.name}: {size:.1f} MB, {ncols} columns; bad copy: line {bad_line}")
    print(f"{'reader':<32}{'time s':>8}{'MB/s':>8}  {'exact':<7} bad line")
    for name, fn in readers(ncols):
        t, values = best_of(lambda: fn(path), repeat)
        n = min(len(ref), len(values))
        exact = bool(np.array_equal(values[:n].view(np.uint64), ref[:n].view(np.uint64)))
        tb, msg = bad_line_report(fn, bad, bad_line)
        print(f"{name:<32}{t:>8.3f}{size / t:>8.0f}  {'yes' if exact else 'NO':<7} "
              f"{tb:.3f} s, {msg}")


def bench_writes(values, decimals, repeat):
    from ins import textformat
    import pandas as pd
    dec = np.array(decimals, dtype=np.int64)
    fmt = " ".join(f"%.{d}f" for d in decimals)
    ours = textformat.format_fixed(values, dec).tobytes()

    def numpy_savetxt():
        b = io.BytesIO()
        np.savetxt(b, values, fmt=fmt)
        return b.getvalue()

    def pandas_to_csv():
        # pandas takes one float_format for all columns: format per column first
        df = pd.DataFrame(values)
        return df.to_csv(sep=" ", header=False, index=False,
                         float_format=f"%.{max(decimals)}f").encode()

    print(f"\nwriting {values.shape[0]} x {values.shape[1]} values, decimals {decimals}")
    print(f"{'writer':<32}{'time s':>8}  same bytes as Python's % formatting")
    t, _ = best_of(lambda: textformat.format_fixed(values, dec).tobytes(), repeat)
    ref_head = "\n".join(fmt % tuple(r) for r in values[:2000]).encode()
    print(f"{'ours format_fixed':<32}{t:>8.3f}  {ours.startswith(ref_head)}")
    t, out = best_of(numpy_savetxt, repeat)
    print(f"{'numpy.savetxt':<32}{t:>8.3f}  {out.startswith(ref_head)}")
    t, out = best_of(pandas_to_csv, repeat)
    print(f"{'pandas to_csv (one format)':<32}{t:>8.3f}  (one decimals for every column)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    data = ensure_bench_data()
    if data is None:
        print("shared benchmark dataset unavailable (../shared/bench/ins missing)")
        return 0
    from ins import textfiles
    textfiles.read_table(data / "gnss.txt", 7, 7)            # compile / warm the kernels
    with tempfile.TemporaryDirectory() as tmpdir:
        bench_reads(data / "imu_noisy.txt", 7, args.repeat, tmpdir)
        bench_reads(data / "gnss.txt", 7, args.repeat, tmpdir)
    nav = textfiles.read_table(data / "truth.nav", 11, 11)[0]
    bench_writes(nav[:, 1:], [3, 9, 9, 4, 4, 4, 4, 6, 6, 6], args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
