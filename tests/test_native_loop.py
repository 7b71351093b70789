"""The compiled time loop of the native engine (dynamics/native_loop.py) against the host
loop of dynamics/driver.py, and what it promises a run (docs/architecture.md, "Engines").

Both loops call the same compiled attempt and the same step controller
(dynamics/control.py), so for one engine they must make exactly the same attempts: the
same steps, rejections and states, bit for bit. The host loop is the independent
reference here: its control flow is plain Python that the JAX engine's parity tests
exercise. And a run interrupted inside a compiled call (Ctrl-C) must still hand over
every step accepted before it.
"""

import _thread
import os
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

from beamcontact.api import load_case
from beamcontact.dynamics.driver import solve_dynamic
from beamcontact.io.case import parse_case
from beamcontact.setup.start import dynamic_start, prepare

REPO = Path(__file__).resolve().parents[1]


class HostLooped:
    """A native engine driven attempt by attempt by the driver's host loop."""

    runs_loop = False

    def __init__(self, engine):
        self._engine = engine
        self.name, self.contact = engine.name, engine.contact

    def __getattr__(self, name):
        return getattr(self._engine, name)


def _drop(model: str, t_end: float, pairing: str | None = None) -> dict:
    """The bundled drop (examples/free_fall) to t_end, with ``model``'s contact law."""
    case = load_case(REPO / "examples" / "free_fall" / f"case_{model}.toml")
    raw = case.model_dump(mode="json", exclude_none=True)
    raw["analysis"]["t_end"] = t_end
    if pairing is not None:
        raw["contact"]["pairing"] = pairing
    raw["solver"] = {**raw.get("solver", {}), "engine": "native"}
    return raw


def _solve(raw: dict, host: bool, capacity: int = 64):
    start = dynamic_start(prepare(parse_case(raw)))
    engine = HostLooped(start.engine) if host else start.engine
    assert engine.runs_loop is not host
    rows = []
    res = solve_dynamic(engine, start.state, raw["analysis"]["t_end"], start.prepared.length,
                        start.control, on_step=rows.append, capacity=capacity)
    assert res.status == "completed", res.message
    if not host:  # the compiled loop's seconds per thread count (summary's loop_threads)
        seconds = start.engine.thread_seconds
        assert seconds and all(1 <= k <= (os.cpu_count() or 1) for k in seconds)
        assert 0 < sum(seconds.values()) <= res.wall_time
        # before CoreShare's first reading: one thread
        assert 0.0 <= start.engine.probe_seconds <= seconds.get(1, 0.0)
    return res, rows


@pytest.mark.parametrize("variant", [("cg", None), ("ipip", "points"), ("ipip", "zones")])
def test_compiled_loop_makes_the_host_loops_steps(variant):
    """Through the first impact (0.75 s) of the bundled drop: identical step sequences,
    rejections by kind, states and energy accounts."""
    raw = _drop(variant[0], 0.8, variant[1])
    (ref, ref_rows), (res, rows) = _solve(raw, host=True), _solve(raw, host=False)
    assert ref.rejections and ref.rejections == res.rejections  # rejections were made
    assert (ref.steps, ref.iterations, ref.cutbacks) == (res.steps, res.iterations,
                                                         res.cutbacks)
    assert [r.step for r in rows] == list(range(1, res.steps + 1))
    for a, b in zip(ref_rows, rows, strict=True):
        assert (a.t, a.dt, a.dt_next, a.iterations, a.cutbacks) == \
            (b.t, b.dt, b.dt_next, b.iterations, b.cutbacks)
        assert a.diagnostics == b.diagnostics
        for x, y in ((a.state.u, b.state.u), (a.state.v, b.state.v),
                     (a.state.a, b.state.a), (a.state.f_pot, b.state.f_pot)):
            assert np.array_equal(np.asarray(x), y)
    assert max(r.diagnostics["E_contact"] for r in rows) > 0.0  # contact acted


def test_the_host_loop_redoes_no_native_attempt_for_a_capacity():
    """The native engine's candidate lists have no fixed length, so the host loop takes
    its counts as they are: with a capacity of 1 candidate (the JAX engine would redo
    each attempt with more candidates than that) it makes the compiled loop's steps
    and Newton iterations, none redone and counted twice."""
    raw = _drop("cg", 0.8)
    (ref, ref_rows), (res, rows) = (_solve(raw, host=True, capacity=1),
                                    _solve(raw, host=False, capacity=1))
    assert (ref.steps, ref.iterations, ref.cutbacks) == (res.steps, res.iterations,
                                                         res.cutbacks)
    assert [r.iterations_total for r in ref_rows] == [r.iterations_total for r in rows]


class LoopLater(HostLooped):
    """A native engine whose compiled loop is "being compiled" (``loop_compiling``) for
    its first ``attempts`` attempts, as by the helper of a cold run: the driver makes
    those with its host loop, then the compiled loop goes on from there."""

    runs_loop = True

    def __init__(self, engine, attempts: int):
        super().__init__(engine)
        self.attempts, self.looks = attempts, 0

    def loop_compiling(self, state, done: float = 0.0) -> bool:
        assert 0.0 <= done < 1.0
        self.looks += 1
        return self.looks <= self.attempts


def test_steps_made_while_the_loop_compiles_are_the_loops_own():
    """A run whose first 300 attempts come from the host loop (dynamics/driver.py,
    ``_compiled_loop``: a cold run while its helper compiles the loop) and the rest from
    the compiled loop, through the first impact: the same steps, states and rejections
    as the compiled loop's alone, bit for bit."""
    raw = _drop("cg", 0.8)
    ref, ref_rows = _solve(raw, host=False)
    start = dynamic_start(prepare(parse_case(raw)))
    engine = LoopLater(start.engine, 300)
    rows = []
    res = solve_dynamic(engine, start.state, 0.8, start.prepared.length, start.control,
                        on_step=rows.append)
    assert res.status == "completed", res.message
    assert engine.looks == 301 and res.steps > 300  # both loops made steps
    assert (ref.steps, ref.iterations, ref.cutbacks, ref.rejections) == \
        (res.steps, res.iterations, res.cutbacks, res.rejections)
    for a, b in zip(ref_rows, rows, strict=True):
        assert (a.t, a.dt, a.dt_next, a.iterations, a.diagnostics) == \
            (b.t, b.dt, b.dt_next, b.iterations, b.diagnostics)
        assert np.array_equal(a.state.u, b.state.u) and np.array_equal(a.state.v, b.state.v)


def test_interrupt_inside_the_compiled_loop_keeps_every_accepted_step():
    """Ctrl-C (SIGINT's KeyboardInterrupt, raised from another thread while the compiled
    loop runs) after some steps: every step accepted until then reaches on_step, in
    order, each the same as in the uninterrupted run."""
    raw = _drop("cg", 0.8)
    full = _solve(raw, host=False)[1]
    raw["analysis"]["t_end"] = 3.0  # far longer than the interrupted run lasts
    start = dynamic_start(prepare(parse_case(raw)))
    rows = []
    timer = threading.Timer(0.3, _thread.interrupt_main)
    # Python's own SIGINT handler, whatever the suite inherited: a process started in
    # the background by a non-interactive shell ignores SIGINT, and then interrupt_main
    # does nothing (the run completed and this test failed, run so)
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            solve_dynamic(start.engine, start.state, 3.0, start.prepared.length,
                          start.control, on_step=rows.append)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, handler)
    assert len(rows) > 0
    assert [r.step for r in rows] == list(range(1, len(rows) + 1))
    for a, b in zip(rows, full[:-1], strict=False):  # (full's last step lands on 0.8 s)
        assert a.t == b.t and np.array_equal(a.state.u, b.state.u)


def test_interrupt_inside_the_host_loop_keeps_every_accepted_step():
    """Ctrl-C in the host loop (the JAX engine's, and the native engine's while a helper
    compiles its loop), raised from another thread early and after some steps: every
    step accepted until then reaches on_step, in order, each the same as in the
    uninterrupted run; the loop hands them over in batches (driver.EMIT_SECONDS), none
    lost to the interrupt."""
    raw = _drop("cg", 0.8)
    full = _solve(raw, host=False)[1]
    raw["analysis"]["t_end"] = 3.0
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        for delay in (0.02, 0.3):
            start = dynamic_start(prepare(parse_case(raw)))
            rows, batches = [], []
            timer = threading.Timer(delay, _thread.interrupt_main)
            try:
                with pytest.raises(KeyboardInterrupt):
                    timer.start()
                    solve_dynamic(HostLooped(start.engine), start.state, 3.0,
                                  start.prepared.length, start.control, on_step=rows.append,
                                  on_steps=lambda b, seen=batches: seen.append(len(b)))
            finally:
                timer.cancel()
            assert [r.step for r in rows] == list(range(1, len(rows) + 1))
            assert sum(batches) == len(rows)
            for a, b in zip(rows, full[:-1], strict=False):
                assert a.t == b.t and np.array_equal(a.state.u, b.state.u)
        assert len(rows) > 0 and max(batches) > 1
    finally:
        signal.signal(signal.SIGINT, handler)


def test_a_steps_strain_energy_is_that_of_its_state():
    """The compiled attempt takes E_strain from its last Newton evaluation, which is at the
    step's solution: it is the strain energy of the accepted state (assembly/
    native_model.energies), bit for bit, through the first impact and in free flight."""
    from beamcontact.assembly.native_model import energies

    raw = _drop("cg", 0.8)
    start = dynamic_start(prepare(parse_case(raw)))
    rows = []
    solve_dynamic(start.engine, start.state, 0.8, start.prepared.length, start.control,
                  on_step=rows.append)
    nm = start.engine.nm
    assert len(rows) > 100 and max(r.diagnostics["E_strain"] for r in rows) > 0.0
    for r in rows:
        s = r.state
        assert r.diagnostics["E_strain"] == energies(nm, s.u, 1.0, s.load_state.theta,
                                                     s.load_state.tangent)[0]


def test_the_residual_alone_is_the_one_of_the_evaluation_with_the_tangent():
    """An iterate expected to have converged is checked on its residual alone
    (native_step._residual); the tangent follows only if it has not, so the two
    evaluations must give the same residual, f_pot, norm and energies, bit for bit: at
    the states of the bundled CG drop through its first impact, under the contact set
    there and without contact."""
    from beamcontact.assembly.native_model import new_blocks
    from beamcontact.dynamics import native_step as ns

    raw = _drop("cg", 0.8)
    start = dynamic_start(prepare(parse_case(raw)))
    rows = []
    solve_dynamic(start.engine, start.state, 0.8, start.prepared.length, start.control,
                  on_step=rows.append)
    engine = start.engine
    nm, sysm = engine.nm, engine.system
    ar, lay = sysm.arrays, sysm.layout
    n = nm.n_dof
    alpha = engine.alpha
    beta, gamma = 0.25 * (1.0 - alpha) ** 2, 0.5 - alpha
    in_contact = [i for i in range(1, len(rows)) if rows[i].diagnostics["E_contact"] > 0.0]
    assert len(in_contact) > 10
    checked = 0
    for i in in_contact[::max(len(in_contact) // 8, 1)] + [1]:
        before, now = rows[i - 1].state, rows[i].state
        h = rows[i].dt
        coeffs = np.array([1.0 / (beta * h * h), h, (1.0 - 2.0 * beta) / (2.0 * beta), gamma])
        x = nm.x_ref + now.u.reshape(-1, 2)
        for frozen in (engine._contact.frozen_at(x), ns.NO_CONTACT):
            common = (nm, frozen, now.u, before.u, before.v, before.a, coeffs, alpha,
                      before.f_pot, before.load_state.theta, before.load_state.tangent)
            r, f_pot, r_layout = np.empty(n), np.empty(n), np.empty(n)
            full = ns._residual_tangent(*common, sysm.position, sysm.block_positions,
                                        sysm.free, ar.band, ar.B, ar.C, ar.D, lay.kl, lay.ku,
                                        r, f_pot, r_layout, new_blocks(nm))
            r_alone, f_alone = np.empty(n), np.empty(n)
            alone = ns._residual(*common, r_alone, f_alone, new_blocks(nm))
            assert alone == full
            assert np.array_equal(r_alone, r) and np.array_equal(f_alone, f_pot)
            checked += frozen[2].shape[0] > 0
    assert checked > 5  # contact blocks took part


def test_an_interrupt_reported_by_numba_as_a_system_error_is_an_interrupt():
    """A signal's KeyboardInterrupt raised in Python code that compiled code calls (as
    Numba's unpickling of constants) comes out of the dispatcher as SystemError("...
    returned a result with an exception set"), one per level, the interrupt at the end
    of the context chain: stop_signals.as_interrupt finds it, and nothing else."""
    from beamcontact.stop_signals import Terminated, as_interrupt

    def chained(inner: BaseException, levels: int) -> BaseException:
        exc = inner
        for _ in range(levels):
            outer = SystemError("returned a result with an exception set")
            outer.__context__ = exc
            exc = outer
        return exc

    ctrl_c, term = KeyboardInterrupt(), Terminated(signal.SIGTERM)
    assert as_interrupt(ctrl_c) is ctrl_c
    assert as_interrupt(chained(ctrl_c, 1)) is ctrl_c
    assert as_interrupt(chained(term, 2)) is term
    assert as_interrupt(chained(ValueError(), 2)) is None
    assert as_interrupt(SystemError()) is None and as_interrupt(OSError()) is None
