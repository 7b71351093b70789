"""The sparse tangent (solvers/linear.py) against dense linear algebra.

Asserted: the host solve (banded LAPACK LU and SuperLU) solves triplet matrices with
repeated entries as a dense LU does, to round-off; a singular matrix gives NaN (so Newton
fails and the step is cut) instead of an exception; the triplet operations are the dense
ones; and a whole run through an impact, and a static elastica, give the dense results
with ``solver.linear_solver = "sparse"``.
"""

import numpy as np
import pytest
from _builders import beam, bending_stiffness, static_case
from test_impacts import _free_collision

import beamcontact

beamcontact.enable_x64()

import jax.numpy as jnp  # noqa: E402

from beamcontact.io.case import CaseError, parse_case  # noqa: E402
from beamcontact.io.results import read_history  # noqa: E402
from beamcontact.runner import run_case  # noqa: E402
from beamcontact.solvers import linear  # noqa: E402


def _blocks(n, chain: bool, seed=0, m=10):
    """Random 10 x 10 element blocks (dofs, blocks): consecutive dofs along a chain (a
    banded matrix, as one beam gives) or random dof sets (a general sparse one); blocks
    overlap, so entries repeat. Diagonally dominant, not symmetric."""
    rng = np.random.default_rng(seed)
    if chain:
        starts = np.arange(0, n - m + 1, 2)
        dofs = starts[:, None] + np.arange(m)
    else:
        dofs = np.array([rng.choice(n, m, replace=False) for _ in range(n // 2)])
    blocks = rng.standard_normal((len(dofs), m, m)) + 2.0 * m * np.eye(m)
    return dofs, blocks


def _dense(n, dofs, blocks):
    A = np.zeros((n, n))
    np.add.at(A, (dofs[:, :, None], dofs[:, None, :]), blocks)
    return A


@pytest.mark.parametrize("chain", [True, False])
def test_host_solve_equals_dense_lu(chain):
    n = 400
    dofs, blocks = _blocks(n, chain)
    K = linear.scatter(linear.zeros(n, True), jnp.asarray(dofs), jnp.asarray(blocks))
    rhs = np.random.default_rng(1).standard_normal(n)
    A = _dense(n, dofs, blocks)
    x_ref = np.linalg.solve(A, rhs)
    x = np.asarray(linear.solve(K, jnp.asarray(rhs)))
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-13 * np.abs(x_ref).max())
    # the band of a chain is narrow (half bandwidth 9 of 400): the banded LU solves it;
    # random dof sets span the whole matrix: SuperLU
    rows, cols = np.asarray(K.rows), np.asarray(K.cols)
    assert (np.max(np.abs(rows - cols)) == 9) == chain
    np.testing.assert_allclose(
        linear._banded_solve(rows, cols, np.asarray(K.vals), rhs.copy(), 9, 9) if chain
        else linear.compressed(rows, cols, np.asarray(K.vals), n).toarray() @ x,
        x_ref if chain else rhs, rtol=0, atol=1e-12 * np.abs(rhs).max())


@pytest.mark.parametrize("chain", [True, False])
def test_singular_matrix_gives_nan_not_an_exception(chain):
    n = 200
    dofs, blocks = _blocks(n, chain)
    K = linear.scatter(linear.zeros(n, True), jnp.asarray(dofs), jnp.asarray(blocks))
    d = int(dofs[len(dofs) // 2, 4])  # that dof's row and column emptied
    keep = (K.rows != d) & (K.cols != d)
    K = linear.SparseTangent(K.rows, K.cols, K.vals * keep, n)
    x = np.asarray(linear.solve(K, jnp.ones(n)))
    assert np.all(np.isnan(x))


def test_triplet_operations_are_the_dense_ones():
    n = 60
    dofs, blocks = _blocks(n, False, seed=3)
    other_dofs, other = _blocks(n, True, seed=4)
    free = np.ones(n)
    free[[0, 1, 17, 59]] = 0.0

    def build(sparse):
        a = linear.scatter(linear.zeros(n, sparse), jnp.asarray(dofs), jnp.asarray(blocks))
        b = linear.scatter(linear.zeros(n, sparse), jnp.asarray(other_dofs),
                           jnp.asarray(other))
        return linear.apply_supports(linear.add(a, b, 1.3), jnp.asarray(free))

    dense, sparse = build(False), build(True)
    assert isinstance(sparse, linear.SparseTangent)
    np.testing.assert_allclose(linear.to_dense(sparse), np.asarray(dense), rtol=1e-15,
                               atol=1e-15 * np.abs(np.asarray(dense)).max())
    # supported rows and columns are the identity's
    np.testing.assert_array_equal(linear.to_dense(sparse)[17], np.eye(n)[17])


def test_auto_choice_and_case_key():
    assert not linear.use_sparse("auto", linear.AUTO_SPARSE_DOFS - 1, "cpu")
    assert linear.use_sparse("auto", linear.AUTO_SPARSE_DOFS, "cpu")
    assert not linear.use_sparse("auto", 10**5, "gpu")  # accelerators keep the dense LU
    assert linear.use_sparse("sparse", 4, "gpu") and not linear.use_sparse("dense", 10**5)
    raw = _free_collision("cg")
    raw["solver"] = {"linear_solver": "cholesky"}
    with pytest.raises(CaseError, match="solver.linear_solver"):
        parse_case(raw)


@pytest.mark.parametrize("law", ["cg", "ipip-points"])
def test_impact_with_sparse_tangent_equals_dense(tmp_path, law):
    """The free collision of tests/test_impacts.py (a run through a whole impact, the
    controller choosing every step) solved both ways: the same number of steps at the
    same times, and trajectories equal to round-off."""
    runs = {}
    for kind in ("dense", "sparse"):
        raw = _free_collision(law)
        raw["analysis"]["t_end"] = 0.1
        raw["solver"] = {"linear_solver": kind, "engine": "jax"}  # the JAX engine's choice
        summary = run_case(parse_case(raw), "", tmp_path / kind)
        assert summary["status"] == "completed", summary["message"]
        assert summary["solver"]["linear_solver_used"] == kind
        runs[kind] = read_history(tmp_path / kind / "history.csv")
    d, s = runs["dense"], runs["sparse"]
    assert d["min_gap"].min() < 0.005  # through the impact
    assert len(d["t"]) == len(s["t"])
    # the controller sizes steps from an error estimate (a difference of accelerations),
    # so round-off reaches the step times: they agree to a billionth of the largest step
    np.testing.assert_allclose(s["t"], d["t"], rtol=0, atol=1e-9 * 2e-3)
    for col in ("A_x", "A_y"):
        np.testing.assert_allclose(s[col], d[col], rtol=0, atol=1e-10)
    np.testing.assert_allclose(s["E_total"], d["E_total"], rtol=1e-9)


def test_static_elastica_with_sparse_tangent():
    """A cantilever with a tip load (the elastica of tests/test_statics.py) solved with the
    sparse tangent: the tip deflection at k = P L^2 / EI = 1 is Mattiasson's 0.30172 L."""
    from beamcontact.setup.model import build_model
    from beamcontact.solvers.newton import NewtonOptions
    from beamcontact.statics.driver import solve_static
    from beamcontact.statics.step import JaxStatics

    L, a, E = 1.0, 0.002, 1.0e9
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=16, radius=a, E=E,
                             supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end",
                         "force": [0.0, -bending_stiffness(E, a) / L**2]}],
                       load_steps=2, linear_solver="sparse")
    model, disc = build_model(case)
    assert model.sparse
    res = solve_static(JaxStatics(model, None, NewtonOptions(), disc.length_scale), 2)
    assert res.status == "completed"
    tip = np.asarray(model.x_ref + res.u.reshape(-1, 2))[-1]
    assert abs(-tip[1] - 0.30172 * L) < 2e-4 * L
