"""Sweep of bad or unusual inputs through the ``ins`` sub-commands (issue: bad inputs).

Each case runs one command in-process on a corrupted copy of a valid input (a simulated
flight, ``tests/data/flights/short.toml``) or with one bad option, and is judged against
the README's promise:

* a bad input: exit code 2, ONE stderr line ``ins CMD: error: ...`` that names the file
  (and its line where one is at fault) or the option or the TOML key, no traceback, no
  numpy repr (``np.float64(``), and nothing left behind in the output folder;
* an unusual but valid input (CRLF line ends, trailing spaces): the result equals the
  clean file's.

Prints one line per case (``ok`` / ``BAD`` and the stderr line) and the counts per
command.  Run: ``.venv/bin/python bench/sweep_bad_inputs_ins.py [--keep DIR]`` (about a
minute, most of it three ``ins process`` runs).
"""
import argparse
import contextlib
import io
import shutil
import sys
import tempfile
import warnings
from collections import Counter
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ins.cli import main as ins_cli  # noqa: E402


def run(argv):
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            code = ins_cli.main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
        except BaseException as exc:   # noqa: BLE001 - a crash is a finding
            import traceback
            traceback.print_exc(file=err)
            code = f"raised {type(exc).__name__}"
    return code, err.getvalue()


def edit_field(src, dst, line, col, value):
    """Copy ``src`` to ``dst`` with field ``col`` (0-based) of 1-based ``line`` = value."""
    lines = Path(src).read_bytes().split(b"\n")
    fields = lines[line - 1].split()
    fields[col] = value.encode() if isinstance(value, str) else value
    lines[line - 1] = b" ".join(fields)
    Path(dst).write_bytes(b"\n".join(lines))
    return dst


def transform(src, dst, fn):
    Path(dst).write_bytes(fn(Path(src).read_bytes()))
    return dst


def swap_cols(data, a, b, first=0):
    out = []
    for k, ln in enumerate(data.split(b"\n")):
        f = ln.split()
        if k >= first and len(f) > max(a, b):
            f[a], f[b] = f[b], f[a]
            ln = b" ".join(f)
        out.append(ln)
    return b"\n".join(out)


def setup(base):
    flight = base / "flight"
    from photogrammetry.simulate.folder import simulate_flight
    simulate_flight(ROOT / "tests" / "data" / "flights" / "short.toml", flight, 0)
    man = tomllib.loads((flight / "manifest.toml").read_text())
    ini, arm = man["initial"], man["lever_arm"]
    config = (
        f"[initial]\ntime_s = {man['flight']['start_time_s']}\nlat_deg = {ini['lat_deg']}\n"
        f"lon_deg = {ini['lon_deg']}\nh_m = {ini['h_m']}\n"
        f"vel_ned_mps = {list(ini['vel_ned_mps'])}\nrpy_deg = {list(ini['rpy_deg'])}\n"
        "[imu_noise]\narw_deg_sqrth = 0.15\nvrw_mps_sqrth = 0.1\ngyro_bias_std_dph = 1.5\n"
        "accel_bias_std_mgal = 1500.0\ngyro_scale_std_ppm = 200.0\n"
        "accel_scale_std_ppm = 400.0\ncorr_time_h = 1.0\n"
        f"[mount]\nimu_to_platform_centre_b_m = {arm['imu_to_platform_centre_b_m']}\n"
        f"platform_centre_to_antenna_a_m = {arm['platform_centre_to_antenna_a_m']}\n")
    (base / "config.toml").write_text(config)
    # a short IMU piece (20 s) for mechanize / allan / align
    lines = (flight / "imu.txt").read_text().splitlines()
    (base / "imu.txt").write_text("\n".join(lines[:2000]) + "\n")
    # a small nav file
    nav = (flight / "truth.nav").read_text().splitlines()
    (base / "truth.nav").write_text("\n".join(nav[:3000]) + "\n")
    # returns and a scanner file
    t0 = float(nav[100].split()[1])
    (base / "returns.csv").write_text("time_s,range_m,scan_angle_deg\n" + "".join(
        f"{t0 + 0.01 * k:.3f},{300 + k % 7},{-20 + k % 40}\n" for k in range(200)))
    shutil.copyfile(ROOT / "data" / "scanner" / "example_scanner.toml", base / "scanner.toml")
    return flight, config


INIT = ["--init-lla", "30.5,114.3,300", "--init-vel", "0,0,0", "--init-att", "0,0,0"]


def cases(base, flight, config):
    """(command, name, argv, expect): expect is ('error', tokens) or ('same', output)."""
    imu, nav, cfg = base / "imu.txt", base / "truth.nav", base / "config.toml"
    scan, ret = base / "scanner.toml", base / "returns.csv"
    out = base / "out"
    c = []

    def err(cmd, name, argv, *tokens):
        c.append((cmd, name, argv, ("error", tokens)))

    def same(cmd, name, argv, output, clean_argv):
        c.append((cmd, name, argv, ("same", (output, clean_argv))))

    bad = base / "bad"
    bad.mkdir()

    def b(name):
        return bad / name

    # ---- IMU text corruptions (mechanize, allan, align, time-offset)
    mech = ["mechanize", None, *INIT, "-q", "-o", out / "m.nav"]

    def m(path, *extra):
        return ["mechanize", path, *INIT, "-q", *extra, "-o", out / "m.nav"]

    err("mechanize", "imu nan", m(edit_field(imu, b("i_nan.txt"), 37, 2, "nan")),
        "i_nan.txt:37:")
    err("mechanize", "imu inf", m(edit_field(imu, b("i_inf.txt"), 40, 5, "-inf")),
        "i_inf.txt:40:")
    err("mechanize", "imu 1e308 dvel", m(edit_field(imu, b("i_huge.txt"), 1500, 4, "1e308")),
        "i_huge.txt:1500:")
    err("mechanize", "imu 1e308 dtheta", m(edit_field(imu, b("i_hugeg.txt"), 900, 1, "1e308")),
        "i_hugeg.txt:900:")
    err("mechanize", "imu 5 rad increment", m(edit_field(imu, b("i_5rad.txt"), 700, 3, "5.0")),
        "i_5rad.txt:700:")
    err("mechanize", "imu 50 m/s increment", m(edit_field(imu, b("i_50v.txt"), 800, 6, "50")),
        "i_50v.txt:800:")
    err("mechanize", "imu not UTF-8", m(transform(imu, b("i_utf.txt"),
                                                  lambda d: d.replace(b"\n", b"\n\xff\xfe", 1))),
        "i_utf.txt:2:")
    err("mechanize", "imu truncated mid-line", m(transform(imu, b("i_trunc.txt"),
                                                           lambda d: d[:len(d) // 2])),
        "i_trunc.txt:")
    err("mechanize", "imu columns swapped (time<->dvel_z)",
        m(transform(imu, b("i_swap.txt"), lambda d: swap_cols(d, 0, 6))), "i_swap.txt:")
    err("mechanize", "imu bin truncated", m(transform(imu, b("i.bin"), lambda d: b"\0" * 100)),
        "i.bin")
    same("mechanize", "imu CRLF", m(transform(imu, b("i_crlf.txt"),
                                              lambda d: d.replace(b"\n", b"\r\n"))),
         out / "m.nav", m(imu))
    same("mechanize", "imu trailing spaces", m(transform(imu, b("i_sp.txt"),
                                                         lambda d: d.replace(b"\n", b"  \n"))),
         out / "m.nav", m(imu))
    # options
    mi = [a for a in mech]
    mi[1] = imu

    def opt(*pairs):
        argv = list(mi)
        for k in range(0, len(pairs), 2):
            if pairs[k] in argv:
                argv[argv.index(pairs[k]) + 1] = pairs[k + 1]
            else:
                argv[2:2] = [pairs[k], pairs[k + 1]]
        return argv

    err("mechanize", "--init-lla nan", opt("--init-lla", "nan,0,0"), "--init-lla")
    err("mechanize", "--init-lla 91", opt("--init-lla", "91,0,0"), "--init-lla", "90")
    err("mechanize", "--init-lla h 1e9", opt("--init-lla", "30,114,1e9"), "--init-lla")
    err("mechanize", "--init-vel 1e9", opt("--init-vel", "1e9,0,0"), "--init-vel")
    err("mechanize", "--init-att nan", opt("--init-att", "0,nan,0"), "--init-att")
    err("mechanize", "--start nan", opt("--start", "nan"), "--start")
    err("mechanize", "--start abc", opt("--start", "abc"), "--start")
    err("mechanize", "--end inf", opt("--end", "inf"), "--end")
    err("mechanize", "--every 0", opt("--every", "0"), "--every")
    err("mechanize", "--week -1", opt("--week", "-1"), "--week")
    err("mechanize", "--format xx", opt("--format", "xx"), "--format")
    err("mechanize", "--gyro-bias-dph inf", opt("--gyro-bias-dph", "inf,0,0"), "--gyro-bias-dph")
    err("mechanize", "unknown option", mi + ["--frobnicate"], "--frobnicate")
    err("mechanize", "missing value", mi + ["--start"], "--start")

    # ---- allan / align
    err("allan", "imu 1e308", ["allan", b("i_huge.txt")], "i_huge.txt:1500:")
    err("allan", "--start nan", ["allan", imu, "--start", "nan"], "--start")
    err("allan", "--end abc", ["allan", imu, "--end", "abc"], "--end")
    al = ["align", imu, "--lla", "30.5,114.3,300"]
    err("align", "imu nan", ["align", b("i_nan.txt"), "--lla", "30.5,114.3,300"], "i_nan.txt:37:")
    err("align", "--lla 91", ["align", imu, "--lla", "91,0,0"], "--lla")
    err("align", "--zupt-sigma-mps 0", al + ["--zupt-sigma-mps", "0"], "--zupt-sigma-mps")
    err("align", "--zupt-sigma-mps -1", al + ["--zupt-sigma-mps", "-1"], "--zupt-sigma-mps")
    err("align", "--arw-deg-sqrth nan", al + ["--arw-deg-sqrth", "nan"], "--arw-deg-sqrth")
    err("align", "--max-heading-std-deg -1", al + ["--max-heading-std-deg", "-1"],
        "--max-heading-std-deg")
    err("align", "--start inf", al + ["--start", "inf"], "--start")

    # ---- compare (nav)
    def cmp(path):
        return ["compare", path, nav]
    err("compare", "nav h 1e308", cmp(edit_field(nav, b("n_h.nav"), 50, 4, "1e308")),
        "n_h.nav:50:")
    err("compare", "nav v inf", cmp(edit_field(nav, b("n_v.nav"), 60, 6, "inf")), "n_v.nav:60:")
    err("compare", "nav lat 95", cmp(edit_field(nav, b("n_lat.nav"), 70, 2, "95")),
        "n_lat.nav:70:")
    err("compare", "nav roll 1e308", cmp(edit_field(nav, b("n_r.nav"), 80, 8, "1e308")),
        "n_r.nav:80:")
    err("compare", "nav not UTF-8", cmp(transform(nav, b("n_u.nav"),
                                                  lambda d: d.replace(b"\n", b"\n\xff", 3))),
        "n_u.nav:")
    err("compare", "nav truncated", cmp(transform(nav, b("n_t.nav"), lambda d: d[:len(d) // 3])),
        "n_t.nav:")

    # ---- vehicle-mounting
    vm = ["vehicle-mounting", nav]
    err("vehicle-mounting", "--roll nan", vm + ["--roll", "nan"], "--roll")
    err("vehicle-mounting", "--roll 1e6", vm + ["--roll", "1e6"], "--roll")
    err("vehicle-mounting", "--min-speed -1", vm + ["--min-speed", "-1"], "--min-speed")
    err("vehicle-mounting", "--max-turn nan", vm + ["--max-turn", "nan"], "--max-turn")
    err("vehicle-mounting", "--block 0", vm + ["--block", "0"], "--block")
    err("vehicle-mounting", "nav nan", ["vehicle-mounting", b("n_v.nav")], "n_v.nav:60:")

    # ---- time-offset
    to = ["time-offset", "--imu", flight / "imu.txt", "--gnss", flight / "gnss.txt"]
    for o, v in (("--max", "0"), ("--step", "nan"), ("--window", "-1"), ("--knots", "0"),
                 ("--min-speed", "nan"), ("--step", "inf")):
        err("time-offset", f"{o} {v}", to + [o, v], o)

    # ---- process (files)
    f = flight

    def proc(imu_=None, gnss=None, mount=None, config=None, *extra, name="res"):
        return ["process", "--imu", imu_ or f / "imu.txt", "--gnss", gnss or f / "gnss.txt",
                "--mount", mount or f / "mount.txt", "--config", config or cfg, "--no-plots",
                "-q", *extra, "-o", out / name]
    err("process", "imu 1e308 line 9000",
        proc(edit_field(f / "imu.txt", b("p_huge.txt"), 9000, 4, "1e308")), "p_huge.txt:9000:")
    err("process", "imu 1e3 dvel line 9000",
        proc(edit_field(f / "imu.txt", b("p_1e3.txt"), 9000, 4, "1e3")), "p_1e3.txt:9000:")
    err("process", "gnss h 1e308", proc(gnss=edit_field(f / "gnss.txt", b("g_h.txt"), 20, 3,
                                                         "1e308")), "g_h.txt:20:")
    err("process", "gnss sigma 1e308", proc(gnss=edit_field(f / "gnss.txt", b("g_s.txt"), 20, 4,
                                                             "1e308")), "g_s.txt:20:")
    err("process", "gnss vel 1e308", proc(gnss=edit_field(f / "gnss.txt", b("g_v.txt"), 20, 7,
                                                           "1e308")), "g_v.txt:20:")
    err("process", "gnss not UTF-8", proc(gnss=transform(f / "gnss.txt", b("g_u.txt"),
                                                         lambda d: d.replace(b"\n", b"\n\xc3(",
                                                                             4))), "g_u.txt:")
    err("process", "mount roll 1e308", proc(mount=edit_field(f / "mount.txt", b("mt.txt"), 30, 1,
                                                              "1e308")), "mt.txt:30:")

    def cfgedit(name, old, new):
        p = b(name)
        text = config.replace(old, new) if old else config + new
        assert text != config
        p.write_text(text)
        return p
    err("process", "config lever 1e6",
        proc(config=cfgedit("c_arm.toml", "platform_centre_to_antenna_a_m = [0.4",
                            "platform_centre_to_antenna_a_m = [1e6")),
        "c_arm.toml", "platform_centre_to_antenna_a_m")
    err("process", "config imu arm 1e6",
        proc(config=cfgedit("c_arm2.toml", "imu_to_platform_centre_b_m = [0.1",
                            "imu_to_platform_centre_b_m = [1e6")),
        "c_arm2.toml", "imu_to_platform_centre_b_m")
    err("process", "config lat 95", proc(config=cfgedit("c_lat.toml", "lat_deg = 30",
                                                         "lat_deg = 95 #")), "c_lat.toml", "lat_deg")
    err("process", "config arw nan", proc(config=cfgedit("c_nan.toml", "arw_deg_sqrth = 0.15",
                                                          "arw_deg_sqrth = nan")),
        "c_nan.toml", "arw_deg_sqrth")
    err("process", "config arw inf", proc(config=cfgedit("c_inf.toml", "arw_deg_sqrth = 0.15",
                                                          "arw_deg_sqrth = inf")),
        "c_inf.toml", "arw_deg_sqrth")
    err("process", "config vel 1e9", proc(config=cfgedit("c_v.toml", "vel_ned_mps = [",
                                                         "vel_ned_mps = [1e9, ")),
        "c_v.toml", "vel_ned_mps")
    err("process", "config h 1e9", proc(config=cfgedit("c_h.toml", "h_m = ", "h_m = 1e9 #")),
        "c_h.toml", "h_m")
    err("process", "config not UTF-8", proc(config=transform(cfg, b("c_u.toml"),
                                                             lambda d: b"\xff" + d)), "c_u.toml")
    err("process", "--imu-time-shift-s nan", proc(None, None, None, None,
                                                  "--imu-time-shift-s", "nan"),
        "--imu-time-shift-s")
    err("process", "--gnss-time-shift-s 1e308", proc(None, None, None, None,
                                                     "--gnss-time-shift-s", "1e308"),
        "--gnss-time-shift-s")
    err("process", "--gnss-quality-scale 1=nan", proc(None, None, None, None,
                                                      "--gnss-quality-scale", "1=nan"),
        "--gnss-quality-scale")
    err("process", "--week -5", proc(None, None, None, None, "--week", "-5"), "--week")
    err("process", "--format foo", proc(None, None, None, None, "--format", "foo"), "--format")
    err("process", "--gnss-format foo", proc(None, None, None, None, "--gnss-format", "foo"),
        "--gnss-format")
    err("process", "unknown option", proc(None, None, None, None, "--frobnicate"), "--frobnicate")
    err("process", "rtklib pos nan", proc(None, transform(
        f / "gnss.txt", b("g.pos"), lambda d: b"%  GPST  latitude(deg) longitude(deg)  "
        b"height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n"
        b"2300 200000.000   30.499 114.295 nan 1 8 0.01 0.01 0.02 0 0 0 0 0\n"),
        None, None, "--gnss-format", "rtklib"), "g.pos:2:")

    # ---- georeference / strip-check (scanner file)
    def scanedit(name, old, new):
        p = b(name)
        text = scan.read_text()
        assert old in text
        p.write_text(text.replace(old, new))
        return p
    geo = ["georeference", ret, "--trajectory", nav, "-o", out / "p.las"]
    err("georeference", "scanner lever 1e6", geo + ["--scanner", scanedit(
        "s_arm.toml", "lever_arm_m = [0.12", "lever_arm_m = [1e6")], "s_arm.toml", "lever_arm_m")
    err("georeference", "scanner lever nan", geo + ["--scanner", scanedit(
        "s_nan.toml", "lever_arm_m = [0.12", "lever_arm_m = [nan")], "s_nan.toml", "lever_arm_m")
    err("georeference", "scanner sigma 1e6", geo + ["--scanner", scanedit(
        "s_sig.toml", "lever_arm_sigma_m = [0.005", "lever_arm_sigma_m = [1e6")],
        "s_sig.toml", "lever_arm_sigma_m")
    err("georeference", "scanner range sigma inf", geo + ["--scanner", scanedit(
        "s_rs.toml", "range_sigma_m = 0.02", "range_sigma_m = inf")], "s_rs.toml", "range_sigma_m")
    err("georeference", "scanner tilt 1e308", geo + ["--scanner", scanedit(
        "s_t.toml", "forward_tilt_deg = 0.0", "forward_tilt_deg = 1e308")], "s_t.toml",
        "forward_tilt_deg")
    err("georeference", "returns range nan", ["georeference", edit_field(
        ret, b("r_nan.csv"), 5, 0, "0,nan,3"), "--trajectory", nav, "--scanner", scan, "-o",
        out / "p.las"], "r_nan.csv:5:")
    err("georeference", "returns range 1e308", ["georeference", edit_field(
        ret, b("r_big.csv"), 6, 0, "1,1e308,3"), "--trajectory", nav, "--scanner", scan, "-o",
        out / "p.las"], "r_big.csv:6:")
    err("georeference", "--block-size 0", geo + ["--scanner", scan, "--block-size", "0"],
        "--block-size")
    sc = ["strip-check", b("none.las"), "--trajectory", nav, "--scanner", scan]
    err("strip-check", "--radius-m 0", sc + ["--radius-m", "0"], "--radius-m")
    err("strip-check", "--radius-m nan", sc + ["--radius-m", "nan"], "--radius-m")
    err("strip-check", "--neighbours 0", sc + ["--neighbours", "0"], "--neighbours")

    # ---- simulate (flight plan)
    plan = (ROOT / "tests" / "data" / "flights" / "short.toml").read_text()

    def planedit(name, old, new):
        p = b(name)
        assert old in plan
        p.write_text(plan.replace(old, new))
        return ["simulate", p, "-q", "-o", out / "sim"]
    err("simulate", "plan imu arm 1e6", planedit(
        "pl_arm.toml", "imu_to_platform_centre_b_m = [0.1", "imu_to_platform_centre_b_m = [1e6"),
        "pl_arm.toml", "imu_to_platform_centre_b_m")
    err("simulate", "plan antenna 1e6", planedit(
        "pl_ant.toml", "platform_centre_to_antenna_a_m = [0.4",
        "platform_centre_to_antenna_a_m = [1e6"), "pl_ant.toml", "platform_centre_to_antenna_a_m")
    err("simulate", "plan height nan", planedit(
        "pl_h.toml", "height_agl_m = 300.0", "height_agl_m = nan"), "pl_h.toml", "height_agl_m")
    err("simulate", "plan lat 95", planedit(
        "pl_lat.toml", "origin_lat_deg = 30.5", "origin_lat_deg = 95"), "pl_lat.toml",
        "origin_lat_deg")
    err("simulate", "--seed -1", ["simulate", ROOT / "tests/data/flights/short.toml", "--seed",
                                  "-1", "-o", out / "sim"], "--seed")

    # ---- import-bag
    (bad / "bag.bag").write_bytes(b"\xff" * 100)
    err("import-bag", "garbage bag", ["import-bag", bad / "bag.bag", "-o", out / "bag"],
        "bag.bag")
    err("import-bag", "--gnss-sigma-m 0,0,0", ["import-bag", bad / "bag.bag", "--gnss-sigma-m",
                                               "0,0,0", "-o", out / "bag"], "--gnss-sigma-m")
    err("import-bag", "--gnss-sigma-m nan", ["import-bag", bad / "bag.bag", "--gnss-sigma-m",
                                             "nan,1,1", "-o", out / "bag"], "--gnss-sigma-m")
    return c


def judge(code, stderr, expect, out_dir, run_clean):
    kind, what = expect
    if kind == "same":
        output, clean_argv = what
        if code != 0:
            return False, stderr.strip().splitlines()[-1:] or [f"exit {code}"]
        got = Path(output).read_bytes()
        Path(output).unlink()
        c2, e2 = run_clean(clean_argv)
        ref = Path(output).read_bytes()
        Path(output).unlink()
        return got == ref, ["same as the clean file" if got == ref else "differs"]
    lines = [x for x in stderr.splitlines() if x.strip()]
    problems = []
    if code != 2:
        problems.append(f"exit {code}")
    if len(lines) != 1:
        problems.append(f"{len(lines)} stderr lines")
    if "Traceback" in stderr:
        problems.append("traceback")
    if "np.float64(" in stderr or "np.int64(" in stderr:
        problems.append("numpy repr")
    last = lines[-1] if lines else ""
    for t in what:
        if t not in last:
            problems.append(f"does not name {t!r}")
    left = [p for p in out_dir.rglob("*")] if out_dir.exists() else []
    if left:
        problems.append(f"left {len(left)} output file(s)")
    return not problems, [last] + problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", help="work folder (kept); default a temporary one")
    ap.add_argument("--only", help="only the cases of this command")
    args = ap.parse_args()
    base = Path(args.keep or tempfile.mkdtemp(prefix="sweep_ins_"))
    base.mkdir(parents=True, exist_ok=True)
    for p in base.iterdir():
        shutil.rmtree(p) if p.is_dir() else p.unlink()
    flight, config = setup(base)
    counts = Counter()
    for cmd, name, argv, expect in cases(base, flight, config):
        if args.only and cmd != args.only:
            continue
        out = base / "out"
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir()
        code, stderr = run(argv)
        ok, notes = judge(code, stderr, expect, out, run)
        counts[cmd, ok] += 1
        print(f"{'ok ' if ok else 'BAD'} {cmd:17s} {name:38s} | {' | '.join(notes)[:300]}")
        sys.stdout.flush()
    print()
    total_ok = total = 0
    for cmd in sorted({k[0] for k in counts}):
        good, bad = counts[cmd, True], counts[cmd, False]
        total_ok += good
        total += good + bad
        print(f"{cmd:17s} {good:3d} ok {bad:3d} not as the README promises")
    print(f"{'all':17s} {total_ok:3d} ok {total - total_ok:3d} not as the README promises "
          f"({total} cases)")
    if not args.keep:
        shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
