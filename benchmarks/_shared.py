"""Pieces the benchmark scripts share: a best-of timer and the one-beam scaling case."""

import time


def best_ms(f, n=30) -> float:
    """Best of 5 means over n calls of f (its result blocked on), in ms, after one
    warm-up call."""
    import jax

    jax.block_until_ready(f())
    best = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            r = f()
        jax.block_until_ready(r)
        best.append((time.perf_counter() - t0) / n)
    return 1e3 * min(best)


def pinned_beam_case(n: int) -> dict:
    """A 10 m beam pinned at both ends under gravity, n quartic C^3 elements (n + 4
    control points), 0.01 s at dt = 1e-4 s, as a raw case table."""
    return {"analysis": {"kind": "dynamic", "t_end": 0.01, "dt": 1e-4, "alpha": -0.1,
                         "gravity": [0.0, -9.81]},
            "beams": [{"name": "beam", "line": {"start": [0.0, 0.0], "end": [10.0, 0.0]},
                       "degree": 4, "elements": n, "continuity": 3,
                       "section": {"shape": "circle", "radius": 0.1},
                       "material": {"E": 1e7, "density": 1000.0},
                       "supports": [{"at": "start", "type": "pinned"},
                                    {"at": "end", "type": "pinned"}]}]}
