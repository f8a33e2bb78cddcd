"""The forward filter's per-node and per-measurement stores (ins.estimation.core.filter_stores):
on disk (a work folder) they give back exactly what the in-memory stores give, across
the buffer's spills; and ``process`` with a work folder gives bit for bit the results of
a run in memory (issue 26: memory bounded by a constant on long logs)."""
import numpy as np

from ins.estimation.core import filter_stores
from ins.estimation.core import smoother
from ins.estimation.core.filter_stores import RecordStore, Rows, Table
from ins.estimation.core.measurements import UpdateRecord


def test_rows_on_disk_read_back_exactly_across_spills(tmp_path):
    rng = np.random.default_rng(1)
    data = rng.normal(size=(103, 4))
    mem, disk = Rows((4,)), Rows((4,), workdir=tmp_path, buffer=10)
    for r in data:
        mem.append(r)
        disk.append(r)
    assert len(disk) == 103 and disk._on_disk == 100          # 10 spills of 10 rows
    for j0, j1 in ((0, 103), (5, 37), (95, 103), (100, 101), (99, 102), (50, 50)):
        assert np.array_equal(disk.read(j0, j1), data[j0:j1])
        assert np.array_equal(mem.read(j0, j1), data[j0:j1])
    assert np.array_equal(disk[-1], data[-1]) and np.array_equal(disk[7], data[7])
    assert np.array_equal(np.concatenate([c for _, c in disk.chunks(17)]), data)
    # pop through the buffer into the file (read back, file truncated), then append again
    popped = [disk.pop() for _ in range(15)]
    assert np.array_equal(np.array(popped), data[88:][::-1]) and len(disk) == 88
    disk.append(data[88])
    assert np.array_equal(disk.array(), data[:89])
    scalars = Rows((), np.int64, workdir=tmp_path, buffer=3)
    for k in range(10):
        scalars.append(k)
    assert scalars.array().tolist() == list(range(10))


def test_record_store_gives_back_the_records(tmp_path):
    rng = np.random.default_rng(2)
    recs = []
    for k in range(40):
        m = (3, 1, 2, 5)[k % 4]                  # 5 axes: a continuation row
        axes = tuple(f"a{i}" for i in range(m)) if m == 5 else ("N", "E", "D")[:m]
        recs.append(UpdateRecord(("gnss_position", "heading", "nonholonomic", "dd")[k % 4],
                                 axes, ("m", "deg", "m/s", "m")[k % 4], 100.0 + k / 3,
                                 rng.normal(size=m), rng.uniform(0.1, 1, m),
                                 float(rng.chisquare(m)), bool(k % 3)))
    for store in (RecordStore(), RecordStore(tmp_path)):
        if store._rows._file is not None:
            store._rows._buffer = 7
        for r in recs:
            store.append(r)
        assert len(store) == 40
        last = store.pop()                       # the 5-axis record, over two rows
        assert last.axes == recs[-1].axes and np.array_equal(last.innovation,
                                                             recs[-1].innovation)
        store.append(last)
        got = list(store)
        assert len(got) == 40
        for a, b in zip(got, recs):
            assert (a.name, a.axes, a.unit, a.time, a.nis, a.accepted) == (
                b.name, b.axes, b.unit, b.time, b.nis, b.accepted)
            assert np.array_equal(a.innovation, b.innovation)
            assert np.array_equal(a.sigma, b.sigma)
            assert np.array_equal(a.standardized, b.standardized)


def test_table_written_backwards(tmp_path):
    data = np.arange(60.0).reshape(20, 3)
    for t in (Table(20, 3), Table(20, 3, tmp_path)):
        for j1 in (20, 13, 6):
            j0 = max(j1 - 7, 0)
            t.put(j0, data[j0:j1])
        assert np.array_equal(t.array(), data) and np.array_equal(t.read(4, 9), data[4:9])


def test_node_store_on_disk_buffers_and_reads_back_exactly(tmp_path, monkeypatch):
    """The node matrices are written in blocks (NODE_BUFFER_BYTES); the file holds
    P_prior, P_post, Phi node after node, and every read (also of nodes still in the
    buffer) gives back what was appended."""
    n = 4
    monkeypatch.setattr(filter_stores, "NODE_BUFFER_BYTES", 5 * 3 * n * n * 8)  # 5 nodes
    rng = np.random.default_rng(2)
    mats = []
    for _ in range(23):
        a = rng.normal(size=(3, n, n))
        a[:2] = a[:2] @ a[:2].transpose(0, 2, 1)            # covariances: positive
        mats.append(a)
    disk, mem = filter_stores.NodeStore(tmp_path), filter_stores.NodeStore()
    for k, a in enumerate(mats):
        disk.append(*a, time=float(k))
        mem.append(*a, time=float(k))
        if k == 11:                                          # 10 written, 2 buffered
            assert disk._n_buf == 2
            assert np.array_equal(disk.block(8, 12), np.array(mats[8:12]))
    assert disk._n_buf == 1 and disk.count == 23        # the read flushed 12
    assert np.array_equal(disk.block(0, 23), np.array(mats))
    back = [(j0, b) for j0, b in disk.blocks_reversed(size=7)]
    assert [j0 for j0, _ in back] == [16, 9, 2, 0]
    assert np.array_equal(np.concatenate([b for _, b in back[::-1]]), np.array(mats))
    assert np.array_equal(disk.post_std, mem.post_std)
    disk._file.seek(0)
    assert disk._file.read() == np.array(mats).tobytes()     # the per-node layout


def test_process_with_a_work_folder_is_bit_identical(tmp_path, monkeypatch):
    """Spilled to disk with tiny buffers and smoother blocks (every boundary crossed
    many times), the results equal the in-memory run's exactly."""
    from test_filter import given_config, short_flight

    from ins.estimation.pipeline.process import process
    cfg = given_config(short_flight())
    ref = process(cfg)
    d = list(Rows.__init__.__defaults__)
    d[-1] = 50
    monkeypatch.setattr(Rows.__init__, "__defaults__", tuple(d))
    monkeypatch.setattr(smoother, "_BLOCK", 23)
    monkeypatch.setattr(filter_stores, "NODE_BUFFER_BYTES", 40_000)     # 7 nodes (n = 27)
    work = tmp_path / "work"
    work.mkdir()
    res = process(cfg, workdir=str(work))
    assert isinstance(res.fwd.stores["dx"], filter_stores.Rows)
    assert res.fwd.node_count > 200
    for name in ("node_time", "forward_std", "smoothed_std", "forward_sensors",
                 "smoothed_sensors"):
        assert np.array_equal(getattr(res, name), getattr(ref, name)), name
    assert np.array_equal(res.node_solution(), ref.node_solution())
    for name in ("nis", "nis_record", "innovation_m", "node_rows", "dx"):
        assert np.array_equal(getattr(res.fwd, name), getattr(ref.fwd, name)), name
    a, b = res.smoothed, ref.smoothed
    assert np.array_equal(a.lla, b.lla) and np.array_equal(a.q_nb, b.q_nb)
    ra, rb = list(res.fwd.records), list(ref.fwd.records)
    assert len(ra) == len(rb) > 200
    assert all(x.time == y.time and np.array_equal(x.innovation, y.innovation)
               for x, y in zip(ra, rb))
    assert res.quality == ref.quality
