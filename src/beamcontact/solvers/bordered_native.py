"""Native (Numba) linear solver of the bordered banded tangent of the CPU engine.

The Newton tangent of beams in contact, with the dofs of the largest beam first, is

    K = [[A, B],      A (n_b x n_b): banded, lower / upper bandwidths kl, ku (one beam:
         [C, D]]      kl = ku = 2 (p + 1) - 1 for interleaved x, y dofs), not symmetric;
                      B (n_b x m), C (m x n_b), D (m x m): dense border (all other beams).

and K x = f is solved by block elimination with the Schur complement (Golub & Van Loan,
Matrix Computations, 4th ed.: sec. 3.2 block LU, 3.4 partial pivoting, 4.3 banded LU with
partial pivoting; bordered systems and the limits of plain block elimination: Govaerts &
Pryce, "Mixed block elimination for linear systems with wider borders", IMA J. Numer.
Anal. 13, 1993):

    A = P L U                       banded LU with partial pivoting (LAPACK dgbtf2)
    X = A^{-1} B                    (stored over B)
    S = D - C X = P_s L_s U_s       dense LU with partial pivoting (LAPACK dgetf2), over D
    y = S^{-1} (f_c - C A^{-1} f_b),   x_b = A^{-1} f_b - X y.

Cost O(n_b (kl + ku) (m + 1) + n_b m^2 + m^3): linear in the length of the big beam.
m = 0 (one beam) is the banded LU alone; n_b = 0 (no band) is the dense LU of D alone.

Storage layout (all float64, C order; layout positions 0 .. n_b + m - 1, the first n_b
the band, position n_b + k is border index k):

    band (n_b, ldab), ldab = 2 kl + ku + 1:  band[j, kl + ku + i - j] = A[i, j]
        for max(0, j - ku) <= i <= min(n_b - 1, j + kl). Row j of ``band`` is column j of
        LAPACK's band storage, so ``band`` is LAPACK's ``ab`` array memory for memory
        (``band.T`` can be handed to dgbtrf / dgbsv). The first kl entries of each row are
        not entries of A: they receive the fill-in of the row interchanges (U has upper
        bandwidth kl + ku); the factorisation zeroes them itself.
    B (n_b, m): B[i, k] = K[i, n_b + k];   C (m, n_b): C[k, j] = K[n_b + k, j];
    D (m, m): D[k, l] = K[n_b + k, n_b + l].
    ipiv (n_b,), ipiv_s (m,) int64: the row interchanges (0-based: row j was swapped with
        row ipiv[j] at step j), written by :func:`factor`.

After :func:`factor`, ``band`` holds L (multipliers below the diagonal entry) and U,
B holds X = A^{-1} B, D holds the LU factors of S; C is unchanged. The factorisation is in
place because the tangent is assembled anew in every Newton iteration.

Singular matrices: as LAPACK (and so the sparse path of :mod:`beamcontact.solvers.linear`,
whose ``host_solve`` returns NaN when gbsv or SuperLU reports a singular factor), the test
is an exact zero pivot. :func:`factor` returns ``info`` = 0 on success, j + 1 when the
pivot of column j of A is zero (A singular: block elimination cannot proceed even though
K itself may be regular, see the caveat below) and n_b + k + 1 when the pivot of column k
of S is zero. :func:`factor_solve` then returns that info with x all NaN, so that the
Newton iteration fails and the step is cut, as on the JAX paths (whose dense LU turns a
zero pivot into inf / NaN).

Caveat: block elimination pivots within A and within S only, never across the border. It
is stable when A is well conditioned (a beam with mass in the HHT tangent, or a supported
beam in statics); a nearly singular A (say a free floating big beam in statics held only
by contact) loses accuracy or reports info in 1 .. n_b although K is regular. The dense
or sparse solve of the whole K is the fallback for that case.

Assembly: :func:`add_block` scatter-adds a local matrix (an element or contact block) at
its layout positions; an entry of A outside the band that is not exactly zero raises
ValueError (kl, ku too small for the dof order); exact zeros (padding, supported rows)
are skipped. Supports as :func:`beamcontact.assembly.system.apply_supports`: K becomes
K * free[:, None] * free[None, :] + diag(1 - free) and r becomes r * free
(:func:`apply_supports`), the same products in the same order.
"""

from typing import NamedTuple

import numpy as np

from beamcontact._native import njit, njit_inline, njit_uncounted


class BorderedLayout(NamedTuple):
    """Dimensions of a bordered banded system: band of n_b dofs with bandwidths (kl, ku),
    border of m dofs."""

    n_b: int
    kl: int
    ku: int
    m: int

    @property
    def n(self) -> int:
        """Number of unknowns."""
        return self.n_b + self.m

    @property
    def ldab(self) -> int:
        """Entries per column of the band storage, fill-in rows included."""
        return 2 * self.kl + self.ku + 1

    @property
    def shapes(self) -> dict:
        """Shapes of the arrays of :func:`allocate`."""
        return {"band": (self.n_b, self.ldab), "B": (self.n_b, self.m),
                "C": (self.m, self.n_b), "D": (self.m, self.m),
                "ipiv": (self.n_b,), "ipiv_s": (self.m,)}


class BorderedArrays(NamedTuple):
    """The arrays of one bordered system (see the module docstring for their meaning)."""

    band: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    ipiv: np.ndarray
    ipiv_s: np.ndarray


def layout(n_b: int, kl: int, ku: int, m: int) -> BorderedLayout:
    """The layout of a system of n_b band dofs of bandwidths (kl, ku) and m border dofs."""
    n_b, kl, ku, m = int(n_b), int(kl), int(ku), int(m)
    if min(n_b, kl, ku, m) < 0:
        raise ValueError(f"negative dimension in (n_b, kl, ku, m) = {(n_b, kl, ku, m)}")
    return BorderedLayout(n_b, kl, ku, m)


def allocate(lay: BorderedLayout) -> BorderedArrays:
    """Zeroed arrays for ``lay``."""
    s = lay.shapes
    return BorderedArrays(np.zeros(s["band"]), np.zeros(s["B"]), np.zeros(s["C"]),
                          np.zeros(s["D"]), np.zeros(s["ipiv"], np.int64),
                          np.zeros(s["ipiv_s"], np.int64))


def band_widths(dofs: np.ndarray, n_b: int) -> tuple[int, int]:
    """(kl, ku) of the band that blocks at layout positions ``dofs`` (n_blocks, k) give
    to A: the largest i - j and j - i over pairs of positions below n_b of one block."""
    dofs = np.asarray(dofs).reshape(len(dofs), -1)
    kl = ku = 0
    for row in dofs:
        d = row[row < n_b]
        if d.size:
            diff = d[:, None] - d[None, :]
            kl, ku = max(kl, int(diff.max())), max(ku, int(-diff.min()))
    return kl, ku


# ---------------------------------------------------------------- assembly


@njit
def _check_widths(band, kl, ku):
    """Bandwidths other than the storage's would put entries in the wrong diagonals."""
    if kl < 0 or ku < 0 or band.shape[1] != 2 * kl + ku + 1:
        raise ValueError("kl, ku do not match the band storage (2 kl + ku + 1 columns)")


@njit_uncounted
def zero(band, B, C, D, coupled=True):
    """Set the system to zero (fill-in rows of the band included); ``coupled`` False:
    B and C are left as they are, for a system that :func:`factor` and :func:`solve`
    will be told is not coupled (they never read B and C then)."""
    band[:] = 0.0
    if coupled:
        B[:] = 0.0
        C[:] = 0.0
    D[:] = 0.0


@njit_inline
def add_block(band, B, C, D, kl, ku, dofs, k_local):
    """K[dofs[a], dofs[b]] += k_local[a, b] for the layout positions ``dofs`` (k,) and the
    local matrix ``k_local`` (k, k); repeated positions add up.

    Exact zeros are skipped, so padding blocks cost no checks and a block may have entries
    outside the band as long as they are zero; a nonzero one raises ValueError, since
    dropping it would solve another system. Positions outside 0 .. n_b + m - 1 raise too
    (Numba does not check bounds).
    """
    _check_widths(band, kl, ku)
    n_b = band.shape[0]
    n = n_b + D.shape[0]
    kv = kl + ku
    k = dofs.shape[0]
    for a in range(k):
        i = dofs[a]
        for b in range(k):
            v = k_local[a, b]
            if v == 0.0:
                continue
            j = dofs[b]
            if i < 0 or i >= n or j < 0 or j >= n:
                raise ValueError("add_block: dof outside the system")
            if i < n_b:
                if j < n_b:
                    if i - j > kl or j - i > ku:
                        raise ValueError("add_block: nonzero entry outside the band")
                    band[j, kv + i - j] += v
                else:
                    B[i, j - n_b] += v
            elif j < n_b:
                C[i - n_b, j] += v
            else:
                D[i - n_b, j - n_b] += v


@njit_uncounted
def add_blocks(band, B, C, D, kl, ku, dofs, blocks):
    """:func:`add_block` for each block: dofs (n_blocks, k), blocks (n_blocks, k, k). A
    block whose positions all lie in the band, within the narrower of its widths of each
    other, or all in the border (an element of a beam) is added without the checks of
    each entry: the same sums in the same order."""
    _check_widths(band, kl, ku)
    n_b = band.shape[0]
    n = n_b + D.shape[0]
    kv = kl + ku
    k = dofs.shape[1]
    for e in range(dofs.shape[0]):
        lo = hi = dofs[e, 0]
        for a in range(1, k):
            lo = min(lo, dofs[e, a])
            hi = max(hi, dofs[e, a])
        if lo >= 0 and hi < n_b and hi - lo <= min(kl, ku):
            for a in range(k):
                i = dofs[e, a]
                for b in range(k):
                    v = blocks[e, a, b]
                    if v != 0.0:
                        j = dofs[e, b]
                        band[j, kv + i - j] += v
        elif lo >= n_b and hi < n:
            for a in range(k):
                i = dofs[e, a] - n_b
                for b in range(k):
                    v = blocks[e, a, b]
                    if v != 0.0:
                        D[i, dofs[e, b] - n_b] += v
        else:
            add_block(band, B, C, D, kl, ku, dofs[e], blocks[e])


@njit
def add_diagonal(band, D, kl, ku, values):
    """K[i, i] += values[i] for every layout position i (values of length n_b + m)."""
    n_b = band.shape[0]
    kv = kl + ku
    for i in range(n_b):
        band[i, kv] += values[i]
    for k in range(D.shape[0]):
        D[k, k] += values[n_b + k]


@njit
def apply_supports(band, B, C, D, kl, ku, free, r, coupled=True):
    """In place, as :func:`beamcontact.assembly.system.apply_supports`:
    K <- K * free[:, None] * free[None, :] + diag(1 - free) and r <- r * free (free = 1
    for a free dof, 0 for a supported one: its row and column become the identity's and
    its residual 0, so its Newton increment is 0). Same products in the same order, so
    the values are the dense ones exactly; the fill-in rows of the band are left alone.
    ``coupled`` False: B and C are zero (:func:`factor`) and stay as they are.

    Only the rows and columns of the supported dofs are visited: every other entry is
    x * 1 * 1, which is x exactly (the products are formed as above, row factor first,
    and repeating one on an entry both in a supported row and column gives the same
    zero). A beam without supports leaves its block untouched but for the diagonal.
    """
    n_b = band.shape[0]
    m = D.shape[0]
    kv = kl + ku
    for s in range(n_b + m):
        if free[s] == 1.0:
            continue
        if s < n_b:
            for i in range(max(0, s - ku), min(n_b, s + kl + 1)):  # column s of A
                band[s, kv + i - s] = band[s, kv + i - s] * free[i] * free[s]
            for j in range(max(0, s - kl), min(n_b, s + ku + 1)):  # row s of A
                band[j, kv + s - j] = band[j, kv + s - j] * free[s] * free[j]
            if coupled:
                for k in range(m):
                    B[s, k] = B[s, k] * free[s] * free[n_b + k]
                    C[k, s] = C[k, s] * free[n_b + k] * free[s]
        else:
            k = s - n_b
            for q in range(m):
                D[k, q] = D[k, q] * free[s] * free[n_b + q]
                D[q, k] = D[q, k] * free[n_b + q] * free[s]
            if coupled:
                for i in range(n_b):
                    B[i, k] = B[i, k] * free[i] * free[s]
                    C[k, i] = C[k, i] * free[s] * free[i]
    for j in range(n_b):
        band[j, kv] += 1.0 - free[j]
    for k in range(m):
        D[k, k] += 1.0 - free[n_b + k]
    for i in range(n_b + m):
        r[i] = r[i] * free[i]


@njit
def to_dense(band, B, C, D, kl, ku):
    """K as an (n_b + m) x (n_b + m) array (tests and diagnostics; before :func:`factor`)."""
    n_b = band.shape[0]
    m = D.shape[0]
    kv = kl + ku
    K = np.zeros((n_b + m, n_b + m))
    for j in range(n_b):
        for i in range(max(0, j - ku), min(n_b, j + kl + 1)):
            K[i, j] = band[j, kv + i - j]
    K[:n_b, n_b:] = B
    K[n_b:, :n_b] = C
    K[n_b:, n_b:] = D
    return K


@njit
def matvec(band, B, C, D, kl, ku, x, y):
    """y = K x (before :func:`factor`): residuals, iterative refinement."""
    n_b = band.shape[0]
    m = D.shape[0]
    kv = kl + ku
    y[:] = 0.0
    for j in range(n_b):
        xj = x[j]
        for i in range(max(0, j - ku), min(n_b, j + kl + 1)):
            y[i] += band[j, kv + i - j] * xj
    for i in range(n_b):
        s = 0.0
        for k in range(m):
            s += B[i, k] * x[n_b + k]
        y[i] += s
    for k in range(m):
        s = 0.0
        for j in range(n_b):
            s += C[k, j] * x[j]
        for q in range(m):
            s += D[k, q] * x[n_b + q]
        y[n_b + k] = s


# ---------------------------------------------------------------- banded LU


@njit_uncounted
def band_lu(band, kl, ku, ipiv):
    """A = P L U in place: LAPACK dgbtf2 (Golub & Van Loan sec. 4.3, band Gaussian
    elimination with pivoting), right-looking, one column at a time. Returns 0, or j + 1
    at the first zero pivot (column j), where it stops.

    A row interchange at step j brings row ipiv[j] <= j + kl, whose entries reach column
    ipiv[j] + ku, into row j: U gets upper bandwidth kl + ku, held by the first kl entries
    of each band row (zeroed here, so that stale factors never leak in). ju, the last
    column touched by any interchange so far, bounds the update, as in dgbtf2.
    """
    n = band.shape[0]
    kv = kl + ku
    for j in range(n):
        for r in range(kl):
            band[j, r] = 0.0
    ju = 0
    for j in range(n):
        col = band[j]
        km = min(kl, n - 1 - j)
        p = 0
        amax = abs(col[kv])
        for i in range(1, km + 1):
            a = abs(col[kv + i])
            if a > amax:
                amax = a
                p = i
        ipiv[j] = j + p
        pivot = col[kv + p]
        if pivot == 0.0:
            return j + 1
        ju = max(ju, min(j + ku + p, n - 1))
        if p != 0:
            for c in range(j, ju + 1):
                t = band[c, kv + j - c]
                band[c, kv + j - c] = band[c, kv + j + p - c]
                band[c, kv + j + p - c] = t
        # division, not a product with 1 / pivot: one rounding per multiplier
        for i in range(1, km + 1):
            col[kv + i] = col[kv + i] / pivot
        # 1-d slices: Numba compiles their loop to a tighter one than 2-d indexing (1.5 times
        # faster here); taken inside the branch, the slice made the whole LU 2 times slower
        mult = col[kv + 1:kv + km + 1]
        for c in range(j + 1, ju + 1):
            o = kv + j - c
            target = band[c, o + 1:o + km + 1]
            u = band[c, o]
            if u != 0.0:
                for i in range(km):
                    target[i] -= mult[i] * u
    return 0


@njit_uncounted
def band_solve(band, kl, ku, ipiv, x):
    """x <- A^{-1} x with the factors of :func:`band_lu` (LAPACK dgbtrs, no transpose):
    the interchanges and L forward, then U (bandwidth kl + ku) backward by columns, which
    reads each band row contiguously."""
    n = band.shape[0]
    kv = kl + ku
    for j in range(n - 1):
        km = min(kl, n - 1 - j)
        p = ipiv[j]
        if p != j:
            t = x[j]
            x[j] = x[p]
            x[p] = t
        xj = x[j]
        if xj != 0.0:
            for i in range(1, km + 1):
                x[j + i] -= band[j, kv + i] * xj
    for j in range(n - 1, -1, -1):
        xj = x[j] / band[j, kv]
        x[j] = xj
        if xj != 0.0:
            for i in range(max(0, j - kv), j):
                x[i] -= band[j, kv + i - j] * xj


@njit_uncounted
def band_solve_rows(band, kl, ku, ipiv, X):
    """X <- A^{-1} X for X (n_b, r), all columns at once: every operation of
    :func:`band_solve` on a scalar becomes one on a contiguous row of X.

    Contact couples few dofs of the band with few of the border, so most rows and
    columns of B are zero. The steps before max(0, f - kl), f the first nonzero row,
    interchange and eliminate zero rows only (ipiv[j] <= j + kl < f) and are skipped;
    the columns outside the range of the nonzero ones are zero and stay zero (A^{-1} 0 =
    0), so each row operation runs over that range only.
    """
    n = X.shape[0]
    kv = kl + ku
    # the first nonzero row f, and the nonzero columns c0 .. c1 - 1: the other columns
    # are zero and stay zero
    f, c0, c1 = n, X.shape[1], 0
    for i in range(n):
        for c in range(X.shape[1]):
            if X[i, c] != 0.0:
                f = min(f, i)
                c0 = min(c0, c)
                c1 = max(c1, c + 1)
    if f == n:
        return
    # row operations on 1-d slices, taken outside the branches (as in band_lu): 2.1 times
    # faster than 2-d indexing for a block of 124 x 52
    w = c1 - c0
    for j in range(max(0, f - kl), n - 1):
        km = min(kl, n - 1 - j)
        p = ipiv[j]
        xj = X[j, c0:c1]
        if p != j:
            xp = X[p, c0:c1]
            for c in range(w):
                t = xj[c]
                xj[c] = xp[c]
                xp[c] = t
        for i in range(1, km + 1):
            mult = band[j, kv + i]
            target = X[j + i, c0:c1]
            if mult != 0.0:
                for c in range(w):
                    target[c] -= mult * xj[c]
    for j in range(n - 1, -1, -1):
        d = band[j, kv]
        xj = X[j, c0:c1]
        for c in range(w):
            xj[c] = xj[c] / d
        for i in range(max(0, j - kv), j):
            u = band[j, kv + i - j]
            target = X[i, c0:c1]
            if u != 0.0:
                for c in range(w):
                    target[c] -= u * xj[c]


# ---------------------------------------------------------------- dense LU


@njit_uncounted
def dense_lu(D, ipiv):
    """D = P L U in place, right-looking with partial pivoting (LAPACK dgetf2; Golub &
    Van Loan sec. 3.4), whole rows interchanged so that the row-major updates run along
    contiguous rows. Returns 0, or k + 1 at the first zero pivot (column k)."""
    m = D.shape[0]
    for k in range(m):
        p = k
        amax = abs(D[k, k])
        for i in range(k + 1, m):
            a = abs(D[i, k])
            if a > amax:
                amax = a
                p = i
        ipiv[k] = p
        pivot = D[p, k]
        if pivot == 0.0:
            return k + 1
        if p != k:
            for c in range(m):
                t = D[k, c]
                D[k, c] = D[p, c]
                D[p, c] = t
        # 1-d slices taken outside the branch, as in band_lu: 2.4 times faster for m = 60
        pivot_row = D[k, k + 1:]
        # the zeros at the end of the pivot row change no entry (x - mult 0 is x; only a
        # -0 entry would have become +0), so a banded block (a beam in free flight) is
        # updated within its band
        width = m - k - 1
        while width > 0 and pivot_row[width - 1] == 0.0:
            width -= 1
        for i in range(k + 1, m):
            target = D[i, k + 1:]
            d = D[i, k]
            if d == 0.0:
                # a zero multiplier changes nothing (a banded block: every row below the
                # band); the division would only have given it a sign
                continue
            mult = d / pivot
            D[i, k] = mult
            if mult != 0.0:
                for c in range(width):
                    target[c] -= mult * pivot_row[c]
    return 0


@njit_uncounted
def dense_solve(D, ipiv, y):
    """y <- S^{-1} y with the factors of :func:`dense_lu` (LAPACK dgetrs)."""
    m = D.shape[0]
    for k in range(m):
        p = ipiv[k]
        if p != k:
            t = y[k]
            y[k] = y[p]
            y[p] = t
    for i in range(m):
        s = y[i]
        for k in range(i):
            s -= D[i, k] * y[k]
        y[i] = s
    for i in range(m - 1, -1, -1):
        s = y[i]
        for c in range(i + 1, m):
            s -= D[i, c] * y[c]
        y[i] = s / D[i, i]


# ---------------------------------------------------------------- bordered system


@njit_uncounted
def factor(band, B, C, D, kl, ku, ipiv, ipiv_s, coupled=True):
    """Factorise K in place (module docstring): band LU of A, B <- X = A^{-1} B,
    D <- LU of S = D - C X. Returns 0, j + 1 for a zero pivot in column j of A, or
    n_b + k + 1 for one in column k of S.

    ``coupled`` False says that B and C are zero (no contact couples the band's beam with
    the others, as in free flight): X = 0 and S = D, and the passes over B and C are
    skipped (they would only add exact zeros).

    The columns of B are solved for over the range of its nonzero ones
    (:func:`band_solve_rows`): narrow where contact couples a few neighbouring elements
    of each beam, the whole border where a coarse-grained cutoff reaches along the
    beam. The zero entries of C are skipped in S = D - C X.
    """
    _check_widths(band, kl, ku)
    n_b = band.shape[0]
    m = D.shape[0]
    info = band_lu(band, kl, ku, ipiv)
    if info != 0:
        return info
    if m == 0:
        return 0
    if coupled:
        band_solve_rows(band, kl, ku, ipiv, B)
        for k in range(m):
            dk = D[k]
            for j in range(n_b):
                cv = C[k, j]
                bj = B[j]
                if cv != 0.0:
                    for q in range(m):
                        dk[q] -= cv * bj[q]
    info = dense_lu(D, ipiv_s)
    if info != 0:
        return n_b + info
    return 0


@njit_uncounted
def solve(band, B, C, D, kl, ku, ipiv, ipiv_s, rhs, x, coupled=True):
    """x = K^{-1} rhs with the factors of a successful :func:`factor` (rhs unchanged; it
    may be x itself); ``coupled`` as there."""
    n_b = band.shape[0]
    m = D.shape[0]
    for i in range(n_b + m):
        x[i] = rhs[i]
    band_solve(band, kl, ku, ipiv, x[:n_b])
    if m == 0:
        return
    y = x[n_b:]
    if coupled:
        _subtract_product(C, x[:n_b], y)
    dense_solve(D, ipiv_s, y)
    if coupled:
        _subtract_product(B, y, x[:n_b])


@njit_inline
def _subtract_product(M, v, out):
    """out -= M v, each row's sum in column order (the two halves of the block
    elimination in :func:`solve`)."""
    for i in range(M.shape[0]):
        s = out[i]
        for k in range(M.shape[1]):
            s -= M[i, k] * v[k]
        out[i] = s


@njit
def factor_solve(band, B, C, D, kl, ku, ipiv, ipiv_s, rhs, x, coupled=True):
    """x = K^{-1} rhs: :func:`factor` (in place) then :func:`solve` (``coupled`` as
    there). Returns factor's info; on a zero pivot (info != 0) x is all NaN."""
    info = factor(band, B, C, D, kl, ku, ipiv, ipiv_s, coupled)
    if info != 0:
        x[:] = np.nan
        return info
    solve(band, B, C, D, kl, ku, ipiv, ipiv_s, rhs, x, coupled)
    return 0


@njit
def newton_update(band, B, C, D, kl, ku, ipiv, ipiv_s, position, r_layout, du, u,
                  coupled=True):
    """One Newton update on the assembled bordered system: K du = -r (r in layout order,
    negated in place; K factorised in place), then u[i] += du[position[i]] for u in the
    global numbering. Returns (max |du|, whether every du is finite); a zero pivot gives a
    NaN du (:func:`factor_solve`; ``coupled`` as :func:`factor`)."""
    for i in range(r_layout.shape[0]):
        r_layout[i] = -r_layout[i]
    factor_solve(band, B, C, D, kl, ku, ipiv, ipiv_s, r_layout, du, coupled)
    step, finite = 0.0, True
    for i in range(u.shape[0]):
        d = du[position[i]]
        u[i] += d
        step = max(step, abs(d))
        finite = finite and np.isfinite(d)
    return step, finite


@njit
def supported_residual(band, B, C, D, kl, ku, free_layout, position, r, r_layout,
                       coupled=True):
    """The supports applied to the assembled system (:func:`apply_supports`, ``coupled``
    as there): the residual r (global numbering) copied into layout order (r_layout),
    both modified, r written back; returns ||r||."""
    for i in range(r.shape[0]):
        r_layout[position[i]] = r[i]
    apply_supports(band, B, C, D, kl, ku, free_layout, r_layout, coupled)
    norm = 0.0
    for i in range(r.shape[0]):
        r[i] = r_layout[position[i]]
        norm += r[i] * r[i]
    return np.sqrt(norm)


@njit
def supported_norm(free, r):
    """The residual alone of :func:`supported_residual`, without a matrix: r <- r * free
    (global numbering, ``free`` as there in that numbering) and ||r||, the same numbers
    bit for bit (the same products, summed in the same order)."""
    norm = 0.0
    for i in range(r.shape[0]):
        r[i] = r[i] * free[i]
        norm += r[i] * r[i]
    return np.sqrt(norm)
