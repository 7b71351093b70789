"""Linear solves of the global tangent: a dense matrix, or the unassembled local blocks
(sparse).

Dense (a ``jnp`` array, n x n): the element blocks are scattered into it and
``jnp.linalg.solve`` (LU with partial pivoting) solves it on the device. Its zeroing and
scatter grow with n^2 and its factorisation with n^3: a beam of 808 dofs costs 13 ms per
step, one of 6408 dofs 200 ms.

Sparse (:class:`SparseTangent`): the same local blocks kept as coordinate triplets (row,
column, value; repeated entries add up), never an n x n array. The solve is a host
callback (``jax.pure_callback``) that sums the triplets into a compressed matrix and
factorises it with LAPACK's banded LU with partial pivoting (``gbsv``) when its
bandwidth is small against n (one beam: half bandwidth 2 (p + 1) - 1 dofs for p + 1
control points per element), else with SuperLU (partial pivoting, COLAMD column order).
Both cost O(n) for a beam, but the callback costs about 0.15 ms however small the system,
so ``solver.linear_solver = "auto"`` keeps small systems dense (:func:`use_sparse`).

Every function here takes either kind, so the assembly, Newton and HHT code is written
once; on the dense kind each does exactly the arithmetic of the dense code it replaced.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beamcontact._jax import gpu_plugin_installed, imported, jax, jnp, pytree

# "auto" switches to the sparse tangent on CPU from this many dofs on: there the dense
# solve and the sparse callback cost about the same (benchmarks/linear_solver.py)
AUTO_SPARSE_DOFS = 300


@pytree
@dataclass(frozen=True)
class SparseTangent:
    """An n x n matrix as coordinate triplets: entry (rows[k], cols[k]) += vals[k]."""

    rows: jax.Array
    cols: jax.Array
    vals: jax.Array
    n: int = field(metadata=dict(static=True))


def use_sparse(choice: str, n_dof: int, backend: str | None = None) -> bool:
    """Whether ``solver.linear_solver = choice`` means the sparse tangent for n_dof dofs:
    "auto" is sparse on CPU from :data:`AUTO_SPARSE_DOFS` dofs on and dense on an
    accelerator (whose dense LU is fast and whose host callbacks are not). The backend,
    unless given, is JAX's default; before JAX is imported (a native run never imports
    it) an installed GPU plugin stands for an accelerator."""
    if choice not in ("auto", "dense", "sparse"):
        raise ValueError(f"linear_solver must be 'auto', 'dense' or 'sparse', not {choice!r}")
    if choice != "auto":
        return choice == "sparse"
    if backend is None:
        backend = jax.default_backend() if imported() else (
            "gpu" if gpu_plugin_installed() else "cpu")
    return backend == "cpu" and n_dof >= AUTO_SPARSE_DOFS


def zeros(n: int, sparse: bool):
    """The zero tangent of n dofs."""
    if not sparse:
        return jnp.zeros((n, n))
    empty = jnp.zeros(0, jnp.int64)
    return SparseTangent(empty, empty, jnp.zeros(0), n)


def scatter(K, dofs: jax.Array, blocks: jax.Array):
    """K plus the local blocks (B, m, m) at the global dofs (B, m) of each block."""
    if not isinstance(K, SparseTangent):
        return K.at[dofs[:, :, None], dofs[:, None, :]].add(blocks)
    B, m = dofs.shape
    rows = jnp.broadcast_to(dofs[:, :, None], (B, m, m)).ravel()
    cols = jnp.broadcast_to(dofs[:, None, :], (B, m, m)).ravel()
    return _append(K, rows, cols, blocks.ravel())


def add(a, b, scale=None):
    """a + b, or a + scale b."""
    if not isinstance(a, SparseTangent):
        return a + b if scale is None else a + scale * b
    return _append(a, b.rows, b.cols, b.vals if scale is None else scale * b.vals)


def apply_supports(K, free: jax.Array):
    """Rows and columns of supported dofs (free = 0) replaced by the identity's."""
    if not isinstance(K, SparseTangent):
        return K * free[:, None] * free[None, :] + jnp.diag(1.0 - free)
    idx = jnp.arange(K.n, dtype=K.rows.dtype)
    kept = SparseTangent(K.rows, K.cols, K.vals * free[K.rows] * free[K.cols], K.n)
    return _append(kept, idx, idx, 1.0 - free)


def solve(K, rhs: jax.Array) -> jax.Array:
    """K^{-1} rhs; NaN where K is singular (never raises inside jit)."""
    if not isinstance(K, SparseTangent):
        return jnp.linalg.solve(K, rhs)
    out = jax.ShapeDtypeStruct(rhs.shape, rhs.dtype)
    return jax.pure_callback(host_solve, out, K.rows, K.cols, K.vals, rhs,
                             vmap_method="sequential")


def to_dense(K) -> np.ndarray:
    """The tangent as a NumPy n x n array (diagnostics and tests)."""
    if not isinstance(K, SparseTangent):
        return np.asarray(K)
    return compressed(K.rows, K.cols, K.vals, K.n).toarray()


def compressed(rows, cols, vals, n: int):
    """The triplets summed into a compressed-column matrix."""
    import scipy.sparse as sp

    return sp.csc_matrix((np.asarray(vals), (np.asarray(rows), np.asarray(cols))),
                         shape=(n, n))


def host_solve(rows, cols, vals, rhs) -> np.ndarray:
    """Solve the triplet matrix against rhs on the host: banded LU (LAPACK gbsv) when the
    band is narrow, SuperLU otherwise; NaN if the matrix is singular."""
    rows, cols, vals = np.asarray(rows), np.asarray(cols), np.asarray(vals)
    rhs = np.array(rhs, dtype=np.float64)
    n = rhs.shape[0]
    keep = vals != 0.0  # padding blocks and supported rows contribute exact zeros
    rows, cols, vals = rows[keep], cols[keep], vals[keep]
    lower = int(np.max(rows - cols, initial=0))
    upper = int(np.max(cols - rows, initial=0))
    if 4 * (2 * lower + upper + 1) < n:
        return _banded_solve(rows, cols, vals, rhs, lower, upper)
    try:
        import scipy.sparse.linalg as spla

        return spla.splu(compressed(rows, cols, vals, n)).solve(rhs)
    except RuntimeError:  # "Factor is exactly singular"
        return np.full(n, np.nan)


def _banded_solve(rows, cols, vals, rhs, lower: int, upper: int) -> np.ndarray:
    """gbsv on LAPACK band storage: ab[lower + upper + i - j, j] = A[i, j], with ``lower``
    extra rows on top for the fill-in of the row interchanges."""
    n = rhs.shape[0]
    height = 2 * lower + upper + 1
    ab = np.bincount((lower + upper + rows - cols) * n + cols, weights=vals,
                     minlength=height * n).reshape(height, n)
    import scipy.linalg as sla

    gbsv = sla.get_lapack_funcs("gbsv", (ab,))
    _, _, x, info = gbsv(lower, upper, ab, rhs, overwrite_ab=True, overwrite_b=True)
    return x if info == 0 else np.full(n, np.nan)


def _append(K: SparseTangent, rows, cols, vals) -> SparseTangent:
    return SparseTangent(jnp.concatenate([K.rows, rows.astype(K.rows.dtype)]),
                         jnp.concatenate([K.cols, cols.astype(K.cols.dtype)]),
                         jnp.concatenate([K.vals, vals]), K.n)
