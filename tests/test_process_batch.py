"""``ins process A B C ... -o OUT`` (issue 34 item 7): many logs at once, one after
another or as Dask tasks (``--workers N``, ``--scheduler``): each run into OUT/NAME with
its own summary and exit status, one table, the worst status; a single input as before;
Ctrl-C and SIGTERM to the process group at random moments leave the finished runs'
folders complete and nothing else (no staging folder, no Dask scratch).

The flights are three tiny ones (one 300 m strip, ~20 s of IMU), simulated here (~4 s);
one input of the batch is a broken per-log config (its files missing).
"""
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ins.cli.process_batch import batch_table, output_names, worst_status

ROOT = Path(__file__).resolve().parents[1]
SHORT = ROOT / "tests" / "data" / "flights" / "short.toml"
SEED = int(os.environ.get("INS_INTERRUPT_SEED", "12"))
PY = [sys.executable, "-m", "ins.cli.main", "process"]


def _tiny_plan():
    text = SHORT.read_text()
    for old, new in (("n_strips = 2", "n_strips = 1"),
                     ("strip_length_m = 600.0", "strip_length_m = 300.0"),
                     ("outages = [[20.0, 5.0]]", "outages = []")):
        assert old in text
        text = text.replace(old, new)
    return text


@pytest.fixture(scope="module")
def flights(tmp_path_factory):
    """Three flight folders a, b, c and a broken config broken.toml (in one folder)."""
    from photogrammetry.simulate.folder import simulate_flight
    d = tmp_path_factory.mktemp("batch")
    plan = d / "tiny.toml"
    plan.write_text(_tiny_plan())
    for k, name in enumerate("abc"):
        simulate_flight(plan, d / name, seed=k)
    (d / "broken.toml").write_text('[files]\nimu = "missing_imu.txt"\ngnss = "missing.txt"\n')
    return d


def _run(argv, cwd, env=None):
    return subprocess.run(PY + argv, cwd=cwd, capture_output=True, text=True, timeout=600,
                          env=env)


def _listing(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))


def _files(folder):
    """{name: bytes} of a run's folder; summary.txt without its timing line and the
    folder in its list of paths."""
    out = {}
    for p in sorted(Path(folder).iterdir()):
        data = p.read_bytes()
        if p.name == "summary.txt":
            text = re.sub(r"processed in .*\n", "", data.decode())
            data = re.sub(r"(?m)^  .*/", "  ", text).encode()     # the paths' folder
        out[p.name] = data
    return out


BATCH = ["a", "b", "broken.toml", "c"]


@pytest.fixture(scope="module")
def serial(flights):
    """The batch one run after another (no --workers): (CompletedProcess, OUT)."""
    proc = _run(BATCH + ["-o", "serial"], flights)
    return proc, flights / "serial"


def test_a_batch_of_three_flights_and_a_broken_config(serial, flights):
    proc, out = serial
    assert proc.returncode == 2, proc.stderr          # the worst run's: bad input
    assert sorted(os.listdir(out)) == ["a", "b", "c"]  # no folder for the broken one,
    for name in "abc":                                 # no staging folder left
        names = set(os.listdir(out / name))
        assert {"solution.nav", "solution_std.txt", "imu_errors.txt", "summary.txt",
                "sigma.png"} <= names
        assert not [n for n in names if n.startswith(".")]
        summary = (out / name / "summary.txt").read_text()
        assert "IMU epochs" in summary and f"serial/{name}/solution.nav" in summary
    table = proc.stdout.splitlines()
    assert table[0].split()[:3] == ["input", "folder", "exit"]
    rows = {line.split()[0]: line.split() for line in table[1:]}
    assert list(rows) == BATCH
    for name in "abc":
        row = rows[name]
        assert row[1:3] == [name, "0"] and "(kfgins)" in row
        rejected, sigma_h, sigma_v, seconds = map(float, row[-4:])
        assert 0 <= rejected < 5 and 0 < sigma_h < 0.1 and 0 < sigma_v < 0.1 and seconds > 0
    assert rows["broken.toml"][1:3] == ["-", "2"]
    err = proc.stderr.splitlines()
    assert err[0] == "process: 4 runs into serial, one after another"
    done = [x.split(":")[1].strip() for x in err if re.match(r"process: \d/4 ", x)]
    assert done == ["1/4 a", "2/4 b", "3/4 broken.toml", "4/4 c"], proc.stderr
    assert any(x.startswith("ins process: broken.toml: error: ") and "missing" in x
               for x in err), proc.stderr
    assert "Traceback" not in proc.stderr


def test_dask_workers_give_the_serial_results_byte_for_byte(serial, flights):
    """--workers 2 (two local Dask worker processes): the same table (but the times),
    the same exit status and the same files, byte for byte; a single run (today's path,
    no summary.txt) writes the same files too."""
    proc, out = serial
    dask = _run(BATCH + ["-o", "dask", "--workers", "2"], flights)
    assert dask.returncode == 2, dask.stderr
    assert "on 2 local Dask workers" in dask.stderr and "Traceback" not in dask.stderr

    def cut(table):
        return [line.split()[:-1] for line in table.splitlines()]
    assert cut(dask.stdout) == cut(proc.stdout)
    assert sorted(os.listdir(flights / "dask")) == ["a", "b", "c"]
    for name in "abc":
        assert _files(flights / "dask" / name) == _files(out / name), name
    one = _run(["b", "-o", "single"], flights)
    assert one.returncode == 0, one.stderr
    single = _files(flights / "single")
    batch = _files(out / "b")
    printed = re.sub(r"(?m)^  .*/", "  ", re.sub(r"processed in .*\n", "", one.stdout))
    assert batch.pop("summary.txt").decode() == printed + "  summary.txt\n"
    assert single == batch


def test_output_names_and_the_worst_status():
    assert output_names(["x/flight", "y/flight", "flight-2", "z/flight", "cfg.toml"]) == \
        ["flight", "flight-2", "flight-2-2", "flight-3", "cfg"]
    assert worst_status([0, 2, 0]) == 2 and worst_status([2, 3, 0]) == 3
    assert worst_status([0, 1]) == 1 and worst_status([]) == 0
    from ins.cli.process_batch import RunRecord
    lines = batch_table([RunRecord("a", "a", 0, gnss="g.txt (kfgins)", rejected_pct=1.5,
                                   sigma_h_m=0.01, sigma_v_m=0.02, time_s=3.0),
                         RunRecord("bad.toml", "bad", 2, error="x", time_s=0.0)],
                        ["a", "bad"])
    assert lines[1].split() == ["a", "a", "0", "g.txt", "(kfgins)", "1.50", "0.0100",
                                "0.0200", "3.0"]
    assert lines[2].split() == ["bad.toml", "-", "2", "-", "-", "-", "-", "0.0"]


def test_name_clashes_occupied_folders_and_bad_batches(flights, tmp_path):
    """Two inputs of one base name get NAME and NAME-2; an occupied OUT/NAME stops the
    batch before any work (exit 2, one line naming it) unless --force, which replaces
    only that folder; options of one log, --workers with --scheduler, a --report path:
    exit 2, one line naming the argument, nothing written."""
    shutil.copytree(flights / "a", tmp_path / "x" / "a")
    out = tmp_path / "out"
    (out / "a-2").mkdir(parents=True)
    (out / "a-2" / "old.txt").write_text("an earlier run\n")
    (out / "keep.txt").write_text("not a run's\n")
    argv = [str(flights / "a"), str(tmp_path / "x" / "a"), "-o", str(out), "--no-plots"]
    proc = _run(argv, tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"ins process: error: {out / 'a-2'}: the output folder is not empty (--force "
        "replaces it whole)"]
    assert _listing(out) == ["a-2", "a-2/old.txt", "keep.txt"]
    proc = _run(argv + ["--force", "-q", "--report", "qc.html"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "" and proc.stderr == ""          # -q: no progress, no table
    assert sorted(os.listdir(out)) == ["a", "a-2", "keep.txt"]
    assert (out / "a" / "qc.html").read_text().startswith("<!DOCTYPE html>")
    assert not (out / "a-2" / "old.txt").exists() and (out / "a-2" / "summary.txt").exists()
    assert (out / "a" / "solution.nav").read_bytes() == \
        (out / "a-2" / "solution.nav").read_bytes()
    for extra, words in ((["--imu", "i.txt"], "--imu: names one log's file"),
                         (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
                          "--workers N starts a local cluster"),
                         (["--report", "sub/r.html"], "--report sub/r.html: in a batch"),
                         (["--workers", "0"], "--workers")):
        proc = _run([str(flights / "a"), str(flights / "b"), "-o", "new"] + extra, tmp_path)
        assert proc.returncode == 2, (extra, proc.stderr)
        assert len(proc.stderr.strip().splitlines()) == 1 and words in proc.stderr, proc.stderr
        assert not (tmp_path / "new").exists()
    proc = _run([str(flights / "a"), str(flights / "a"), "-o", "new"], tmp_path)
    assert proc.returncode == 2 and "given twice" in proc.stderr
    proc = _run([str(flights / "a"), str(flights / "b"), "-o", str(flights)], tmp_path)
    assert proc.returncode == 2 and "would hold or replace the input" in proc.stderr


def test_a_run_that_meets_a_bug(flights, tmp_path, monkeypatch, capsys):
    """An unexpected exception in a run (a bug) is that run's exit 1 with its traceback;
    the batch goes on; no folder is left for it (nor OUT, made for no finished run)."""
    from ins.cli import process_batch
    from ins.cli.main import main

    def broken(result, cfg):
        raise ZeroDivisionError("a bug")
    monkeypatch.setattr(process_batch, "_gnss_source", broken)
    out = tmp_path / "out"
    assert main(["process", str(flights / "a"), str(flights / "broken.toml"), "-o", str(out),
                 "--no-plots"]) == 2                        # 2 > 1: the worst
    err = capsys.readouterr().err
    assert f"ins process: {flights / 'a'}: error: internal error: ZeroDivisionError: a bug" \
        in err and "Traceback" in err
    assert not out.exists()


def test_a_scheduler_address(flights, tmp_path):
    """--scheduler ADDRESS: the runs on an existing cluster (here a local one of this
    test), the same files as one after another."""
    from dask.distributed import LocalCluster
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None, local_directory=str(tmp_path / "scratch")
                      ) as cluster:
        proc = _run(["a", "c", "-o", str(tmp_path / "out"), "--no-plots", "--scheduler",
                     cluster.scheduler_address], flights)
    assert proc.returncode == 0, proc.stderr
    assert f"on the Dask scheduler {cluster.scheduler_address}" in proc.stderr
    plain = _run(["a", "c", "-o", str(tmp_path / "plain"), "--no-plots"], flights)
    assert plain.returncode == 0, plain.stderr
    for name in "ac":
        assert _files(tmp_path / "out" / name) == _files(tmp_path / "plain" / name)


def test_a_per_log_config_beside_a_flight_folder(flights, tmp_path):
    """A per-log config (its [files] relative to it) runs as its own log, into
    OUT/<its name without .toml>, as the same log's single run with --config does."""
    import tomllib
    man = tomllib.loads((flights / "b" / "manifest.toml").read_text())
    ini, arm = man["initial"], man["lever_arm"]
    cfg = tmp_path / "logs" / "log_b.toml"
    cfg.parent.mkdir()
    cfg.write_text(f"""
[files]
imu = "../../{flights.name}/b/imu.txt"
gnss = "../../{flights.name}/b/gnss.txt"
mount = "../../{flights.name}/b/mount.txt"
[initial]
time_s = {man['flight']['start_time_s']}
lat_deg = {ini['lat_deg']}
lon_deg = {ini['lon_deg']}
h_m = {ini['h_m']}
vel_ned_mps = {list(ini['vel_ned_mps'])}
rpy_deg = {list(ini['rpy_deg'])}
att_std_deg = [0.05, 0.05, 0.2]
[mount]
imu_to_platform_centre_b_m = {arm['imu_to_platform_centre_b_m']}
platform_centre_to_antenna_a_m = {arm['platform_centre_to_antenna_a_m']}
""".replace(f"../../{flights.name}", os.path.relpath(flights, cfg.parent)))
    proc = _run([str(flights / "a"), str(cfg), "-o", "out", "--no-plots"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert sorted(os.listdir(tmp_path / "out")) == ["a", "log_b"]
    one = _run(["--config", str(cfg), "-o", "one", "--no-plots", "-q"], tmp_path)
    assert one.returncode == 0, one.stderr
    assert (tmp_path / "out" / "log_b" / "solution.nav").read_bytes() == \
        (tmp_path / "one" / "solution.nav").read_bytes()


def test_the_help_states_the_batch_rules(capsys):
    from ins.cli.main import main
    with pytest.raises(SystemExit):
        main(["process", "--help"])
    text = capsys.readouterr().out
    assert "many logs (a batch)" in text and "the largest exit code of the runs" in text
    assert "OUT/flight-2" in text and "--scheduler" in text


# --- Ctrl-C and SIGTERM to the process group --------------------------------------------

STOPPED = {signal.SIGINT: (130, "interrupted"), signal.SIGTERM: (143, "terminated (SIGTERM)")}


@pytest.mark.slow
def test_ctrl_c_and_sigterm_at_random_moments_of_a_batch(flights, tmp_path):
    """SIGINT or SIGTERM to the whole process group (as a terminal or a batch scheduler
    sends it) at random moments of a batch of three flights, on two Dask workers and one
    after another: exit 130/143 (or 0 if it had finished) and one stderr line; the runs
    named there complete (as in an uninterrupted batch), the others absent, OUT absent
    when none had finished, no staging folder, nothing left in TMPDIR, no process left."""
    names = ["a", "b", "c"]
    durations = {}
    for workers in ("2", "1"):                # how long each takes here
        t0 = time.perf_counter()
        reference = _run(names + ["-o", f"ref{workers}", "-q", "--no-plots", "--workers",
                                  workers], flights)
        durations[workers] = time.perf_counter() - t0
        assert reference.returncode == 0, reference.stderr
    complete = {n: _listing(flights / "ref2" / n) for n in names}
    rng = random.Random(f"{SEED}-batch")
    # (signal, workers, when): at a random moment of the run, or a moment after the
    # first run's folder is in place (the finished/unfinished split)
    cases = [(signal.SIGINT, "2", "any"), (signal.SIGTERM, "2", "any"),
             (signal.SIGINT, "1", "after"), (signal.SIGTERM, "2", "after"),
             (signal.SIGINT, "2", "after"), (signal.SIGTERM, "1", "any")]
    outcomes = []
    for k, (sig, workers, when) in enumerate(cases):
        work, tmp = tmp_path / f"run{k}", tmp_path / f"tmp{k}"
        work.mkdir()
        tmp.mkdir()
        argv = PY + [str(flights / n) for n in names] + ["-o", "out", "-q", "--no-plots",
                                                         "--workers", workers]
        proc = subprocess.Popen(argv, cwd=work, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True,
                                env=dict(os.environ, TMPDIR=str(tmp)))
        t0 = time.perf_counter()
        duration = durations[workers]
        if when == "any":
            delay = rng.uniform(0.5, 0.9 * duration)
            time.sleep(delay)
        else:                   # the runs after the first (imports done) are quick in
            while proc.poll() is None and not (       # this process: a shorter wait
                    (work / "out").is_dir() and any(
                        not n.startswith(".") for n in os.listdir(work / "out"))):
                time.sleep(0.02)
            time.sleep(rng.uniform(0.0, 1.0 if workers == "2" else 0.2))
            delay = time.perf_counter() - t0
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            pass
        _, err = proc.communicate(timeout=600)
        where = f"run {k} ({sig.name} at {delay:.1f} s of {duration:.1f}, --workers " \
                f"{workers}): rc " \
                f"{proc.returncode}, stderr {err!r}, files {_listing(work)}"
        assert "Traceback" not in err, where
        lines = [x for x in err.splitlines() if x.strip() and not x.startswith("warning:")]
        assert _listing(tmp) == [], where
        out = work / "out"
        if proc.returncode == 0:
            assert lines == [] and sorted(os.listdir(out)) == names, where
            outcomes.append("0")
        else:
            code, word = STOPPED[sig]
            assert proc.returncode == code and len(lines) == 1, where
            if lines[0] == f"ins process: {word}; no output written":
                assert not out.exists(), where
                outcomes.append(f"{code}, none finished")
            else:
                head = f"ins process: {word} after the output was complete: "
                assert lines[0].startswith(head), where
                done = sorted(os.path.basename(p) for p in lines[0][len(head):].split(", "))
                assert sorted(os.listdir(out)) == done, where     # no staging folder
                outcomes.append(f"{code}, {len(done)} finished")
            for n in os.listdir(out) if out.exists() else []:
                assert _listing(out / n) == complete[n], where
        t1 = time.perf_counter()          # the group empties: no worker left
        while time.perf_counter() - t1 < 15:
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.2)
        else:
            raise AssertionError(where + subprocess.run(
                ["ps", "-o", "pid,stat,cmd", "-g", str(proc.pid)], capture_output=True,
                text=True).stdout)
    print(f"\nbatch interrupts: {outcomes}")
    assert sum(not o.startswith("0") for o in outcomes) >= len(cases) // 2
