"""Contact energy of element pairs: pair-level AD, aggregated per element pair.

For a block (element e1 of one beam, element e2 of another) with contact points
p1_i = R1_i x_e1 and p2_j = R2_j x_e2, the energy is sum_ij W_ij phi(|p1_i - p2_j|).
AD acts on the scalar law f(s) = phi(sqrt(s)) of s = r . r, r_ij = p1_i - p2_j, only
(f' and f''); the gradient 2 f' r and Hessian 2 f' I + 4 f'' r r^T in r, then the
element-pair residual and the 2(n_loc) x 2(n_loc) tangent, follow by small batched
products with the basis rows (docs/architecture.md, "Energies and assembly"); the
assembly scatters them, one chunk of blocks at a time (:func:`fold_block_forces`).

W_ij is w1_i w2_j (reference arc lengths) for the coarse-grained model, computed chunk by
chunk from the element indices (``ContactSet.W`` is None), and the weights of the
closest-pair selection for IPIP (:mod:`beamcontact.contact.select`: 1 or 1/2 per zone for
"zones", chosen on the host; shares of 1/2 per point for "points", chosen on the device in
dynamics).
"""

from __future__ import annotations

from dataclasses import dataclass

from beamcontact._jax import jax, jnp, pytree
from beamcontact.contact.laws import ContactLaw
from beamcontact.contact.obstacles import Obstacles
from beamcontact.contact.points import ContactElements


@pytree
@dataclass(frozen=True)
class ContactSet:
    """Candidate blocks frozen for one step: pairs (C, 2) global element indices (padding
    = E); pair weights W (C, n_s, n_s), or None for the reference arc-length weights of
    an integrated law (:func:`arc_length_weights`, formed chunk by chunk inside the
    kernels, never as a whole list); ``law`` the contact law."""

    pairs: jax.Array
    W: jax.Array | None
    law: ContactLaw


@pytree
@dataclass(frozen=True)
class FrozenContact:
    """What the assembly needs of contact in one step: the contact points of every
    element, the frozen set of candidate blocks (with its law) and the rigid obstacles
    (None: none; :mod:`beamcontact.contact.obstacles`). No contact is None."""

    elements: ContactElements
    blocks: ContactSet
    obstacles: Obstacles | None = None


def _pair_law(law: ContactLaw):
    """f(s, R12, amplitude) with s = |r|^2.

    Writing the pair energy through s = r . r keeps it smooth at r = 0 and makes its
    derivatives in r exact algebra on the scalar AD derivatives f' = df/ds, f'' (see
    :func:`_pair_derivatives`).
    """

    def f(s, R12, amp):
        return law.pair_energy(jnp.sqrt(jnp.where(s > 1e-300, s, 1e-300)), R12, amp)

    return f


def _pair_derivatives(f):
    """(f', f'') = (df/ds, d2f/ds2) of the scalar law, both from AD: the gradient in r of
    phi(r) = f(r . r) is 2 f' r and its Hessian 2 f' I + 4 f'' r r^T."""
    df = jax.grad(f)

    def derivatives(s, R12, amp):
        # f' and f'' in one forward pass over f' (they share every transcendental)
        return jax.jvp(lambda s: df(s, R12, amp), (s,), (jnp.ones_like(s),))

    return derivatives


def _over_pairs(f):
    """vmap f(x, R12, amp) over blocks and both point indices of x (C, s, s, ...)."""
    inner = jax.vmap(jax.vmap(f, (0, None, None)), (0, None, None))
    return jax.vmap(inner, (0, 0, 0))


def _gather(ce: ContactElements, idx):
    """(control points, basis rows, radius, density) of elements ``idx``, the sentinel
    index E mapped to element 0 (its weight is 0)."""
    safe = jnp.minimum(idx, ce.n_elements - 1)
    return (ce.conn[safe], ce.R[safe], ce.radius[safe], ce.beta[safe])


def point_mask(ce: ContactElements, pairs):
    """(C, n_s, n_s): the point pairs of real blocks that may interact (padding blocks,
    and neighbours along one beam under self-contact, are False;
    :meth:`ContactElements.point_mask`)."""
    valid = (pairs[:, 0] < ce.n_elements)[:, None, None]
    e1 = jnp.minimum(pairs[:, 0], ce.n_elements - 1)
    e2 = jnp.minimum(pairs[:, 1], ce.n_elements - 1)
    return valid & ce.point_mask(e1, e2)


def arc_length_weights(ce: ContactElements, pairs):
    """W_ij = w1_i w2_j for the point pairs that may interact, 0 for the rest."""
    e1 = jnp.minimum(pairs[:, 0], ce.n_elements - 1)
    e2 = jnp.minimum(pairs[:, 1], ce.n_elements - 1)
    return jnp.where(point_mask(ce, pairs), ce.w[e1][:, :, None] * ce.w[e2][:, None, :], 0.0)


def over_real_chunks(f, ce: ContactElements, pairs, fill):
    """``f(chunk)`` over the block list in chunks of CHUNK blocks, concatenated; a chunk
    with no real block is not evaluated and gives ``fill`` (its output shape).

    The lists put their real blocks first (the broad phase, the culling and the IPIP
    selection all do), so the cost follows the number of candidates, not the capacity:
    in free flight a step's checks over a list of 128 empty slots cost nothing.
    """
    C = pairs.shape[0]
    size = CHUNK if C % CHUNK == 0 else C
    chunks = pairs.reshape(C // size, size, 2)
    shape = jax.eval_shape(f, chunks[0])

    def skip(_):
        return jnp.full(shape.shape, fill, shape.dtype)

    def body(carry, chunk):
        return carry, jax.lax.cond(jnp.any(chunk[:, 0] < ce.n_elements), f, skip, chunk)

    out = jax.lax.scan(body, None, chunks)[1]
    return out.reshape(C, *out.shape[2:])


def block_distances(x, ce: ContactElements, pairs):
    """Centre-line distances of all point pairs of each block, shape (C, n_s, n_s)
    (+inf for the pairs that may not interact, and in chunks of padding blocks, which are
    skipped)."""

    def distances(chunk):
        r = _block_geometry(x, ce, chunk)[2]
        return jnp.where(point_mask(ce, chunk), jnp.sqrt(jnp.sum(r * r, axis=-1)), jnp.inf)

    return over_real_chunks(distances, ce, pairs, jnp.inf)


def near_blocks(x, ce: ContactElements, pairs, limit):
    """The blocks of ``pairs`` with a point pair closer than ``limit`` (centre-line
    distance at x), moved to the front in their original order; the rest become padding.

    The boxes of the broad phase are loose (a quartic element's control polygon is much
    larger than the element), so only a third of their candidates, and an eighth of
    their point pairs, are within the coarse-grained cutoff; a block with no pair inside
    it contributes exactly zero and need not be evaluated in the Newton loop.
    """
    d = jnp.min(block_distances(x, ce, pairs), axis=(1, 2))
    keep = (pairs[:, 0] < ce.n_elements) & (d < limit)
    order = jnp.argsort(~keep, stable=True)
    return jnp.where(keep[order][:, None], pairs[order], ce.sentinel)


def block_gaps(x, ce: ContactElements, pairs, d=None):
    """Surface gaps q = d - R1 - R2 of all point pairs of real blocks (+inf for padding);
    ``d``: their :func:`block_distances`, when already at hand."""
    d = block_distances(x, ce, pairs) if d is None else d
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


def contact_energy(x, ce: ContactElements, cs: ContactSet):
    """Total contact energy of the frozen blocks at control points x."""
    phi = _pair_law(cs.law)

    def add(total, part: ContactSet):
        (_, _, r1, b1), (_, _, r2, b2), r = _block_geometry(x, ce, part.pairs)
        amp = part.law.amplitude(r1, r2, b1 * b2)
        return total + jnp.sum(part.W * _over_pairs(phi)(jnp.sum(r * r, -1), r1 + r2, amp))

    return _over_chunks(ce, cs, add, jnp.zeros((), x.dtype))


CHUNK = 4


def fold_block_forces(x, ce: ContactElements, cs: ContactSet, add, init):
    """Fold ``add(carry, conn, f, k)`` over the frozen blocks, a chunk at a time: conn
    (C, 2 n_loc) the control points of both elements of each block, f (C, 4 n_loc) the
    gradient of its energy and k (C, 4 n_loc, 4 n_loc) its Hessian, in the order of
    ``x[conn].ravel()``. The assembly scatters them (it alone knows the global dofs)."""
    return _over_chunks(ce, cs, lambda carry, part: add(carry, *_block_forces(x, ce, part)),
                        init)


def _over_chunks(ce: ContactElements, cs: ContactSet, add, init):
    """Fold ``add(carry, chunk)`` over the candidate list in chunks of CHUNK blocks,
    skipping (``lax.cond``) every chunk whose weights are all zero; each chunk reaches
    ``add`` with its weights W filled in.

    The broad phase puts the real blocks first, so the cost follows the number of
    candidates, not the capacity: a generous capacity costs nothing and saves
    recompilations, and free flight costs nothing at all.
    """
    def body(carry, part):
        # padding blocks, and IPIP blocks without a selected pair, have zero weights
        active = jnp.any(part.W != 0.0)
        return jax.lax.cond(active, lambda c: add(c, part), lambda c: c, carry), None

    return _scan_chunks(ce, cs, body, init)[0]


def _scan_chunks(ce: ContactElements, cs: ContactSet, body, init):
    """``lax.scan`` of ``body(carry, part)`` over the candidate list in chunks of CHUNK
    blocks, each chunk as a ContactSet with its weights filled in."""
    C = cs.pairs.shape[0]
    size = CHUNK if C % CHUNK == 0 else C
    chunks = jax.tree_util.tree_map(lambda a: a.reshape(C // size, size, *a.shape[1:]),
                                    (cs.pairs, cs.W))

    def weighted(carry, chunk):
        pairs, W = chunk
        part = ContactSet(pairs, arc_length_weights(ce, pairs) if W is None else W, cs.law)
        return body(carry, part)

    return jax.lax.scan(weighted, init, chunks)


def block_forces(x, ce: ContactElements, cs: ContactSet):
    """(conn, gradient, Hessian) of every block at once, in the layout of
    :func:`fold_block_forces`, for an assembly that keeps the blocks (the sparse tangent);
    chunks without a weight are skipped and give zeros (conn 0)."""

    def body(carry, part):
        shapes = jax.eval_shape(lambda p: _block_forces(x, ce, p), part)

        def skip(_):
            return tuple(jnp.zeros(s.shape, s.dtype) for s in shapes)

        active = jnp.any(part.W != 0.0)
        return carry, jax.lax.cond(active, lambda p: _block_forces(x, ce, p), skip, part)

    conn, f, k = _scan_chunks(ce, cs, body, None)[1]
    return tuple(a.reshape(-1, *a.shape[2:]) for a in (conn, f, k))


def _block_forces(x, ce: ContactElements, cs: ContactSet):
    """(conn, gradient, Hessian) of every block of ``cs`` (see :func:`fold_block_forces`).

    With A = 2 W f' and B = 4 W f'' per point pair, the pair Hessian is
    A I + B r r^T: its three distinct components (xx, xy, yy) are scalar fields over the
    pairs, so each element-pair tangent is three small products rows1^T H_ab rows2 (and the
    diagonal blocks R^T diag(row sums) R), never a (C, s, s, 2, 2) array.
    """
    (c1, rows1, r1, b1), (c2, rows2, r2, b2), r = _block_geometry(x, ce, cs.pairs)
    f1, f2 = _over_pairs(_pair_derivatives(_pair_law(cs.law)))(
        jnp.sum(r * r, -1), r1 + r2, cs.law.amplitude(r1, r2, b1 * b2))
    A, B = 2.0 * cs.W * f1, 4.0 * cs.W * f2  # (C, s, s)
    G = A[..., None] * r  # gradient of each pair's energy in r
    rx, ry = r[..., 0], r[..., 1]
    H = jnp.stack([A + B * rx * rx, B * rx * ry, A + B * ry * ry], axis=1)  # (C, 3, s, s)
    g1 = jnp.einsum("cik,cija->cka", rows1, G)
    g2 = -jnp.einsum("cjl,cija->cla", rows2, G)
    H11 = jnp.einsum("cik,cmi,cil->cmkl", rows1, H.sum(axis=3), rows1)
    H22 = jnp.einsum("cjk,cmj,cjl->cmkl", rows2, H.sum(axis=2), rows2)
    H12 = -jnp.einsum("cik,cmij,cjl->cmkl", rows1, H, rows2)
    C, n_loc = c1.shape
    m = 2 * n_loc

    def dofs_major(Hm):  # (C, 3, k, l) -> (C, 2 k + a, 2 l + b), the x_e.ravel() order
        xx, xy, yy = Hm[:, 0], Hm[:, 1], Hm[:, 2]
        return jnp.stack([jnp.stack([xx, xy], -1), jnp.stack([xy, yy], -1)], 2).reshape(C, m, m)

    K11, K22, K12 = dofs_major(H11), dofs_major(H22), dofs_major(H12)
    k = jnp.concatenate([jnp.concatenate([K11, K12], 2),
                         jnp.concatenate([jnp.swapaxes(K12, 1, 2), K22], 2)], 1)
    f = jnp.concatenate([g1.reshape(C, m), g2.reshape(C, m)], axis=1)
    return jnp.concatenate([c1, c2], axis=1), f, k
