"""The compiled (Cython) mechanization and filter kernels accept what their callers pass:
strided and read-only arrays give the same numbers as contiguous copies, node rows of
any integer type, and wrong shapes raise ValueError instead of reading out of bounds.
(Their numbers against a truth: tests/test_mechanization.py, tests/test_error_model.py.)"""
import numpy as np
import pytest

from ins.estimation.core import _filter_kernels as F
from ins.nav import _kernels as K


def _log(n=400, seed=3):
    rng = np.random.default_rng(seed)
    t = 1000.0 + 0.005 * np.arange(n)
    table = np.column_stack([t, rng.normal(0, 1e-4, (n, 3)),
                             rng.normal(0, 1e-3, (n, 3)) + [0.0, 0.0, -9.8 * 0.005]])
    state = np.array([0.5, 2.0, 300.0, 50.0, -20.0, 1.0, 0.1, -0.2, 0.3, 0.0])
    state[9] = np.sqrt(1.0 - np.sum(state[6:9] ** 2))
    return table, state


def test_strided_and_read_only_inputs_match_contiguous():
    table, s0 = _log()
    table.flags.writeable = False
    n = len(table)
    t, th, dv = table[:, 0], table[:, 1:4], table[:, 4:7]          # strided, read-only
    assert not th.flags.c_contiguous and not th.flags.writeable
    tc, thc, dvc = (np.ascontiguousarray(a) for a in (t, th, dv))
    out_a, out_b = np.empty((n - 1, 10)), np.empty((n - 1, 10))
    sa, sb = s0.copy(), s0.copy()
    K.mechanize_rows(t, th, dv, 1, n, sa, out_a)
    K.mechanize_rows(tc, thc, dvc, 1, n, sb, out_b)
    assert np.array_equal(out_a, out_b) and np.array_equal(sa, sb)
    assert np.array_equal(sa, out_a[-1])
    assert not np.array_equal(out_a[0], s0)                           # it moved
    sens = np.linspace(-1e-5, 1e-5, 12)
    mis = np.linspace(1e-4, 3e-4, 6)
    acc_a, acc_b = np.zeros((16, 3)), np.zeros((16, 3))
    sa, sb = s0.copy(), s0.copy()
    F.propagate_rows_mis(t, th, dv, 1, n, sa, sens, mis, out_a, acc_a)
    F.propagate_rows_mis(tc, thc, dvc, 1, n, sb, sens, mis, out_b, acc_b)
    assert np.array_equal(out_a, out_b) and np.array_equal(acc_a, acc_b)
    # a state that is a strided row (a column slice of a wider table) is updated in place
    wide = np.zeros((2, 12))
    wide[0, 1:11] = s0
    view = wide[0, 1:11]
    d = np.array([1.0, -2.0, 0.5, 0.1, 0.2, -0.1, 1e-5, -2e-5, 3e-5])
    ref = s0.copy()
    F.correct_state(ref, d)
    F.correct_state(view, d)
    assert np.array_equal(view, ref) and wide[0, 0] == 0.0 and wide[0, 11] == 0.0


def test_correct_rows_node_rows_of_any_integer_type():
    table, s0 = _log()
    n = len(table)
    traj = np.empty((n - 1, 10))
    K.mechanize_rows(table[:, 0], table[:, 1:4], table[:, 4:7], 1, n, s0.copy(), traj)
    nodes = np.arange(0, n, 50)
    rng = np.random.default_rng(1)
    xa, xb = rng.normal(0, 0.01, (len(nodes), 21)), rng.normal(0, 0.01, (len(nodes), 21))
    time = table[1:, 0]
    a, b = traj[100:300].copy(), traj[100:300].copy()
    F.correct_rows(a, time[100:300], 100, nodes.astype(np.int64), table[nodes, 0], xa, xb)
    F.correct_rows(b, time[100:300], 100, nodes.astype(np.int32), table[nodes, 0], xa, xb)
    assert np.array_equal(a, b)
    # a node row gets x_after exactly: the same as correct_state with it
    ref = traj[150].copy()
    F.correct_state(ref, xa[3])
    assert np.array_equal(a[50], ref)


def test_wrong_shapes_raise():
    table, s0 = _log(10)
    t, th, dv = table[:, 0], table[:, 1:4], table[:, 4:7]
    out = np.empty((9, 10))
    with pytest.raises(ValueError, match="rows"):
        K.mechanize_rows(t, th, dv, 1, 11, s0.copy(), np.empty((10, 10)))
    with pytest.raises(ValueError, match="same number of rows"):
        K.mechanize_rows(t[:-1], th, dv, 1, 9, s0.copy(), out)
    with pytest.raises(ValueError, match="state"):
        K.mechanize_rows(t, th, dv, 1, 10, s0[:9].copy(), out)
    with pytest.raises(ValueError, match="acc"):
        F.propagate_rows_mis(t, th, dv, 1, 10, s0.copy(), np.zeros(12), np.zeros(6), out,
                             np.zeros((10, 3)))
    with pytest.raises(ValueError, match="out"):
        F.propagate_rows(t, th, dv, 1, 10, s0.copy(), np.zeros(12), out[:5], np.zeros((10, 3)))
    with pytest.raises(ValueError):
        F.correct_state(s0.copy(), np.zeros(8))
    with pytest.raises(ValueError):
        K.quat_to_dcm_rows(0.0, 0.0, 0.0, 1.0, np.empty(8))
