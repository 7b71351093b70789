"""IPIP: the closest integration-point pairs (paper Sec. 2.1), chosen on the host per step.

For each pair of beams, the discrete distance d(i, j) lives on the grid of their contact
points. Active pairs are its local minima (no neighbour of the 8-neighbourhood is closer
by more than a round-off tolerance) with a gap below ``q_active``: one pair per contact
zone. Local minima that touch form a plateau (straight parallel beams give a valley of
equal distances): the plateau is one zone and its middle pair is taken, or, for an even
number of cells, the two middle pairs with weight 1/2 each, so that symmetric problems
stay symmetric. Cells of a plateau are ordered lexicographically by (i, j).
"""

import numpy as np
from scipy import ndimage


def closest_pair_weights(q: np.ndarray, pairs: np.ndarray, beam_of: np.ndarray,
                         local_element: np.ndarray, n_elements: np.ndarray, q_active: float,
                         rtol: float = 1e-9) -> np.ndarray:
    """Pair weights W (C, n_s, n_s) of the IPIP model from the block gaps q (C, n_s, n_s).

    Args:
        q: gaps of every point pair of every candidate block (inf for padding blocks).
        pairs: the blocks' global element indices (C, 2); padding rows are >= E.
        beam_of: beam of every global element.
        local_element: index within its beam of every global element.
        n_elements: number of elements of every beam.
        q_active: pairs with a larger gap are left out (they cannot touch in this step).
        rtol: relative tolerance of "equal distance" on plateaus.
    """
    C, ns, _ = q.shape
    W = np.zeros_like(q)
    E = len(beam_of)
    real = np.where(pairs[:, 0] < E)[0]
    if real.size == 0:
        return W
    keys = {}
    for c in real:
        keys.setdefault((beam_of[pairs[c, 0]], beam_of[pairs[c, 1]]), []).append(c)
    for (b1, b2), blocks in keys.items():
        n1, n2 = n_elements[b1] * ns, n_elements[b2] * ns
        grid = np.full((n1 + 2, n2 + 2), np.inf)
        owner = np.full((n1 + 2, n2 + 2), -1)
        for c in blocks:
            i0 = local_element[pairs[c, 0]] * ns + 1
            j0 = local_element[pairs[c, 1]] * ns + 1
            grid[i0 : i0 + ns, j0 : j0 + ns] = q[c]
            owner[i0 : i0 + ns, j0 : j0 + ns] = c
        centre = grid[1:-1, 1:-1]
        tol = rtol * np.maximum(1.0, np.abs(np.where(np.isfinite(centre), centre, 0.0)))
        is_min = np.isfinite(centre) & (centre < q_active)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                if di or dj:
                    nb = grid[1 + di : n1 + 1 + di, 1 + dj : n2 + 1 + dj]
                    is_min &= centre <= nb + tol
        labels, count = ndimage.label(is_min, structure=np.ones((3, 3)))
        for lab in range(1, count + 1):
            cells = np.argwhere(labels == lab)  # lexicographic (i, j) order
            k = len(cells)
            chosen = [(cells[k // 2], 1.0)] if k % 2 else [(cells[k // 2 - 1], 0.5),
                                                            (cells[k // 2], 0.5)]
            for (i, j), weight in chosen:
                c = owner[i + 1, j + 1]
                W[c, i - (local_element[pairs[c, 0]] * ns), j - (local_element[pairs[c, 1]] * ns)] \
                    += weight
    return W
