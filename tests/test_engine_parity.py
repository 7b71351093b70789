"""The native engine against the JAX engine: the same physics (docs/architecture.md,
"Engines").

Both engines run the same case through the same driver and controller; only the order of
floating-point operations differs (hand-written kernels and a bordered banded LU against
AD and JAX's LU). So the step sequence is the same and the trajectories agree to
round-off, amplified over the run by at most the conditioning of the dynamics: asserted
here to 1e-9 of the beam length, far above round-off (1e-15) and far below any
difference in physics (a wrong term changes the trajectory at the 1e-4 level or more).
"""

import tomllib
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam

from beamcontact._jax import gpu_plugin_installed
from beamcontact.api import load_case
from beamcontact.assembly.inertia import inertia_force_and_mass
from beamcontact.dynamics.driver import solve_dynamic
from beamcontact.io.case import parse_case
from beamcontact.io.results import read_history
from beamcontact.runner import run_case
from beamcontact.setup.start import choose_engine, dynamic_start, prepare

REPO = Path(__file__).resolve().parents[1]


def _cantilever_swing() -> dict:
    """A clamped cantilever released under gravity with a tip force and a tip moment
    (their potentials, the tracked tip rotation), alpha = -0.1."""
    b = beam("c", line=([0.0, 0.0], [1.0, 0.0]), degree=4, elements=6, radius=0.02,
             E=2e8, density=1000.0, supports=[{"at": "start", "type": "clamped"}])
    return {"analysis": {"kind": "dynamic", "t_end": 0.12, "dt": 2e-3, "alpha": -0.1,
                         "gravity": [0.0, -9.81]},
            "beams": [b],
            "loads": [{"beam": "c", "at": "end", "force": [0.0, -3.0], "moment": 1.5}],
            "output": {"points": [{"name": "tip", "beam": "c", "at": 1.0}]}}


def _free_fall_without_contact() -> dict:
    """The bundled benchmark's two beams with contact off: the lower pinned beam at rest,
    the upper one falling freely (two beams: the bordered system)."""
    case = load_case(REPO / "examples" / "free_fall" / "case_cg.toml")
    raw = case.model_dump(mode="json", exclude_none=True)
    raw.pop("contact")
    raw["analysis"]["t_end"] = 0.3
    return raw


def _on(raw: dict, engine: str) -> dict:
    """``raw`` with ``solver.engine`` set."""
    return {**raw, "solver": {**raw.get("solver", {}), "engine": engine}}


def _touching_drop() -> dict:
    """The bundled coarse-grained drop with the upper beam lowered into the interaction
    range (surface gap 1.5 mm) and thrown sideways and down: contact forces act at t = 0
    and accelerate the lower beam."""
    case = load_case(REPO / "examples" / "free_fall" / "case_cg.toml")
    raw = case.model_dump(mode="json", exclude_none=True)
    upper = raw["beams"][1]
    upper["line"] = {"start": [3.5, 0.2015], "end": [6.5, 0.2015]}
    upper["initial_velocity"] = [0.3, -1.0]
    return raw


def _both(raw: dict) -> dict:
    """Each engine from its own initial state through the same driver."""
    runs = {}
    for name in ("jax", "native"):
        start = dynamic_start(prepare(parse_case(_on(raw, name))))
        assert start.engine.name == name
        prepared, an = start.prepared, start.prepared.case.analysis
        rows = []
        res = solve_dynamic(start.engine, start.state, an.t_end, prepared.length,
                            start.control, on_step=lambda s, rows=rows: rows.append(
                                (s.t, np.array(s.state.u), s.diagnostics)))
        assert res.status == "completed", res.message
        runs[name] = rows
    return runs, prepared.length


def _touching_drop_free_ends() -> dict:
    """:func:`_touching_drop` with the upper beam's outliers removed (beam/free_ends.py):
    its tied end points' velocity and acceleration at t = 0."""
    raw = _touching_drop()
    raw["beams"][1]["remove_outliers"] = True
    return raw


@pytest.mark.parametrize("make", [_cantilever_swing, _touching_drop, _touching_drop_free_ends])
def test_initial_state_is_the_same_on_both_engines(make):
    """The consistent start (M a0 = -f(u0), Sec. 4) of each engine: the same velocity
    and load state, the potential force (contact included) to round-off, and the native
    acceleration solves the JAX engine's equation F_inertia(u0, v0, a0) = -f_pot(u0) on
    the free dofs to round-off (a backward error: the rotational inertia makes the mass
    matrix ill-conditioned, so the accelerations themselves differ by more); the
    diagnostics of the first row agree too."""
    raw = make()
    starts = {name: dynamic_start(prepare(parse_case(_on(raw, name))))
              for name in ("jax", "native")}
    j, n = starts["jax"].state, starts["native"].state
    model = starts["jax"].prepared.model
    free = np.asarray(model.free)
    # the velocity as given, but for the tied points of free ends (beam/free_ends.py), a
    # sum whose order of operations XLA chooses: to round-off
    tied = np.asarray(model.tied)
    given = np.ones(free.shape, bool)
    given[tied] = False
    assert np.all(n.u == 0.0) and np.array_equal(n.v[given], np.asarray(j.v)[given])
    np.testing.assert_allclose(n.v, np.asarray(j.v), rtol=0,
                               atol=8 * np.finfo(float).eps * np.max(np.abs(n.v)))
    np.testing.assert_allclose(n.load_state.tangent, np.asarray(j.load_state.tangent),
                               rtol=1e-14, atol=0)
    assert np.all(n.load_state.theta == 0.0) and float(n.t) == 0.0
    # JAX's AD of the strain energy at the reference (zero strain) leaves round-off where
    # the native kernel gives zero: the strain eps_11 = (g - g_ref) / 2 of a difference of
    # O(1) numbers is off by about eps, and each element adds EA eps_11 dR ds, at most
    # about p EA eps, to each of its p + 1 control points
    f_pot = np.asarray(j.f_pot)
    scale = np.max(np.abs(f_pot))
    p = max(b["degree"] for b in raw["beams"])
    ea = max(b["material"]["E"] * np.pi * b["section"]["radius"] ** 2 for b in raw["beams"])
    tol = max(1e-11 * scale, (p + 1) * p * np.finfo(float).eps * ea)
    np.testing.assert_allclose(n.f_pot, f_pot, rtol=0, atol=tol)
    # (the native a solves the native f_pot's equation: the same round-off again)
    f_inertia = np.asarray(inertia_force_and_mass(j.u, j.v, jnp.asarray(n.a), model)[0])
    assert np.max(np.abs((f_inertia + f_pot) * free)) <= tol
    if make is not _cantilever_swing:
        assert np.max(np.abs(n.a[np.asarray(prepare(parse_case(raw)).model.free) > 0])) \
            > 0.0
    diag = {name: s.engine.energies(s.state, s.prepared.contact.first_capacity(64)
                                    if s.prepared.contact else None)
            for name, s in starts.items()}
    assert diag["native"].keys() == diag["jax"].keys()
    for key, want in diag["jax"].items():
        assert diag["native"][key] == pytest.approx(want, rel=1e-12, abs=1e-12,
                                                    nan_ok=True), key
    if make is not _cantilever_swing:
        assert diag["native"]["E_contact"] > 0.0 and 0.0 < diag["native"]["min_gap"] < 0.1


@pytest.mark.parametrize("make", [_cantilever_swing, _free_fall_without_contact])
def test_native_engine_follows_the_jax_engine(make):
    runs, length = _both(make())
    jax_rows, native_rows = runs["jax"], runs["native"]
    assert len(jax_rows) == len(native_rows)
    t_j = np.array([r[0] for r in jax_rows])
    t_n = np.array([r[0] for r in native_rows])
    np.testing.assert_allclose(t_n, t_j, rtol=0, atol=1e-9 * t_j[-1])
    u_j = np.array([r[1] for r in jax_rows])
    u_n = np.array([r[1] for r in native_rows])
    np.testing.assert_allclose(u_n, u_j, rtol=0, atol=1e-9 * length)
    keys = ("E_kin", "E_strain", "E_gravity", "E_ext", "E_total", "E_dissipated")
    energies = {name: {k: np.array([r[2][k] for r in rows]) for k in keys}
                for name, rows in runs.items()}
    # relative to the energy scale of the run: a term that stays at round-off (the strain
    # of a falling rigid beam, 1e-18 J) has no digits of its own to compare
    scale = max(np.max(np.abs(e)) for e in energies["jax"].values())
    for k in keys:
        assert np.max(np.abs(energies["jax"][k] - energies["native"][k])) <= 1e-9 * scale, k
    assert np.max(np.abs(u_j)) > 0.02 * length  # the run moved: the comparison means something


def test_auto_chooses_native_where_every_term_has_a_kernel():
    """On a CPU, ``auto`` runs natively every case with a native kernel for all its terms;
    with a GPU plugin of JAX installed, the JAX engine runs everything (and says why)."""
    gpu = gpu_plugin_installed()
    for case in ("pinned_beam_vibration/case.toml", "free_fall/case_cg.toml",
                 "cantilever_end_moment/case.toml"):
        name, why = choose_engine(load_case(REPO / "examples" / case))
        assert (name, "GPU" in why) == (("jax", True) if gpu else ("native", False)), case
    name, why = choose_engine(load_case(REPO / "examples" / "fibre_pile" / "case_cg.toml"))
    assert name == "jax" and "obstacles" in why


def _history(raw: dict, engine: str, out) -> dict:
    raw = {**raw, "solver": {**raw.get("solver", {}), "engine": engine}}
    summary = run_case(parse_case(raw), "", out)
    assert summary["status"] == "completed", summary["message"]
    assert summary["solver"]["engine_used"] == engine
    return read_history(out / "history.csv")


@pytest.mark.parametrize("variant", ["cg", "ipip-zones", "ipip-points",
                                     "ipip-points+free-ends"])
def test_bundled_drop_is_the_same_on_both_engines(tmp_path, variant):
    """The paper's drop (examples/free_fall) to 0.9 s, through the first impact (0.75 s),
    on both engines: point A to 1e-8 m before the impact and 1e-5 m through it, and the
    energy account (E_total, E_dissipated, E_set_change) to 1e-6 of the initial energy.
    "+free-ends": the falling beam's outliers removed (beam/free_ends.py), so that the
    contact points of its end elements work in the folded basis on both engines."""
    variant, _, extra = variant.partition("+")
    model, _, pairing = variant.partition("-")
    raw = tomllib.loads((REPO / "examples" / "free_fall" / f"case_{model}.toml").read_text())
    raw["analysis"]["t_end"] = 0.9
    if pairing:
        raw["contact"]["pairing"] = pairing
    if extra == "free-ends":
        raw["beams"][1]["remove_outliers"] = True
    ref = _history(raw, "jax", tmp_path / "jax")
    nat = _history(raw, "native", tmp_path / "native")
    t = ref["t"]
    impact = np.argmax(ref["E_contact"] > 1e-6 * ref["E_total"][0])
    assert 0.7 < t[impact] < 0.8 and ref["min_gap"].min() < 0.01  # it went through
    a_native = np.interp(t, nat["t"], nat["A_uy"])
    assert np.max(np.abs(a_native - ref["A_uy"])[:impact]) < 1e-8
    assert np.max(np.abs(a_native - ref["A_uy"])) < 1e-5
    e0 = abs(ref["E_total"][0])
    for key in ("E_total", "E_dissipated", "E_set_change"):
        assert abs(nat[key][-1] - ref[key][-1]) < 1e-6 * e0, key
