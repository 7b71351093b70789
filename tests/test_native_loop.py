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


def _solve(raw: dict, host: bool):
    start = dynamic_start(prepare(parse_case(raw)))
    engine = HostLooped(start.engine) if host else start.engine
    assert engine.runs_loop is not host
    rows = []
    res = solve_dynamic(engine, start.state, raw["analysis"]["t_end"], start.prepared.length,
                        start.control, on_step=rows.append)
    assert res.status == "completed", res.message
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
