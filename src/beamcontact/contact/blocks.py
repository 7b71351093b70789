"""Contact energy of element pairs: pair-level AD, aggregated per element pair.

For a block (element e1 of one beam, element e2 of another) with contact points
p1_i = R1_i x_e1 and p2_j = R2_j x_e2, the energy is sum_ij W_ij phi(|p1_i - p2_j|).
``jax.grad`` and ``jax.hessian`` of phi act on the 2-vector r_ij = p1_i - p2_j only; the
element-pair residual and the 2(n_loc) x 2(n_loc) tangent follow by small batched
products with the basis rows (DESIGN.md Sec. 7), before one scatter per block.

W_ij is w1_i w2_j (reference arc lengths) for the coarse-grained model, and the host's
selection of closest pairs (1, or 1/2 for the two middle pairs of an even plateau) for
IPIP.
"""

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from beamcontact.assembly.model import element_dofs
from beamcontact.contact.laws import LAWS
from beamcontact.contact.points import ContactElements


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ContactSet:
    """Candidate blocks frozen for one step: pairs (C, 2) global element indices (padding
    = E) and pair weights W (C, n_s, n_s); ``params`` the law parameters."""

    pairs: jax.Array
    W: jax.Array
    params: jax.Array


def _pair_law(law: str):
    """f(s, R12, amplitude, params) with s = |r|^2, and the per-block amplitude.

    Writing the pair energy through s = r . r keeps it smooth at r = 0 and makes its
    derivatives in r exact algebra on the scalar AD derivatives f' = df/ds, f'' (see
    :func:`_pair_derivatives`).
    """
    amplitude, energy = LAWS[law]

    def f(s, R12, amp, params):
        return energy(jnp.sqrt(jnp.where(s > 1e-300, s, 1e-300)), R12, amp, params)

    return f, amplitude


def _pair_derivatives(f):
    """Gradient and Hessian in r of phi(r) = f(r . r): 2 f' r and 2 f' I + 4 f'' r r^T,
    with f' and f'' from ``jax.grad`` of the scalar law."""
    df = jax.grad(f)
    d2f = jax.grad(df)

    def derivatives(r, R12, amp, params):
        s = r @ r
        f1, f2 = df(s, R12, amp, params), d2f(s, R12, amp, params)
        return 2.0 * f1 * r, 2.0 * f1 * jnp.eye(2) + 4.0 * f2 * jnp.outer(r, r)

    return derivatives


def _over_pairs(f):
    """vmap f(x, R12, amp, params) over blocks and both point indices of x (C, s, s, ...)."""
    inner = jax.vmap(jax.vmap(f, (0, None, None, None)), (0, None, None, None))
    return jax.vmap(inner, (0, 0, 0, None))


def _gather(ce: ContactElements, idx):
    """Element data with the sentinel index E mapped to element 0 (its weight is 0)."""
    safe = jnp.minimum(idx, ce.n_elements - 1)
    return (ce.conn[safe], ce.R[safe], ce.radius[safe], ce.beta[safe])


def block_weights_cg(ce: ContactElements, pairs):
    """W_ij = w1_i w2_j for real blocks, 0 for padding."""
    valid = (pairs[:, 0] < ce.n_elements)[:, None, None]
    e1 = jnp.minimum(pairs[:, 0], ce.n_elements - 1)
    e2 = jnp.minimum(pairs[:, 1], ce.n_elements - 1)
    return jnp.where(valid, ce.w[e1][:, :, None] * ce.w[e2][:, None, :], 0.0)


def block_distances(x, ce: ContactElements, pairs):
    """Centre-line distances of all point pairs of each block, shape (C, n_s, n_s)."""
    r = _block_geometry(x, ce, pairs)[2]
    return jnp.sqrt(jnp.sum(r * r, axis=-1))


def block_gaps(x, ce: ContactElements, pairs):
    """Surface gaps q = d - R1 - R2 of all point pairs of real blocks (+inf for padding)."""
    d = block_distances(x, ce, pairs)
    _, _, r1, _ = _gather(ce, pairs[:, 0])
    _, _, r2, _ = _gather(ce, pairs[:, 1])
    q = d - (r1 + r2)[:, None, None]
    return jnp.where((pairs[:, 0] < ce.n_elements)[:, None, None], q, jnp.inf)


def _block_geometry(x, ce: ContactElements, pairs):
    """Both elements' data of every block and the pair vectors r = p1_i - p2_j (C, s, s, 2)."""
    first, second = _gather(ce, pairs[:, 0]), _gather(ce, pairs[:, 1])
    p1 = jnp.einsum("csk,ckd->csd", first[1], x[first[0]])
    p2 = jnp.einsum("csk,ckd->csd", second[1], x[second[0]])
    return first, second, p1[:, :, None, :] - p2[:, None, :, :]


def contact_energy(x, ce: ContactElements, cs: ContactSet, law: str):
    """Total contact energy of the frozen blocks at control points x."""
    phi, amplitude = _pair_law(law)

    def add(total, part: ContactSet):
        (_, _, r1, b1), (_, _, r2, b2), r = _block_geometry(x, ce, part.pairs)
        amp = amplitude(r1, r2, b1 * b2, part.params)
        return total + jnp.sum(part.W * _over_pairs(phi)(jnp.sum(r * r, -1), r1 + r2, amp,
                                                          part.params))

    return _over_chunks(cs, add, jnp.zeros((), x.dtype))


CHUNK = 8


def contact_residual_tangent(x, ce: ContactElements, cs: ContactSet, law: str, n_dof: int):
    """Global contact force (gradient) and tangent (Hessian) of the frozen blocks."""
    zero = (jnp.zeros(n_dof, x.dtype), jnp.zeros((n_dof, n_dof), x.dtype))
    return _over_chunks(cs, lambda carry, part: _add_blocks(carry, x, ce, part, law), zero)


def _over_chunks(cs: ContactSet, add, init):
    """Fold ``add(carry, chunk)`` over the candidate list in chunks of CHUNK blocks,
    skipping (``lax.cond``) every chunk whose weights are all zero.

    The broad phase puts the real blocks first, so the cost follows the number of
    candidates, not the capacity: a generous capacity costs nothing and saves
    recompilations, and free flight costs nothing at all.
    """
    C = cs.pairs.shape[0]
    size = CHUNK if C % CHUNK == 0 else C
    chunks = jax.tree_util.tree_map(lambda a: a.reshape(C // size, size, *a.shape[1:]),
                                    (cs.pairs, cs.W))

    def body(carry, chunk):
        part = ContactSet(chunk[0], chunk[1], cs.params)
        # padding blocks, and IPIP blocks without a selected pair, have zero weights
        active = jnp.any(part.W != 0.0)
        return jax.lax.cond(active, lambda c: add(c, part), lambda c: c, carry), None

    return jax.lax.scan(body, init, chunks)[0]


def _add_blocks(carry, x, ce: ContactElements, cs: ContactSet, law: str):
    """Add the residual and tangent of the blocks of ``cs`` to carry = (res, K)."""
    res, K = carry
    phi, amplitude = _pair_law(law)
    (c1, R1, r1, b1), (c2, R2, r2, b2), r = _block_geometry(x, ce, cs.pairs)
    args = (r, r1 + r2, amplitude(r1, r2, b1 * b2, cs.params), cs.params)
    g, h = _over_pairs(_pair_derivatives(phi))(*args)
    G = cs.W[..., None] * g  # (C, s, s, 2)
    H = cs.W[..., None, None] * h
    f1 = jnp.einsum("cik,cija->cka", R1, G)
    f2 = -jnp.einsum("cjl,cija->cla", R2, G)
    K11 = jnp.einsum("cik,cil,ciab->ckalb", R1, R1, H.sum(axis=2))
    K22 = jnp.einsum("cjk,cjl,cjab->ckalb", R2, R2, H.sum(axis=1))
    K12 = -jnp.einsum("cik,cijab,cjl->ckalb", R1, H, R2)
    C, n_loc = c1.shape
    m = 2 * n_loc
    k = jnp.zeros((C, 2 * m, 2 * m))
    k = k.at[:, :m, :m].set(K11.reshape(C, m, m))
    k = k.at[:, m:, m:].set(K22.reshape(C, m, m))
    k = k.at[:, :m, m:].set(K12.reshape(C, m, m))
    k = k.at[:, m:, :m].set(jnp.swapaxes(K12.reshape(C, m, m), 1, 2))
    f = jnp.concatenate([f1.reshape(C, m), f2.reshape(C, m)], axis=1)
    dofs = jnp.concatenate([element_dofs(c1), element_dofs(c2)], axis=1)
    return res.at[dofs].add(f), K.at[dofs[:, :, None], dofs[:, None, :]].add(k)
