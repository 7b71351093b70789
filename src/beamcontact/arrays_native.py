"""Element-wise copies and comparisons of arrays, and a sorted search, for the compiled
kernels.

``dst[:] = src`` or ``dst[k] = src`` of whole arrays makes Numba compile, for each pair
of array types, its error message for mismatched shapes (the shapes formatted as
strings): about 2 s in each of the two processes of a cold start, whichever site comes
first (benchmarks/README.md, session 25). A loop compiles in milliseconds and copies the
same numbers. Callers pass arrays of equal shape; nothing is checked.

``np.searchsorted``, ``np.array_equal`` and ``np.finfo`` in a kernel tie its cached
machine code to Numba's ``numba.np.arraymath``, which loading the kernel imports, and
with it scipy.linalg (0.1 s of every warm run that would not load it otherwise; session
27): :func:`count_not_above`, :func:`equal` and :data:`EPS` compute the same numbers.
"""

import numpy as np

from beamcontact._native import njit


@njit
def copy_1d(dst, src):
    """dst[i] = src[i] for every i of src (1-d)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@njit
def copy_2d(dst, src):
    """dst[i, j] = src[i, j] for every (i, j) of src (2-d)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


# the spacing of float64 at 1.0, np.finfo(np.float64).eps, as a constant of the kernels
EPS = float(np.finfo(np.float64).eps)


@njit
def count_not_above(sorted_values, x):
    """How many of the ascending ``sorted_values`` are not above x:
    ``np.searchsorted(sorted_values, x, side="right")`` (a NaN x counts them all, as
    NumPy sorts NaN last), by bisection."""
    lo, hi = 0, sorted_values.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if x < sorted_values[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit
def equal(a, b):
    """``np.array_equal(a, b)``: the same shape and every entry equal (NaN equals
    nothing)."""
    if a.shape != b.shape:
        return False
    a_flat, b_flat = a.ravel(), b.ravel()  # views of C-contiguous arrays
    for i in range(a_flat.shape[0]):  # noqa: SIM110 (Numba compiles the loop, not all())
        if a_flat[i] != b_flat[i]:
            return False
    return True
