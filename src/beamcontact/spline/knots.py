"""Open knot vectors on [0, 1].

An interior knot of multiplicity m gives continuity C^(p-m) there (Piegl & Tiller, Sec. 2.2).
"""

import numpy as np


def open_uniform_knots(degree: int, elements: int, continuity: int) -> np.ndarray:
    """Open knot vector with ``elements`` equal spans and interior continuity C^continuity.

    Args:
        degree: polynomial degree p >= 1.
        elements: number of non-empty knot spans (elements), >= 1.
        continuity: 0 <= continuity <= p - 1; interior multiplicity is p - continuity.
    """
    if degree < 1 or elements < 1 or not 0 <= continuity <= degree - 1:
        raise ValueError(f"invalid knot vector: degree={degree}, elements={elements}, "
                         f"continuity={continuity}")
    mult = degree - continuity
    inner = np.repeat(np.arange(1, elements) / elements, mult)
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


def interior_knots(knots: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Distinct interior knot values and their multiplicities."""
    inner = np.asarray(knots)[degree + 1 : len(knots) - degree - 1]
    if inner.size == 0:
        return np.zeros(0), np.zeros(0, dtype=int)
    values, counts = np.unique(inner, return_counts=True)
    return values, counts


def element_breaks(knots: np.ndarray) -> np.ndarray:
    """Distinct knot values: the element boundaries, from 0 to 1."""
    return np.unique(np.asarray(knots))
