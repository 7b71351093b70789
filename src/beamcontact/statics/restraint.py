"""Rigid-body modes that the supports leave free: mechanisms of a static analysis.

A static problem is solvable only if its tangent on the free dofs is regular. At the
stress-free reference (u = 0) the strain energy of a beam is invariant under rigid
motions, so the infinitesimal rigid motions of its control points,
    v_i = a + omega J x_i,   J = [[0, -1], [1, 0]]      (3 modes: x, y, rotation),
are exact null vectors of its own stiffness (the control points of a NURBS curve move
rigidly with it: affine invariance). Supports fix control points; the modes that vanish
on every fixed dof are not restrained by them. Such a mode makes the static tangent
singular unless contact with another beam restrains it (loads never do).

Two checks use this, both on the host with NumPy (small 3 x 3 or n x 3 problems):
- ``build.checks.static_mechanisms``, from the case alone: a beam with unrestrained modes
  and no contact partner is a mechanism (invalid input);
- :func:`singular_tangent_message`, from the assembled tangent at u = 0 (contact included):
  the modes that neither supports nor contact restrain.
"""

from collections.abc import Sequence

import numpy as np

# a mode v is in the null space of K when ||K v|| <= NULL_TOL ||K|| ||v||: round-off of
# the assembled stiffness leaves 1e-17 to 1e-15; a contact that holds a beam gives much
# more, even when soft (1e-8: a penalty of 1e6 N/m on beams with E = 1e15 Pa, the IPIP
# reaction test of test_contact.py)
NULL_TOL = 1e-12


def rigid_modes(x: np.ndarray) -> np.ndarray:
    """Infinitesimal rigid motions of the points x (n, 2) as columns of a (2n, 3) matrix:
    translations in x and y and a rotation about the centroid, each of unit norm."""
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    r = x - x.mean(axis=0)
    modes = np.zeros((n, 2, 3))
    modes[:, 0, 0] = 1.0
    modes[:, 1, 1] = 1.0
    modes[:, 0, 2], modes[:, 1, 2] = -r[:, 1], r[:, 0]
    modes = modes.reshape(2 * n, 3)
    norms = np.linalg.norm(modes, axis=0)
    return modes / np.where(norms > 0.0, norms, 1.0)


def unrestrained_modes(x: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Orthonormal basis (2n, m) of the rigid modes of points x (n, 2) that vanish on the
    fixed dofs (boolean, 2n): the null space of the modes' fixed rows, by SVD."""
    phi = rigid_modes(x)
    if not np.any(fixed):
        return phi
    if np.ptp(x[:, 0]) + np.ptp(x[:, 1]) == 0.0:  # all points coincide: no rotation
        phi = phi[:, :2]
    _, s, vt = np.linalg.svd(phi[fixed], full_matrices=True)
    rank = int(np.sum(s > 1e-10 * max(s[0], 1e-300)))
    basis = phi @ vt[rank:].T
    if basis.shape[1] == 0:
        return basis
    q, _ = np.linalg.qr(basis)
    return q


def describe_modes(x: np.ndarray, modes: np.ndarray) -> str:
    """Words for a set of rigid modes of points x: translation and rotation, or rotation
    about a point (one mode that is a rotation about a fixed centre c = J a / omega)."""
    m = modes.shape[1]
    if m == 1:
        v = modes[:, 0].reshape(-1, 2)
        # least-squares fit v_i = a + omega J x_i
        n = x.shape[0]
        A = np.zeros((2 * n, 3))
        A[0::2, 0] = A[1::2, 1] = 1.0
        A[0::2, 2], A[1::2, 2] = -x[:, 1], x[:, 0]
        (ax, ay, omega), *_ = np.linalg.lstsq(A, v.ravel(), rcond=None)
        if abs(omega) > 1e-8 * np.hypot(ax, ay):
            c = np.array([-ay, ax]) / omega
            return f"it can rotate about ({_num(c[0])}, {_num(c[1])})"
        return "it can translate freely"
    if m == 2:
        return "it can translate freely"
    return "it can translate and rotate freely"


def _num(v: float) -> str:
    return f"{0.0 if abs(v) < 1e-12 else v:.4g}"


def _plural(m: int) -> str:
    return f"{m} rigid-body mode{'s' if m != 1 else ''}"


HINT = "add supports: clamp an end, or pin both ends"


def beam_ranges(conns: Sequence[np.ndarray]) -> list[tuple[int, int]]:
    """Control-point ranges [start, stop) of the beams, from the element connectivities:
    the elements of one beam share control points, those of different beams do not, and
    each beam's points are numbered consecutively (assembly/model.py)."""
    conn = np.concatenate([np.asarray(c).reshape(len(c), -1) for c in conns])
    spans = np.column_stack([conn.min(axis=1), conn.max(axis=1)])
    spans = spans[np.argsort(spans[:, 0], kind="stable")]
    ranges = []
    for lo, hi in spans:
        if ranges and lo < ranges[-1][1]:  # shares a point with the beam so far
            ranges[-1][1] = max(ranges[-1][1], hi + 1)
        else:
            ranges.append([lo, hi + 1])
    return [(int(a), int(b)) for a, b in ranges]


def beam_modes(x_ref: np.ndarray, free: np.ndarray, ranges) -> list[np.ndarray]:
    """Per beam, its rigid modes not restrained by supports, on its own dofs (2 n_b, m)."""
    return [unrestrained_modes(x_ref[a:b], ~free[2 * a:2 * b]) for a, b in ranges]


def _nullity(KQ: np.ndarray, scale: float) -> tuple[int, np.ndarray]:
    """Number of combinations of the columns of Q that K maps to (numerically) zero, and
    their coefficients: the right singular vectors of K Q with sigma <= NULL_TOL scale."""
    if KQ.shape[1] == 0:
        return 0, np.zeros((0, 0))
    _, s, vt = np.linalg.svd(KQ, full_matrices=False)
    null = s <= NULL_TOL * scale
    return int(np.sum(null)), vt[null].T


def singular_tangent_message(K: np.ndarray, free: np.ndarray, x_ref: np.ndarray, ranges,
                             labels: Sequence[str], contact: bool = False) -> str | None:
    """Why the tangent K (unconstrained, at u = 0) is singular on the free dofs, or None if
    every beam's unrestrained rigid modes are restrained (by contact).

    Args:
        K: the assembled tangent (n, n), contact included, loads at zero.
        free: boolean mask of the free dofs (n,).
        x_ref: reference control points (n / 2, 2).
        ranges: control-point range [start, stop) of every beam (:func:`beam_ranges`).
        labels: how the message names each beam (e.g. its quoted name).
        contact: whether K includes contact (the message then says that contact does not
            hold the beam either).

    Beam by beam: the modes v of the beam with K_ff v = 0 (nothing holds it); then all
    beams together, for modes held only by contact among beams none of which is supported
    (two free beams pressed on each other).
    """
    K = np.asarray(K) * free[:, None] * free[None, :]
    scale = float(np.max(np.sum(np.abs(K), axis=1)))  # ||K||_inf >= ||K||_2
    n = K.shape[0]
    by = "its supports or by contact in the initial configuration" if contact else \
        "its supports"
    problems, total, embedded = [], 0, []
    for label, (a, b), Q in zip(labels, ranges, beam_modes(x_ref, free, ranges), strict=True):
        full = np.zeros((n, Q.shape[1]))
        full[2 * a:2 * b] = Q
        embedded.append(full)
        k, coeff = _nullity(K @ full, scale)
        total += k
        if k:
            problems.append(f"beam {label} has {_plural(k)} not restrained by {by} "
                            f"({describe_modes(x_ref[a:b], Q @ coeff)})")
    k_all, coeff = _nullity(K @ np.concatenate(embedded, axis=1), scale)
    if k_all > total:
        bounds = np.cumsum([0] + [Q.shape[1] for Q in embedded])
        group = [label for label, lo, hi in zip(labels, bounds[:-1], bounds[1:], strict=True)
                 if hi > lo and np.linalg.norm(coeff[lo:hi]) > 1e-6]
        problems.append(f"beams {_join(group)} are held only by contact with each other: "
                        f"together they have {_plural(k_all - total)} not restrained by "
                        f"supports")
    if not problems:
        return None
    return f"the stiffness matrix is singular: {'; '.join(problems)}; {HINT}"


def _join(words: list[str]) -> str:
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"
