"""Time stepping with HHT-alpha, automatic cut-back and recovery of the nominal step.

A failed Newton solve (iteration limit or a non-finite value) restarts the step from the
last accepted state with half the step, up to ``max_cutbacks`` successive halvings; each
accepted step doubles the step back towards the nominal ``dt``. The last step is shortened
to land on ``t_end``. Every accepted step goes to ``on_step`` at once.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from beamcontact.assembly.inertia import kinetic_energy_and_momentum
from beamcontact.assembly.model import Model
from beamcontact.assembly.system import energies
from beamcontact.dynamics.hht import DynState, hht_step
from beamcontact.solvers.newton import NewtonOptions


@dataclass(frozen=True)
class DynamicStep:
    """One accepted time step (host values)."""

    step: int
    t: float
    dt: float
    state: DynState
    iterations: int
    cutbacks: int
    diagnostics: dict


@dataclass(frozen=True)
class DynamicResult:
    """Outcome of a dynamic analysis; ``state`` and ``dt_next`` allow a restart."""

    status: str  # "completed" | "failed"
    message: str
    steps: int
    iterations: int
    cutbacks: int
    t: float
    state: DynState
    dt_next: float
    wall_time: float
    compile_time: float


@jax.jit
def diagnostics(state: DynState, model: Model) -> dict:
    """Energies and linear momentum of a state."""
    e = energies(state.u, model, 1.0, state.load_state)
    e_kin, p = kinetic_energy_and_momentum(state.u, state.v, model)
    return {**e, "E_kin": e_kin, "p_x": p[0], "p_y": p[1]}


def host_diagnostics(state: DynState, model: Model) -> dict:
    """:func:`diagnostics` as Python floats, with E_total."""
    d = {k: float(v) for k, v in diagnostics(state, model).items()}
    d["E_total"] = d["E_kin"] + d["E_strain"] + d["E_gravity"] + d["E_ext"]
    return d


def solve_dynamic(model: Model, state: DynState, t_end: float, dt: float, alpha: float,
                  options: NewtonOptions, length: float, max_cutbacks: int = 12, *,
                  dt_start: float | None = None, step0: int = 0,
                  on_step: Callable[[DynamicStep], None] | None = None) -> DynamicResult:
    """Integrate from ``state`` to ``t_end``.

    Args:
        model: the discrete model.
        state: initial (or restart) state.
        t_end: final time; dt: nominal step; alpha: HHT parameter in [-1/3, 0].
        options: Newton settings; length: scale of the increment tolerance.
        max_cutbacks: successive halvings allowed before giving up.
        dt_start: the step to try first (a restart passes the interrupted run's).
        step0: number of the last accepted step (restart).
        on_step: called with every accepted step.
    """
    start = time.perf_counter()
    rtol = jnp.asarray(options.rtol)
    utol = jnp.asarray(options.utol * length)
    alpha_arr = jnp.asarray(alpha, dtype=jnp.float64)
    t = float(state.t)
    dt_cur = dt if dt_start is None else dt_start
    steps = iterations = cutbacks = consecutive = 0
    compile_time = 0.0
    first = True
    while t_end - t > 1e-12 * max(dt, t_end):
        h = _step_size(t, t_end, dt_cur)
        t0 = time.perf_counter()
        new, res = hht_step(state, model, jnp.asarray(h), alpha_arr, rtol, utol,
                            max_iterations=options.max_iterations)
        converged = bool(res.converged)
        if first:
            compile_time = time.perf_counter() - t0
            first = False
        iterations += int(res.iterations)
        if not converged:
            cutbacks += 1
            consecutive += 1
            if consecutive > max_cutbacks:
                return DynamicResult(
                    "failed",
                    f"Newton did not converge at t = {t + h:.6g} s ({int(res.iterations)} "
                    f"iterations, residual {float(res.residual_norm):.3e} from "
                    f"{float(res.initial_residual_norm):.3e}) after {consecutive - 1} "
                    f"successive halvings of the time step (now {h:.3g} s); the last "
                    f"accepted time is {t:.6g} s",
                    steps, iterations, cutbacks, t, state, dt_cur,
                    time.perf_counter() - start, compile_time)
            dt_cur = 0.5 * h
            continue
        consecutive = 0
        t = _on_grid(t + h, dt, t_end)
        state = replace(new, t=jnp.asarray(t))
        steps += 1
        if on_step is not None:
            on_step(DynamicStep(step0 + steps, t, h, state, int(res.iterations), cutbacks,
                                host_diagnostics(state, model)))
        dt_cur = min(2.0 * dt_cur, dt)
    return DynamicResult("completed", f"reached t = {t:.6g} s in {steps} steps", steps,
                         iterations, cutbacks, t, state, dt_cur, time.perf_counter() - start,
                         compile_time)


def _step_size(t: float, t_end: float, dt_cur: float) -> float:
    """The next step: dt_cur, shortened to land on t_end without leaving a sliver."""
    remaining = t_end - t
    if abs(remaining - dt_cur) <= 1e-9 * dt_cur:
        return dt_cur  # exactly nominal, so a restart repeats the same arithmetic
    h = min(dt_cur, remaining)
    return remaining if remaining - h < 1e-6 * h else h


def _on_grid(t: float, dt: float, t_end: float) -> float:
    """Snap a time within round-off of a multiple of the nominal step (or of t_end) onto it,
    so that times do not drift and a restarted run is identical to an uninterrupted one."""
    k = round(t / dt)
    if abs(t - k * dt) <= 1e-9 * dt:
        return k * dt
    return t_end if abs(t - t_end) <= 1e-9 * dt else t


def uniform_velocities(disc, velocities) -> np.ndarray:
    """Global control-point velocities from one uniform velocity per beam (flat)."""
    v = np.zeros((disc.n_cp, 2))
    for info, vel in zip(disc.beams, velocities, strict=True):
        v[info.offset : info.offset + info.n_cp] = vel
    return v.ravel()
