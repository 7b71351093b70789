"""The cost a parallel loop pays on two threads: an empty Numba ``prange`` of two
iterations timed on two threads and on one, printed as the difference per call in us.

On the 2-core machine of benchmarks/README.md (sessions 21-30) it is about 0.2 us in
some minutes and about 1.4 us in others (the hypervisor places the two vCPUs on cores
that share a cache or not; a two-thread ping-pong on one cache line: 90-130 ns against
390-460 ns), and the native engine's two-thread loops are fast or slow accordingly:
peers.py prints it before and after each timed run of beamcontact.

    python benchmarks/peers/fork_join.py
"""

import time

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def _touch(out):
    for i in numba.prange(out.shape[0]):
        out[i] += 1.0


def per_call_us(threads: int, calls: int = 2000, repeats: int = 5) -> float:
    """The least mean time of one call of the empty loop over ``repeats`` runs of
    ``calls`` calls on ``threads`` threads [us]."""
    numba.set_num_threads(threads)
    out = np.zeros(2)
    _touch(out)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            _touch(out)
        best = min(best, (time.perf_counter() - t0) / calls * 1e6)
    return best


def extra_us() -> float:
    """Two threads' time per call less one thread's [us] (0 with one core)."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        return 0.0
    one = per_call_us(1)
    return per_call_us(2) - one


if __name__ == "__main__":
    print(f"{extra_us():.2f}")
