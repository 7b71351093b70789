"""Element-wise copies of arrays for the compiled kernels.

``dst[:] = src`` or ``dst[k] = src`` of whole arrays makes Numba compile, for each pair
of array types, its error message for mismatched shapes (the shapes formatted as
strings): about 2 s in each of the two processes of a cold start, whichever site comes
first (benchmarks/README.md, session 25). A loop compiles in milliseconds and copies the
same numbers. Callers pass arrays of equal shape; nothing is checked.
"""

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
