"""The native bordered banded solver (solvers/bordered_native.py) against dense linear
algebra (NumPy's LAPACK gesv) and LAPACK's banded LU (dgbtrf).

Systems are assembled through ``add_block`` from random element blocks as an FE assembly
does: blocks of consecutive dofs overlapping along a chain for the big beam (the band) and
for the other beams (the border), and contact-like blocks joining a band dof set to a
border dof set. Entries are standard normal, not diagonally dominant (asserted), with a
few diagonal entries set to exactly zero, so that partial pivoting is needed (asserted:
rows are interchanged).

Tolerances. LU with partial pivoting is backward stable: the computed x solves a matrix
within about n eps g of K (g the growth factor, a few here), so the relative residual
|K x - b| / |b| is about n eps g cond(K) at worst and a few eps in practice; block
elimination adds the same with cond(A) of the pivot block (it pivots within A only). Two
backward stable solutions then differ by about cond(K) times their backward errors: with
cond(K), cond(A) < 1e4 (random band matrices have a heavy tail of condition numbers, so
the accuracy cases are the seeds below that; at least 3 of 10 per case, asserted) and
backward errors of a few eps, 1e-12 and 1e-10 keep margins of 10 and more with typical
error growth. Observed: residual < 4e-14, agreement < 5e-14 (NumPy's own residual is
below 1e-14); an error in an index or a missed interchange gives O(1).
"""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sla

from beamcontact.assembly.system import apply_supports
from beamcontact.solvers import bordered_native as bn

RES_TOL = 1e-12
REL_TOL = 1e-10
MAX_COND = 1e4

# (n_b, kl, ku, m): the paper's two beams (p = 4: kl = ku = 9; long beam 96-250 dofs, short
# one 20-60), other degrees (p = 2, 3), kl != ku, one beam (m = 0), no band (n_b = 0), a
# diagonal band, a band wider than the block, a single border dof
CASES = [(96, 9, 9, 0), (96, 9, 9, 20), (176, 9, 9, 60), (250, 9, 9, 60), (60, 5, 5, 12),
         (120, 7, 7, 30), (150, 4, 9, 25), (150, 9, 3, 25), (0, 9, 9, 40), (1, 0, 0, 1),
         (8, 9, 9, 5), (40, 0, 0, 10), (40, 0, 3, 10), (200, 9, 9, 1), (30, 2, 6, 0)]


def _ids(case):
    return "n_b{}-kl{}-ku{}-m{}".format(*case)


def _chain(first, count, width, stride):
    """Dof sets of consecutive dofs along a chain: [first + s, first + s + width) for s in
    steps of ``stride``, the last one flush with the end."""
    width = min(width, count)
    if width == 0:
        return []
    starts = list(range(0, count - width + 1, min(stride, width)))
    if starts[-1] != count - width:
        starts.append(count - width)
    return [first + s + np.arange(width) for s in starts]


def _blocks(n_b, kl, ku, m, seed, zero_diagonal=True):
    """Random element blocks (list of (dofs, k_local)) of a bordered system: band blocks
    of max(kl, ku) + 1 consecutive dofs (2 (p + 1) for kl = ku = 2 (p + 1) - 1) with the
    entries outside (kl, ku) zero, border blocks of 6 dofs (p = 2), and coupling blocks of
    a band set and a border set; then blocks that cancel some diagonal entries exactly
    (x + (-x) = 0 in floating point)."""
    rng = np.random.default_rng(seed)
    blocks = []
    for d in _chain(0, n_b, max(kl, ku) + 1, 2):
        k = rng.standard_normal((len(d), len(d))) + 2.0 * np.eye(len(d))
        diff = d[:, None] - d[None, :]
        k[(diff > kl) | (-diff > ku)] = 0.0
        blocks.append((d, k))
    for d in _chain(n_b, m, 6, 2):
        blocks.append((d, rng.standard_normal((len(d), len(d))) + 2.0 * np.eye(len(d))))
    if n_b and m:
        width = min(min(kl, ku) + 1, 6, n_b)
        for _ in range(4):
            a = rng.integers(0, n_b - width + 1)
            b = rng.integers(0, m - min(6, m) + 1)
            d = np.concatenate([a + np.arange(width), n_b + b + np.arange(min(6, m))])
            blocks.append((d, rng.standard_normal((len(d), len(d)))))
    if zero_diagonal:
        # not where no interchange can help: a diagonal band (kl = 0), a single border dof
        K = _dense(n_b + m, blocks)
        for i in range(0, n_b + m, 10):
            if (kl > 0) if i < n_b else (m > 1):
                blocks.append((np.array([i]), np.array([[-K[i, i]]])))
    return [(d.astype(np.int64), k) for d, k in blocks]


def _dense(n, blocks):
    K = np.zeros((n, n))
    for d, k in blocks:
        np.add.at(K, (d[:, None], d[None, :]), k)
    return K


def _assemble(n_b, kl, ku, m, blocks):
    arrays = bn.allocate(bn.layout(n_b, kl, ku, m))
    for d, k in blocks:
        bn.add_block(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, d, k)
    return arrays


def _system(case, seed=0, **kwargs):
    """(arrays, dense K, rhs) of a random case."""
    n_b, kl, ku, m = case
    blocks = _blocks(n_b, kl, ku, m, seed, **kwargs)
    rhs = np.random.default_rng(seed + 1000).standard_normal(n_b + m)
    return _assemble(n_b, kl, ku, m, blocks), _dense(n_b + m, blocks), rhs


def _factor_solve(arrays, kl, ku, rhs):
    x = np.empty_like(rhs)
    info = bn.factor_solve(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, arrays.ipiv,
                           arrays.ipiv_s, rhs, x)
    return info, x


def _residual(K, x, b):
    return float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))


def _rel(x, ref):
    return float(np.linalg.norm(x - ref) / np.linalg.norm(ref))


# ---------------------------------------------------------------- layout and assembly

def test_layout_shapes_and_band_widths():
    lay = bn.layout(176, 9, 7, 60)
    assert lay.n == 236 and lay.ldab == 2 * 9 + 7 + 1
    arrays = bn.allocate(lay)
    for name, shape in lay.shapes.items():
        a = getattr(arrays, name)
        assert a.shape == shape
        assert a.dtype == (np.int64 if name.startswith("ipiv") else np.float64)
    # one beam of degree p, x and y interleaved: half bandwidth 2 (p + 1) - 1
    for p in (2, 3, 4):
        dofs = np.array(_chain(0, 100, 2 * (p + 1), 2))
        assert bn.band_widths(dofs, 100) == (2 * p + 1, 2 * p + 1)
    # border positions do not count
    assert bn.band_widths(np.array([[0, 3, 120, 130]]), 100) == (3, 3)
    with pytest.raises(ValueError):
        bn.layout(10, -1, 2, 0)


@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_assembly_equals_dense_scatter(case):
    """Every entry lands in its place: the stored system is the dense scatter-add, bit for
    bit (the same additions in the same order); K x too, to round-off."""
    n_b, kl, ku, m = case
    arrays, K, rhs = _system(case)
    A = bn.to_dense(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku)
    assert np.array_equal(A, K)
    assert np.all(arrays.band[:, :kl] == 0.0)  # the fill-in rows stay free for the LU
    y = np.empty_like(rhs)
    bn.matvec(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, rhs, y)
    assert np.max(np.abs(y - K @ rhs)) <= 1e-14 * np.max(np.abs(K) @ np.abs(rhs))
    # the batched scatter is the same
    blocks = _blocks(n_b, kl, ku, m, 0, zero_diagonal=False)
    same = [(d, k) for d, k in blocks if len(d) == len(blocks[0][0])]
    dofs = np.array([d for d, _ in same])
    ks = np.array([k for _, k in same])
    one, many = bn.allocate(bn.layout(*case)), bn.allocate(bn.layout(*case))
    for d, k in same:
        bn.add_block(one.band, one.B, one.C, one.D, kl, ku, d, k)
    bn.add_blocks(many.band, many.B, many.C, many.D, kl, ku, dofs, ks)
    for a, b in zip(one[:4], many[:4], strict=True):
        assert np.array_equal(a, b)
    bn.zero(many.band, many.B, many.C, many.D)
    assert all(np.all(a == 0.0) for a in many[:4])


def test_add_blocks_of_every_kind_is_add_block_of_each():
    """Blocks within the band (at its full width, which the unchecked path must leave to
    the checked one when the widths differ), within the border, across both (contact) and
    padded (zeros at position 0), each with zero entries: add_blocks stores what
    add_block does one block at a time, bit for bit."""
    rng = np.random.default_rng(7)
    n_b, kl, ku, m = 30, 5, 3, 8
    dofs = np.array([[4, 5, 6, 7], [10, 11, 13, 14], [31, 32, 34, 37], [2, 3, 32, 33],
                     [0, 0, 20, 21], [12, 13, 14, 15], [30, 31, 32, 33]], dtype=np.int64)
    ks = rng.standard_normal((len(dofs), 4, 4))
    ks[rng.random(ks.shape) < 0.2] = 0.0
    ks[4, :2, :] = ks[4, :, :2] = 0.0  # padding entries carry exact zeros
    ks[1][dofs[1][None, :] - dofs[1][:, None] > ku] = 0.0  # within kl below, ku above
    one, many = bn.allocate(bn.layout(n_b, kl, ku, m)), bn.allocate(bn.layout(n_b, kl, ku, m))
    for d, k in zip(dofs, ks, strict=True):
        bn.add_block(one.band, one.B, one.C, one.D, kl, ku, d, k)
    bn.add_blocks(many.band, many.B, many.C, many.D, kl, ku, dofs, ks)
    for a, b in zip(one[:4], many[:4], strict=True):
        assert np.array_equal(a, b)
    assert np.count_nonzero(many.B) and np.count_nonzero(many.D)


def test_add_block_rejects_what_it_cannot_store():
    arrays = bn.allocate(bn.layout(20, 2, 3, 4))
    args = (arrays.band, arrays.B, arrays.C, arrays.D, 2, 3)
    # zeros outside the band are skipped (padding, structurally asymmetric blocks)
    k = np.zeros((5, 5))
    k[0, 0] = 1.0
    bn.add_block(*args, np.arange(5, dtype=np.int64), k)
    assert arrays.band[0, 2 + 3] == 1.0
    with pytest.raises(ValueError, match="outside the band"):
        bn.add_block(*args, np.array([0, 3], dtype=np.int64), np.ones((2, 2)))  # 3 - 0 > kl
    with pytest.raises(ValueError, match="outside the band"):
        bn.add_block(*args, np.array([4, 0], dtype=np.int64), np.eye(2)[::-1].copy())
    with pytest.raises(ValueError, match="outside the system"):
        bn.add_block(*args, np.array([23, 24], dtype=np.int64), np.ones((2, 2)))
    with pytest.raises(ValueError, match="outside the system"):
        bn.add_block(*args, np.array([-1], dtype=np.int64), np.ones((1, 1)))
    # the same through add_blocks, whose blocks within the band or the border skip the
    # checks of each entry: a block it cannot store goes the checked way
    for d, message in (([0, 3], "outside the band"), ([23, 24], "outside the system"),
                       ([-1, 0], "outside the system")):
        with pytest.raises(ValueError, match=message):
            bn.add_blocks(*args, np.array([d], dtype=np.int64), np.ones((1, 2, 2)))
    # bandwidths that are not those of the storage
    with pytest.raises(ValueError, match="do not match"):
        bn.add_block(arrays.band, arrays.B, arrays.C, arrays.D, 3, 2, np.arange(2), np.eye(2))
    with pytest.raises(ValueError, match="do not match"):
        bn.add_blocks(arrays.band, arrays.B, arrays.C, arrays.D, 3, 2, np.arange(2)[None],
                      np.eye(2)[None])
    with pytest.raises(ValueError, match="do not match"):
        bn.factor(arrays.band, arrays.B, arrays.C, arrays.D, 3, 3, arrays.ipiv, arrays.ipiv_s)


# ---------------------------------------------------------------- solves

def _well_conditioned(case, count=3, tries=10):
    """The first ``count`` seeds whose K and A have condition numbers below MAX_COND: the
    agreement with NumPy is a test of the solver only there (module docstring). Random
    band matrices have a heavy tail of condition numbers; most seeds pass."""
    n_b = case[0]
    seeds = []
    for seed in range(tries):
        K = _dense(n_b + case[3], _blocks(*case, seed))
        if np.linalg.cond(K) < MAX_COND and (n_b == 0 or np.linalg.cond(K[:n_b, :n_b]) < MAX_COND):
            seeds.append(seed)
    assert len(seeds) >= count
    return seeds[:count]


def _not_dominant(K, n_b):
    """Rows not diagonally dominant in the band (when it has 5 diagonals or more) and in
    the border (6 dofs or more) are at least a third of each."""
    n = len(K)
    off = np.sum(np.abs(K), axis=1) - np.abs(np.diag(K))
    weak = np.abs(np.diag(K)) < off
    narrow = np.count_nonzero(K[:n_b, :n_b], axis=1).max(initial=0) < 5
    band = narrow or 3 * weak[:n_b].sum() >= n_b
    border = n - n_b < 6 or 3 * weak[n_b:].sum() >= n - n_b
    return band and border


@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_solve_equals_dense_lu(case):
    n_b, kl, ku, m = case
    worst_res = worst_rel = 0.0
    for seed in _well_conditioned(case):
        arrays, K, rhs = _system(case, seed)
        assert _not_dominant(K, n_b)
        info, x = _factor_solve(arrays, kl, ku, rhs)
        assert info == 0
        ref = np.linalg.solve(K, rhs)
        worst_res = max(worst_res, _residual(K, x, rhs))
        worst_rel = max(worst_rel, _rel(x, ref))
        # partial pivoting did interchange rows
        if n_b > 1 and kl > 0:
            assert np.any(arrays.ipiv != np.arange(n_b))
        if m > 1:
            assert np.any(arrays.ipiv_s != np.arange(m))
    assert worst_res < RES_TOL
    assert worst_rel < REL_TOL


def _lu_every_column(D):
    """Right-looking LU with partial pivoting that updates every column of every row
    (dense_lu without its bound on the pivot row), on a copy; returns (LU, pivots)."""
    D = D.copy()
    m = D.shape[0]
    piv = np.zeros(m, np.int64)
    for k in range(m):
        p = k + int(np.argmax(np.abs(D[k:, k])))  # the first of equal candidates
        piv[k] = p
        D[[k, p]] = D[[p, k]]
        for i in range(k + 1, m):
            mult = D[i, k] / D[k, k]
            D[i, k] = mult
            if mult != 0.0:
                for c in range(k + 1, m):
                    D[i, c] -= mult * D[k, c]
    return D, piv


def test_dense_lu_of_a_banded_block_skips_only_exact_zeros():
    """A beam without contact is a banded border block D: dense_lu leaves the rows whose
    entry in the pivot column is zero alone and updates the others only up to the last
    nonzero of the pivot row, and its factors equal those of the update of every row and
    column (supported rows and columns with their -0 entries included; a zero multiplier
    not divided may differ in the sign of its zero only)."""
    rng = np.random.default_rng(11)
    m, kl, ku = 40, 5, 5
    D = np.zeros((m, m))
    for i in range(m):
        for j in range(max(0, i - kl), min(m, i + ku + 1)):
            D[i, j] = rng.standard_normal()
    free = np.ones(m)
    free[[0, 1, m - 2]] = 0.0
    D = D * free[:, None] * free[None, :]  # as apply_supports: -0 where x < 0
    D[np.arange(m), np.arange(m)] += 1.0 - free
    assert np.any(np.signbit(D) & (D == 0.0))  # -0 entries are there
    ref, piv = _lu_every_column(D)
    lu, ipiv = D.copy(), np.zeros(m, np.int64)
    assert bn.dense_lu(lu, ipiv) == 0
    assert np.array_equal(ipiv, piv) and np.any(ipiv != np.arange(m))
    assert np.array_equal(lu, ref)


def test_factor_once_solve_many():
    """The factors serve several right-hand sides, which stay unchanged."""
    case = (176, 9, 9, 60)
    n_b, kl, ku, m = case
    arrays, K, _ = _system(case, seed=5)
    assert bn.factor(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, arrays.ipiv,
                     arrays.ipiv_s) == 0
    rhs = np.random.default_rng(6).standard_normal((4, n_b + m))
    rhs[1, :n_b] = 0.0  # load on the border only
    rhs[2, n_b:] = 0.0  # on the band only
    keep = rhs.copy()
    for b in rhs:
        x = np.empty(n_b + m)
        bn.solve(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, arrays.ipiv,
                 arrays.ipiv_s, b, x)
        assert _residual(K, x, b) < RES_TOL
        assert _rel(x, np.linalg.solve(K, b)) < REL_TOL
    assert np.array_equal(rhs, keep)


@pytest.mark.parametrize("case", [(124, 9, 9, 52), (96, 9, 9, 20), (150, 4, 9, 25)], ids=_ids)
def test_uncoupled_system_skips_the_border_products(case):
    """Beams that no contact couples (free flight: B = C = 0): ``coupled=False`` skips the
    passes over B and C in the supports and the solve and gives the same system and
    solution, bit for bit, as the full passes, the solution of the block-diagonal K."""
    n_b, kl, ku, m = case
    n = n_b + m
    free = np.ones(n)
    free[[0, 1, n_b - 2, n - 1]] = 0.0  # pinned ends of both beams
    for seed in _well_conditioned(case)[:3]:
        blocks = [(d, k) for d, k in _blocks(n_b, kl, ku, m, seed)
                  if not (d.min() < n_b <= d.max())]  # no block spans band and border
        K = _dense(n, blocks)
        assert not K[:n_b, n_b:].any() and not K[n_b:, :n_b].any()
        rhs = np.random.default_rng(seed + 1000).standard_normal(n)
        xs, Ks = [], []
        for coupled in (True, False):
            arrays = _assemble(n_b, kl, ku, m, blocks)
            r = rhs.copy()
            bn.apply_supports(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, free, r,
                              coupled)
            Ks.append(bn.to_dense(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku))
            x = np.empty_like(rhs)
            assert bn.factor_solve(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku,
                                   arrays.ipiv, arrays.ipiv_s, r, x, coupled) == 0
            xs.append(x)
        assert np.array_equal(Ks[0], Ks[1]) and np.array_equal(xs[0], xs[1])
        assert _residual(Ks[1], xs[1], rhs * free) < RES_TOL


@pytest.mark.parametrize("case", [(96, 9, 9, 20), (150, 4, 9, 25), (200, 9, 3, 0)], ids=_ids)
def test_band_lu_is_lapack_dgbtrf(case):
    """The banded LU makes LAPACK's choices: same interchanges, same factors up to the
    rounding of division against LAPACK's product with the reciprocal pivot; ``band.T``
    is LAPACK's band array."""
    n_b, kl, ku, m = case
    arrays, _, _ = _system(case, seed=2)
    lu, piv, info = sla.lapack.dgbtrf(arrays.band.T.copy(), kl, ku)
    band = arrays.band.copy()
    ipiv = np.zeros(n_b, np.int64)
    assert bn.band_lu(band, kl, ku, ipiv) == 0 and info == 0
    assert np.array_equal(ipiv, piv)  # SciPy returns 0-based pivots
    assert np.max(np.abs(band.T - lu)) < 1e-12 * np.max(np.abs(lu))


# ---------------------------------------------------------------- supports

@pytest.mark.parametrize("case", [(96, 9, 9, 20), (150, 4, 9, 25), (0, 9, 9, 30),
                                  (60, 5, 5, 0)], ids=_ids)
def test_supports_as_the_dense_convention(case):
    """apply_supports is assembly.system.apply_supports (K * free free^T + diag(1 - free),
    r * free; called here on the dense K) value for value, and the supported dofs get
    exactly zero increments."""
    n_b, kl, ku, m = case
    n = n_b + m
    arrays, K, rhs = _system(case, seed=3)
    free = np.ones(n)
    supported = np.r_[0, 1, n_b - 2 if n_b > 2 else 0, n - 1, n - 4, n_b + m // 2 if m else 2]
    free[supported] = 0.0
    r = rhs.copy()
    bn.apply_supports(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku, free, r)
    r_jax, K_jax = apply_supports(jnp.asarray(rhs), jnp.asarray(K), jnp.asarray(free))
    K_sup = np.asarray(K_jax)
    assert np.array_equal(bn.to_dense(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku), K_sup)
    assert np.array_equal(r, np.asarray(r_jax))
    info, x = _factor_solve(arrays, kl, ku, r)
    assert info == 0
    assert np.all(x[supported] == 0.0)
    assert _residual(K_sup, x, r) < RES_TOL
    assert _rel(x, np.linalg.solve(K_sup, r)) < REL_TOL


def test_add_diagonal():
    case = (40, 3, 5, 7)
    arrays, K, _ = _system(case, seed=4)
    d = np.random.default_rng(0).standard_normal(47)
    bn.add_diagonal(arrays.band, arrays.D, 3, 5, d)
    assert np.array_equal(bn.to_dense(arrays.band, arrays.B, arrays.C, arrays.D, 3, 5),
                          K + np.diag(d))


# ---------------------------------------------------------------- singular matrices

def test_singular_band_gives_nan():
    """A zero column of A: an exact zero pivot (updates keep a zero column zero), info in
    1 .. n_b, x all NaN (as the sparse path's gbsv / SuperLU failure; NumPy raises)."""
    case = (96, 9, 9, 20)
    n_b, kl, ku, m = case
    arrays, K, rhs = _system(case)
    j = 37
    arrays.band[j, :] = 0.0  # column j of A
    arrays.C[:, j] = 0.0
    K[:, j] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(K, rhs)
    info, x = _factor_solve(arrays, kl, ku, rhs)
    assert 1 <= info <= j + 1
    assert np.all(np.isnan(x))


@pytest.mark.parametrize("case", [(96, 9, 9, 20), (0, 9, 9, 20)], ids=_ids)
def test_singular_schur_complement_gives_nan(case):
    """Two equal border rows: S has two equal rows, one of which stays exactly zero and is
    never a pivot until the last column: info = n_b + k + 1 for some k, x all NaN."""
    n_b, kl, ku, m = case
    arrays, K, rhs = _system(case)
    arrays.C[5] = arrays.C[2]
    arrays.D[5] = arrays.D[2]
    K[n_b + 5] = K[n_b + 2]
    assert np.linalg.matrix_rank(K) < n_b + m
    info, x = _factor_solve(arrays, kl, ku, rhs)
    assert n_b < info <= n_b + m
    assert np.all(np.isnan(x))


def test_singular_pivot_block_is_reported():
    """The documented limit of block elimination: A singular with K regular (the zero
    column of A is held by the border) is reported as a failure in A, with NaN."""
    case = (96, 9, 9, 20)
    n_b, kl, ku, m = case
    arrays, K, rhs = _system(case)
    j = int(np.flatnonzero(np.any(arrays.C != 0.0, axis=0))[0])  # a dof touched by contact
    arrays.band[j, :] = 0.0
    K[:n_b, j] = 0.0
    assert np.linalg.cond(K) < 1e6
    info, x = _factor_solve(arrays, kl, ku, rhs)
    assert 1 <= info <= n_b
    assert np.all(np.isnan(x))


def test_band_solve_rows_is_band_solve_column_by_column():
    """X = A^{-1} B for a border block whose nonzero columns are a narrow range (contact
    couples neighbouring elements): band_solve_rows works over that range only, and each
    column is the one band_solve gives for it alone, bit for bit, the zero columns
    exactly zero."""
    case = (124, 9, 9, 52)
    n_b, kl, ku, m = case
    arrays, _, _ = _system(case, seed=3)
    assert bn.band_lu(arrays.band, kl, ku, arrays.ipiv) == 0
    B = np.zeros((n_b, m))
    B[60:80, 20:31] = np.random.default_rng(4).standard_normal((20, 11))
    X = B.copy()
    bn.band_solve_rows(arrays.band, kl, ku, arrays.ipiv, X)
    for c in range(m):
        x = B[:, c].copy()
        bn.band_solve(arrays.band, kl, ku, arrays.ipiv, x)
        assert np.array_equal(X[:, c], x)
    assert not X[:, :20].any() and not X[:, 31:].any()
    assert np.abs(X[:, 20:31]).min() > 0.0  # A^{-1} fills the columns in


def test_an_uncoupled_system_ignores_what_a_coupled_one_left_in_the_border():
    """zero(..., coupled=False) leaves B and C as a coupled factorisation left them
    (X = A^{-1} B over B): the uncoupled factorisation and solve never read them, and
    the solution is that of fresh arrays, bit for bit."""
    case = (124, 9, 9, 52)
    n_b, kl, ku, m = case
    coupled, _, rhs = _system(case, seed=7)
    assert bn.factor(coupled.band, coupled.B, coupled.C, coupled.D, kl, ku, coupled.ipiv,
                     coupled.ipiv_s) == 0
    assert coupled.B.any() and coupled.C.any()
    blocks = [(d, k) for d, k in _blocks(n_b, kl, ku, m, 8) if not (d.min() < n_b <= d.max())]
    fresh = _assemble(n_b, kl, ku, m, blocks)
    reused = coupled
    bn.zero(reused.band, reused.B, reused.C, reused.D, False)
    for d, k in blocks:
        bn.add_block(reused.band, reused.B, reused.C, reused.D, kl, ku, d, k)
    xs = []
    for arrays in (fresh, reused):
        x = np.empty(n_b + m)
        assert bn.factor_solve(arrays.band, arrays.B, arrays.C, arrays.D, kl, ku,
                               arrays.ipiv, arrays.ipiv_s, rhs, x, False) == 0
        xs.append(x)
    assert np.array_equal(xs[0], xs[1])
