"""The interior point's system ``I + G B G'`` laid out and assembled by blocks (:mod:`hairinv.solver.blocked`),
against its definition: the pattern of ``I + H'H`` from the contacts' incidence, and the values of a dense
product built column by column (a contact's repeated columns added, as ``G`` adds them)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse

from hairinv.solver.blocked import BlockedSystem


def _strand_contacts(rng, strands: int, contacts: int, same: bool):
    """Contacts shaped like the rows': each side the leading coordinates of a strand (up to an element),
    a second side on six in ten; ``same``: some with both sides on one strand."""
    offsets = np.r_[0, np.cumsum(rng.integers(1, 12, strands))]
    ptr, cols = [0], []
    for _ in range(contacts):
        a = rng.integers(strands)
        side = list(range(3 * offsets[a], 3 * (offsets[a] + rng.integers(1, offsets[a + 1] - offsets[a] + 1))))
        if rng.random() < 0.6:
            b = a if same and rng.random() < 0.3 else rng.integers(strands)
            side += list(range(3 * offsets[b], 3 * (offsets[b] + rng.integers(1, offsets[b + 1] - offsets[b] + 1))))
        cols += side
        ptr.append(len(cols))
    return np.array(ptr), np.array(cols), 3 * int(offsets[-1]) + 4  # four coordinates no contact touches


def _any_columns(rng, n: int, contacts: int):
    ptr, cols = [0], []
    for _ in range(contacts):
        cols += list(np.unique(rng.integers(0, n, rng.integers(1, 20))))
        ptr.append(len(cols))
    return np.array(ptr), np.array(cols), n


def _cases():
    rng = np.random.default_rng(11)
    yield "strands", _strand_contacts(rng, 60, 400, False)
    yield "strands, both sides on one", _strand_contacts(rng, 20, 150, True)
    yield "consecutive strands", (np.array([0, 9, 15]), np.array([3, 4, 5, 6, 7, 8, 0, 1, 2, 6, 7, 8, 9, 10, 11]), 15)
    yield "any columns", _any_columns(rng, 300, 200)
    yield "every column", (np.arange(5) * 30, np.tile(np.arange(30), 4), 30)
    wide = np.r_[np.arange(120), np.arange(150, 240), np.arange(0, 90)]  # pieces over the kernel's 64 columns
    yield "wide pieces", (np.array([0, len(wide), len(wide) + 30]), np.r_[wide, np.arange(150, 180)], 260)


@pytest.mark.parametrize("name,case", list(_cases()), ids=[c[0] for c in _cases()])
def test_the_blocked_system_is_the_product(name, case):
    ptr, cols, n = case
    C = len(ptr) - 1
    system = BlockedSystem(ptr, cols, n)
    counts = np.diff(ptr)
    incidence = scipy.sparse.csr_matrix((np.ones(len(cols)), (np.repeat(np.arange(C), counts), cols)), shape=(C, n))
    pattern = scipy.sparse.tril((incidence.T @ incidence + scipy.sparse.eye(n)).tocsc(), format="csc")
    pattern.sort_indices()
    assert np.array_equal(system.Sp, pattern.indptr) and np.array_equal(system.Si, pattern.indices)
    rng = np.random.default_rng(len(cols))
    g = rng.standard_normal((len(cols), 3))
    M = rng.standard_normal((C, 3, 3))
    Binv = M @ M.transpose(0, 2, 1)
    G = np.zeros((n, 3 * C))
    for i in range(C):
        np.add.at(G, (cols[ptr[i]:ptr[i + 1]], slice(3 * i, 3 * i + 3)), g[ptr[i]:ptr[i + 1]])
    expected = np.eye(n) + G @ scipy.linalg.block_diag(*Binv) @ G.T
    Sx = np.full(system.entries, np.nan)  # every entry written, none left over
    for _ in range(2):  # assembled again over the last values
        system.assemble(g, Binv, Sx)
        lower = scipy.sparse.csc_matrix((Sx, system.Si, system.Sp), shape=(n, n)).toarray()
        assert np.allclose(lower, np.tril(expected), rtol=1e-13, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("seed", range(3))
def test_the_orderings_are_counted_exactly_where_coordinates_go_untouched(seed):
    """Strands whose tails no contact reaches (and whole coordinates none touches): each candidate ordering's
    count, made on groups of coordinates, equals the fill of a dense Cholesky of a matrix of the same pattern
    under that ordering."""
    from hairinv.solver import interior

    ptr, cols, n = _strand_contacts(np.random.default_rng(seed), 25, 60, seed == 2)
    factor = interior._Factor(ptr, cols, n, "supernodal")
    lower = scipy.sparse.csc_matrix((np.ones(len(factor.Si)), factor.Si, factor.Sp), shape=(n, n))
    full = (lower + lower.T).toarray() * np.random.default_rng(seed).uniform(0.1, 1.0, (n, n))
    full = full + full.T
    full += np.diag(np.abs(full).sum(axis=1) + 1.0)
    assert np.any(np.asarray(lower.sum(axis=0)).ravel() == 1)  # some coordinates have the diagonal only
    for name, (order, flops) in factor.candidates.items():
        L = np.linalg.cholesky(full[np.ix_(order, order)])
        dense = float(np.sum(np.count_nonzero(L, axis=0).astype(float) ** 2))
        assert flops == dense or (flops == np.inf and dense > factor.flops), name
