"""The supernodal Cholesky factorisation against the definition of the Cholesky factor.

The factor of a symmetric positive definite matrix with a positive diagonal is unique, so the supernodal
factor of ``P A P'`` must equal numpy's dense Cholesky of the same permuted matrix, entry for entry, on
patterns that exercise every path: single columns and wide supernodes, relaxed merges (explicit zeros),
updates scattered and written in place, jobs (subtrees) and the levels above them, the gathering split
into column blocks and the rows below into row blocks.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse

from hairinv.solver import supernodal
from hairinv.solver.supernodal import SupernodalCholesky


def _lower(A):
    low = scipy.sparse.tril(scipy.sparse.csc_matrix(A), format="csc")
    low.sort_indices()
    return low.indptr.astype(np.int64), low.indices.astype(np.int64), low.data.copy()


def _dense_factor(f: SupernodalCholesky) -> np.ndarray:
    """The factor ``L`` (in the permuted order) read out of the supernodes' panels."""
    L = np.zeros((f.n, f.n))
    for s in range(f.supernodes):
        lo, hi = int(f.super_ptr[s]), int(f.super_ptr[s + 1])
        ns = hi - lo
        below = f.rows[f.rows_ptr[s]:f.rows_ptr[s + 1]]
        index = np.concatenate([np.arange(lo, hi), below])
        panel = f.X[f.x_ptr[s]:f.x_ptr[s + 1]].reshape(ns, len(index)).T
        for c in range(ns):
            L[index[c:], lo + c] = panel[c:, c]
    return L


def _strands(rng, strands: int, per: int, couplings: int) -> np.ndarray:
    """A matrix shaped like the interior point's: each strand's coordinates densely coupled up to an
    element (a contact near the tip couples the whole strand up to it), strands coupled in pairs."""
    n = strands * per
    A = np.eye(n)
    for k in range(couplings):
        a, b = rng.integers(0, strands, 2)
        ea, eb = rng.integers(1, per + 1, 2)
        cols = np.concatenate([a * per + np.arange(ea), b * per + np.arange(eb)])
        g = rng.standard_normal((len(cols), 3))
        A[np.ix_(cols, cols)] += g @ g.T
    return A


def _grid(side: int) -> np.ndarray:
    """A 2D Laplacian plus the identity: wide separators under nested dissection."""
    T = scipy.sparse.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(side, side))
    I = scipy.sparse.eye(side)
    return (scipy.sparse.kron(T, I) + scipy.sparse.kron(I, T) + 0.1 * scipy.sparse.eye(side * side)).toarray()


def _cases():
    rng = np.random.default_rng(7)
    yield "one", np.array([[4.0]]), np.array([0])
    yield "diagonal", np.diag(rng.uniform(1, 2, 40)), rng.permutation(40)
    d = rng.standard_normal((30, 30))
    yield "dense", d @ d.T + 30 * np.eye(30), rng.permutation(30)
    arrow = np.eye(50) * 60
    arrow[0, :] = arrow[:, 0] = 1.0
    arrow[0, 0] = 60.0
    yield "arrow", arrow, np.arange(50)
    yield "strands", _strands(rng, 40, 12, 120), rng.permutation(480)
    A = _strands(rng, 60, 24, 400)
    yield "strands natural", A, np.arange(A.shape[0])
    G = _grid(24)
    order = supernodal_order(G)
    yield "grid", G, order


def supernodal_order(A):
    from hairinv.solver.interior import nested_dissection

    order = nested_dissection(scipy.sparse.csr_matrix(A))
    return np.arange(A.shape[0]) if order is None else order


@pytest.mark.parametrize("name,A,order", list(_cases()), ids=[c[0] for c in _cases()])
def test_the_factor_is_the_cholesky_factor(name, A, order):
    Sp, Si, Sx = _lower(A)
    f = SupernodalCholesky(Sp, Si, order)
    f.factor(Sx)
    P = A[np.ix_(f.perm, f.perm)]
    expected = np.linalg.cholesky(P)
    got = _dense_factor(f)
    assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected))
    # the permutation is the given ordering, postordered: a permutation of every row
    assert np.array_equal(np.sort(f.perm), np.arange(A.shape[0]))
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    x = f.solve(b)
    assert np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b) * np.linalg.cond(A)
    # new values in the same pattern: factored again from the values alone
    Sx2 = Sx * 2.0
    f.factor(Sx2)
    assert np.max(np.abs(_dense_factor(f) - np.sqrt(2.0) * expected)) <= 1e-12 * np.max(np.abs(expected))


def test_the_pieces_split_panels_and_the_bits_do_not_depend_on_the_thread_count(monkeypatch):
    """Blocks small enough that the gathering is split into column blocks, the rows below into row blocks
    and several jobs run at once; the factor is the dense one, and the same to the bit on 1 and 3 threads."""
    monkeypatch.setattr(supernodal, "_COLUMNS_PER_TASK", 5)
    monkeypatch.setattr(supernodal, "_ROWS_PER_TASK", 7)
    A = _grid(20)
    order = supernodal_order(A)
    Sp, Si, Sx = _lower(A)
    bits = []
    for threads in ("1", "3"):
        monkeypatch.setenv("HAIRINV_THREADS", threads)
        f = SupernodalCholesky(Sp, Si, order)
        assert len(f.jobs) > 1 and len(f.level_ptr) > 2
        assert np.any(np.diff(f.node_ptr) > 2)  # some supernode is more than one piece of each kind
        f.factor(Sx)
        bits.append((_dense_factor(f), f.solve(np.arange(A.shape[0], dtype=float))))
    assert np.array_equal(bits[0][0], bits[1][0]) and np.array_equal(bits[0][1], bits[1][1])
    expected = np.linalg.cholesky(A[np.ix_(f.perm, f.perm)])
    assert np.max(np.abs(_dense_factor(f) - expected)) <= 1e-12 * np.max(np.abs(expected))


def test_the_bits_do_not_depend_on_the_thread_count_at_sizes_blas_would_thread(monkeypatch):
    """Default pieces on a system whose top supernodes are large enough for OpenBLAS to thread its calls
    (which would round differently): the factor and a solve are the same to the bit on 1 and 2 threads."""
    A = scipy.sparse.csc_matrix(_grid(60))
    order = supernodal_order(A.toarray())
    low = scipy.sparse.tril(A, format="csc")
    low.sort_indices()
    bits = []
    for threads in ("1", "2"):
        monkeypatch.setenv("HAIRINV_THREADS", threads)
        f = SupernodalCholesky(low.indptr.astype(np.int64), low.indices.astype(np.int64), order)
        assert np.max(np.diff(f.super_ptr)) >= 60  # a separator's supernode: dpotrf and dgemm on real blocks
        f.factor(low.data.copy())
        bits.append((f.X.copy(), f.solve(np.ones(A.shape[0]))))
    assert np.array_equal(bits[0][0], bits[1][0]) and np.array_equal(bits[0][1], bits[1][1])
    x = bits[0][1]
    assert np.linalg.norm(A @ x - 1.0) <= 1e-12 * np.sqrt(A.shape[0]) * 1e3


def test_a_matrix_that_is_not_positive_definite_is_refused():
    A = _grid(8)
    A[20, 20] = -5.0
    Sp, Si, Sx = _lower(A)
    f = SupernodalCholesky(Sp, Si, np.arange(A.shape[0]))
    with pytest.raises(ArithmeticError, match="non-positive pivot"):
        f.factor(Sx)
    # and the next values factor cleanly
    f.factor(_lower(_grid(8))[2])
    assert np.allclose(_dense_factor(f) @ _dense_factor(f).T, _grid(8)[np.ix_(f.perm, f.perm)], atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_weighted_column_counts_are_those_of_the_expanded_pattern(seed):
    """Nodes standing for cliques of indistinguishable unknowns (``weight`` each, eliminated one after the
    other): the weighted counts give the same ``sum c^2`` as a dense Cholesky of a matrix of the expanded
    pattern, under a random order of the nodes."""
    rng = np.random.default_rng(seed)
    m = 40
    weight = rng.integers(1, 5, m).astype(np.int64)
    adjacency = np.triu(rng.random((m, m)) < 0.08, 1)
    adjacency = adjacency | adjacency.T | np.eye(m, dtype=bool)
    node_order = rng.permutation(m)
    # the expanded matrix, in the order the nodes' order expands to
    starts = np.r_[0, np.cumsum(weight)]
    order = np.concatenate([np.arange(starts[k], starts[k + 1]) for k in node_order])
    owner = np.repeat(np.arange(m), weight)
    A = adjacency[np.ix_(owner, owner)] * rng.uniform(0.1, 1.0, (len(owner),) * 2)
    A = A + A.T
    A += np.diag(np.abs(A).sum(axis=1) + 1.0)
    L = np.linalg.cholesky(A[np.ix_(order, order)])
    dense = float(np.sum(np.count_nonzero(L, axis=0).astype(float) ** 2))
    inv = np.empty(m, np.int64)
    inv[node_order] = np.arange(m)
    Sp, Si, _ = _lower(adjacency.astype(float))
    Up, Ui, _, _, _ = supernodal.permuted_pattern(m, Sp, Si, inv)
    w = weight[node_order]
    counts = supernodal.column_counts(m, supernodal.etree(m, Up, Ui), Up, Ui, np.inf, w)
    assert supernodal.expanded_flops(counts, w) == dense
    # the early stop: never below the count, and only once the count passes the limit
    assert len(supernodal.column_counts(m, supernodal.etree(m, Up, Ui), Up, Ui, dense, w)) == m
    assert len(supernodal.column_counts(m, supernodal.etree(m, Up, Ui), Up, Ui, dense / len(order), w)) == 0
