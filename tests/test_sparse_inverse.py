"""Selected inversion of a sparse L D L' factor (photogrammetry.adjustment.banded.SparseSPD) against
numpy's dense inverse, and the pattern check it relies on."""
import numpy as np
import pytest
from scipy import sparse

from photogrammetry.adjustment._sparse_kernels import pattern_is_closed
from photogrammetry.adjustment.banded import SparseSPD


def _grid_spd(nx, ny, seed):
    """SPD matrix of a 2-D grid graph with a few long-range couplings (fill-in)."""
    rng = np.random.default_rng(seed)
    n = nx * ny
    idx = np.arange(n).reshape(nx, ny)
    rows = np.concatenate([idx[:-1].ravel(), idx[:, :-1].ravel(),
                           rng.integers(0, n, 20)])
    cols = np.concatenate([idx[1:].ravel(), idx[:, 1:].ravel(), rng.integers(0, n, 20)])
    keep = rows != cols
    w = rng.uniform(0.5, 2.0, keep.sum())
    B = sparse.coo_matrix((w, (rows[keep], cols[keep])), shape=(n, n))
    B = B + B.T
    deg = np.asarray(abs(B).sum(axis=1)).ravel()
    return sparse.csc_matrix(sparse.diags(deg + rng.uniform(0.1, 1.0, n)) - B)


def test_inverse_entries_match_dense_inverse():
    A = _grid_spd(12, 15, 1)
    f = SparseSPD(A)
    assert f.has_selected_inverse()
    Z = np.linalg.inv(A.toarray())
    coo = sparse.tril(A).tocoo()                  # every coupled pair lies on the pattern
    got = f.inverse_entries(coo.row, coo.col)
    np.testing.assert_allclose(got, Z[coo.row, coo.col], rtol=1e-10,
                               atol=1e-12 * np.abs(Z).max())
    np.testing.assert_allclose(f.inverse_entries(coo.col, coo.row), got)   # symmetric


def test_diagonal_blocks_match_dense_inverse():
    A = _grid_spd(9, 10, 2)                       # 90 unknowns: 30 blocks of 3
    # couple each 3-group fully so the blocks lie on the pattern
    g = np.arange(90) // 3
    A = sparse.csc_matrix(A + sparse.csc_matrix(0.01 * (g[:, None] == g[None, :])))
    f = SparseSPD(A)
    Z = np.linalg.inv(A.toarray())
    ref = np.stack([Z[3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(30)])
    np.testing.assert_allclose(f.diagonal_blocks(3), ref, rtol=1e-10)


def test_entry_outside_the_pattern_is_refused():
    A = sparse.csc_matrix(sparse.diags([4.0, 4.0, 4.0, 4.0]) + sparse.csc_matrix(
        ([1.0, 1.0], ([0, 1], [1, 0])), shape=(4, 4)))
    f = SparseSPD(A)
    assert f.inverse_entries([0], [1])[0] == pytest.approx(-1.0 / 15.0)
    with pytest.raises(ValueError, match="outside the pattern"):
        f.inverse_entries([0], [3])


def test_pattern_check():
    # column 0: rows 2, 3; column 2 (its parent): row 3 -> closed
    closed = sparse.csc_matrix(([1.0, 1.0, 1.0], ([2, 3, 3], [0, 0, 2])), shape=(4, 4))
    assert pattern_is_closed(closed.indptr, closed.indices, 4)
    # column 2 without row 3: (3, 2) is missing, the inverse would read it
    open_ = sparse.csc_matrix(([1.0, 1.0], ([2, 3], [0, 0])), shape=(4, 4))
    assert not pattern_is_closed(open_.indptr, open_.indices, 4)


def test_same_pattern_reuses_the_ordering_with_the_same_results():
    """A second matrix of the same pattern (new values: the next Gauss-Newton iterate)
    is factored in the first one's minimum-degree order: solves and inverse entries
    against numpy's dense ones, and the fill of the first factor."""
    A = _grid_spd(11, 13, 3)
    B = A.copy()
    B.data = B.data * np.random.default_rng(4).uniform(0.8, 1.2, B.nnz)
    B = (B + B.T) / 2 + sparse.diags(np.abs(B).sum(axis=1).A1)   # SPD, same pattern
    B = sparse.csc_matrix(B)
    f = SparseSPD(A)
    g = SparseSPD(B)
    assert g.order is not None and g.nnz == f.nnz       # the ordering reused, same fill
    rhs = np.random.default_rng(5).normal(size=(B.shape[0], 2))
    np.testing.assert_allclose(g.solve(rhs), np.linalg.solve(B.toarray(), rhs), rtol=1e-9,
                               atol=1e-12)
    Z = np.linalg.inv(B.toarray())
    coo = sparse.tril(B).tocoo()
    np.testing.assert_allclose(g.inverse_entries(coo.row, coo.col), Z[coo.row, coo.col],
                               rtol=1e-9, atol=1e-12 * np.abs(Z).max())


def test_inverse_form_matches_dense_solve():
    """``B' A^-1 B`` by the sparse half solve ``Y = L^-1 Q B`` and ``Y' D^-1 Y``
    (:meth:`SparseSPD.inverse_form`, both its sparse and its dense rows) against numpy's
    dense solve, with A's own ordering and with the ordering reused for its pattern."""
    A = _grid_spd(14, 16, 5)
    n = A.shape[0]
    rng = np.random.default_rng(6)
    B = sparse.random(n, 37, density=0.03, random_state=7, format="csc")
    B = B + sparse.csc_matrix((rng.normal(size=37), (rng.integers(0, n, 37),
                                                      np.arange(37))), shape=(n, 37))
    ref = B.T.toarray() @ np.linalg.solve(A.toarray(), B.toarray())
    for _ in range(2):                        # the second factor reuses the ordering
        got = SparseSPD(A).inverse_form(B)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_array_equal(got, got.T)


@pytest.mark.parametrize("panel", [1, 5, 32, 64])
def test_gram_rows_and_lower_solve_against_numpy(panel):
    """The compiled kernels against numpy: ``Y' diag(w) Y`` of a sparse ``Y`` with empty
    and full rows (any panel width, one that does not divide k), and ``L^-1 B`` of a
    unit lower triangular ``L`` with unsorted rows and duplicate entries in ``B``."""
    from photogrammetry.adjustment._sparse_kernels import gram_rows, lower_solve_sparse
    rng = np.random.default_rng(panel)
    Y = sparse.random(60, 23, density=0.2, random_state=panel, format="lil")
    Y[5, :] = 0.0
    Y[7, :] = rng.normal(size=23)
    Y = sparse.csr_matrix(Y)
    Y.sort_indices()
    w = rng.uniform(0.5, 2.0, 60)
    G = gram_rows(Y.indptr, Y.indices, Y.data, w, 23, panel)
    Yd = Y.toarray()
    np.testing.assert_allclose(G, Yd.T @ (w[:, None] * Yd), rtol=1e-13, atol=1e-14)
    n = 40
    L = sparse.tril(sparse.random(n, n, density=0.1, random_state=3), k=-1, format="csc")
    perm = rng.permutation(L.nnz)             # rows unsorted within columns
    cols = np.repeat(np.arange(n), np.diff(L.indptr))
    order = np.lexsort((perm, cols))
    Lu = sparse.csc_matrix((L.data[order], L.indices[order], L.indptr), shape=(n, n))
    r, c = rng.integers(0, n, 30), rng.integers(0, 6, 30)
    B = sparse.coo_matrix((rng.normal(size=30), (r, c)), shape=(n, 6)).tocsc()
    B.has_canonical_format = False
    B = sparse.csc_matrix((np.repeat(B.data, 2) / 2, np.repeat(B.indices, 2),
                           2 * B.indptr), shape=(n, 6))   # every entry split in two
    yp, yi, yx = lower_solve_sparse(Lu.indptr, Lu.indices, Lu.data, B.indptr, B.indices,
                                    B.data, n)
    got = sparse.csc_matrix((yx, yi, yp), shape=(n, 6)).toarray()
    ref = np.linalg.solve(np.eye(n) + L.toarray(), B.toarray())
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    assert np.all(np.diff(yi[yp[0]:yp[1]]) > 0)              # rows sorted


def test_cholmod_factor_solves_like_numpy():
    """The optional CHOLMOD factor (cvxopt) against numpy's dense solve, a vector and a
    matrix right-hand side, and its refusal of a matrix that is not positive definite."""
    pytest.importorskip("cvxopt")
    from ins.common.errors import InputError
    from photogrammetry.adjustment.cholmod import CholmodSPD
    A = _grid_spd(11, 13, 8)
    rng = np.random.default_rng(9)
    b = rng.normal(size=(A.shape[0], 3))
    f = CholmodSPD(A)
    ref = np.linalg.solve(A.toarray(), b)
    np.testing.assert_allclose(f.solve(b), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(f.solve(b[:, 0]), ref[:, 0], rtol=0,
                               atol=1e-12 * np.abs(ref).max())
    with pytest.raises(InputError, match="not positive definite"):
        CholmodSPD(A - 10 * sparse.eye(A.shape[0]), what="test matrix")
