"""The start of a run: everything a solver takes, made from a validated case in one place
(the runner, the tests and the benchmarks all start here).

:func:`prepare` discretises the case and builds the model, the contact problem and the
Newton settings; :func:`static_engine` is the engine of load stepping
(:class:`~beamcontact.statics.native_step.NativeStatics` or
:class:`~beamcontact.statics.step.JaxStatics`); :func:`dynamic_start` adds the engine of
the time loop (:class:`~beamcontact.dynamics.native_step.NativeEngine` or
:class:`~beamcontact.dynamics.step.JaxEngine`), the step controller's settings and the
consistent state at t = 0 (paper Sec. 4: M a0 = f(u0)). :func:`choose_engine` says
which engine runs a case and why.
"""

from dataclasses import dataclass

from beamcontact._jax import gpu_plugin_installed
from beamcontact.contact.broadphase import ALL_PAIRS_LIMIT
from beamcontact.contact.laws import CoarseGrained, Penalty
from beamcontact.contact.problem import ContactProblem
from beamcontact.io.case import Case, CaseError
from beamcontact.setup.contact import build_contact
from beamcontact.setup.model import Discretization, build_model, discretize
from beamcontact.solvers.newton import NewtonOptions


@dataclass(frozen=True, eq=False)
class Prepared:
    """A case made ready for a solver: its discretisation, discrete model (an
    ``assembly.model.Model``), contact problem (None: no contact) and Newton settings."""

    case: Case
    disc: Discretization
    model: object
    contact: ContactProblem | None
    options: NewtonOptions

    @property
    def length(self) -> float:
        """The length scale L of the tolerances (the longest beam)."""
        return self.disc.length_scale


@dataclass(frozen=True, eq=False)
class DynamicStart:
    """A dynamic run at t = 0: the prepared case, the engine of its time loop, the step
    controller's settings and the initial state."""

    prepared: Prepared
    engine: object
    control: object
    state: object


def prepare(case: Case) -> Prepared:
    """Discretise ``case`` and build what every solver takes (a mesh the case cannot have
    is a CaseError naming ``beams``)."""
    try:
        disc = discretize(case)
    except ValueError as exc:
        raise CaseError(f"beams: {exc}") from None
    model, disc = build_model(case, disc)
    so = case.solver
    # the error left in a Newton iterate is bounded relative to a time step's local error
    etol = so.newton_error_fraction * so.error_tol if case.analysis.kind == "dynamic" else 0.0
    return Prepared(case, disc, model, build_contact(case, disc),
                    NewtonOptions(so.max_iterations, so.rtol, so.utol, etol))


# the dense tangent's bytes per entry in the JAX engine: the matrix, its LU and the
# buffers XLA keeps of them
DENSE_BYTES_PER_ENTRY = 3 * 8


def physical_memory() -> int | None:
    """This machine's memory in bytes (None where the system does not say)."""
    import os

    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, OSError, ValueError):
        return None


def check_dense_memory(prepared: Prepared) -> None:
    """Refuse, before anything is allocated, a dense tangent (``solver.linear_solver``
    "dense", or "auto" on an accelerator) larger than this machine's memory, saying what
    to change."""
    model = prepared.model
    memory = physical_memory()
    need = DENSE_BYTES_PER_ENTRY * model.n_dof**2
    if model.sparse or memory is None or need <= memory:
        return
    raise CaseError(
        f"solver.linear_solver: the dense tangent of {model.n_dof} dofs needs about "
        f"{need / 2**30:.1f} GB, more than this machine's {memory / 2**30:.1f} GB; use "
        f"linear_solver = \"sparse\" (or \"auto\" on a CPU) or fewer elements")


def static_engine(prepared: Prepared):
    """The engine of load stepping (:func:`choose_engine`):
    :class:`~beamcontact.statics.native_step.NativeStatics` or
    :class:`~beamcontact.statics.step.JaxStatics`."""
    contact = prepared.contact
    if choose_engine(prepared.case, None if contact is None else contact.law)[0] == "native":
        from beamcontact.statics.native_step import NativeStatics

        return NativeStatics(prepared.model, contact, prepared.options, prepared.length)
    from beamcontact.statics.step import JaxStatics

    check_dense_memory(prepared)
    return JaxStatics(prepared.model, contact, prepared.options, prepared.length)


def compile_loop_early(case: Case) -> bool:
    """Before the model of a dynamic case is built: if the native engine will run it and
    the kernel cache lacks the compiled time loop, start the helper that compiles it
    (beamcontact/_warmup.py), so that it works beside the whole start of the run
    (runner.py calls it for every dynamic run; :func:`dynamic_start` alone compiles the
    loop at its first call). Returns whether the run should make its start, from its
    model to its first energies, with the kernels as Python
    (``_warmup.start_as_python``: a small model while the cache lacks the loop). A case
    that the native engine cannot run with its case file's laws starts nothing (its
    error comes with the start of the run). A run that stops on an error in its model
    leaves the helper to finish filling the cache (under a minute), which the next run
    then finds."""
    try:
        native = choose_engine(case)[0] == "native"
    except CaseError:
        return False
    if not native:
        return False
    from beamcontact import _warmup

    _warmup.start_if_cold()
    return _warmup.start_as_python(sum(beam.elements for beam in case.beams))


def dynamic_start(prepared: Prepared, initial: bool = True) -> DynamicStart:
    """The engine (:func:`choose_engine`), the step control and the state at t = 0 of a
    dynamic case: zero displacements, the beams' initial velocities, consistent
    accelerations under the contact set of the reference configuration (``initial``
    False: no state, for a run that continues a saved one). The native engine makes its
    own state (no JAX program runs)."""
    from beamcontact.setup.model import uniform_velocities

    case, model, contact = prepared.case, prepared.model, prepared.contact
    an = case.analysis
    v0 = uniform_velocities(prepared.disc, [b.initial_velocity for b in case.beams])
    name, _ = choose_engine(case, None if contact is None else contact.law)
    if name == "native":
        from beamcontact.dynamics.native_step import NativeEngine

        engine = NativeEngine(model, an.alpha, prepared.options, prepared.length, an.dt,
                              contact)
        state = engine.initial_state(v0) if initial else None
        return DynamicStart(prepared, engine, step_control(case), state)
    from beamcontact._jax import jnp, on_device
    from beamcontact.assembly.model import initial_load_state
    from beamcontact.contact.problem import freeze
    from beamcontact.dynamics.hht import initial_state
    from beamcontact.dynamics.step import JaxEngine

    check_dense_memory(prepared)
    engine = JaxEngine(model, contact, an.alpha, prepared.options, prepared.length, an.dt)
    state = None
    if initial:  # from the engine's device copies of the model and the contact points
        model, contact = engine.model, engine.contact
        cs0 = None if contact is None else contact.grown_set(
            model.x_ref, 0.0, contact.first_capacity(case.contact.capacity))[0]
        state = initial_state(jnp.zeros(model.n_dof), jnp.asarray(v0), model,
                              on_device(initial_load_state(model)), freeze(contact, cs0))
    return DynamicStart(prepared, engine, step_control(case), state)


def step_control(case: Case):
    """The step controller's settings (:class:`~beamcontact.dynamics.control.StepControl`)
    of a validated dynamic case."""
    from beamcontact.dynamics.control import StepControl

    an, so = case.analysis, case.solver
    return StepControl(an.dt, an.smallest_step, so.error_tol, so.energy_tol, so.max_cutbacks)


def native_unsupported(case: Case, law=None) -> str | None:
    """What of ``case`` (with its contact law object ``law``, when built) has no native
    kernel yet (None: the native engine runs it all)."""
    if case.contact.model == "none":
        return None
    if law is not None and type(law) not in _NATIVE_LAWS:
        return f"the contact law {type(law).__name__} (no native kernel)"
    if case.contact.self_contact:
        return "self-contact (contact.self_contact = true)"
    if case.obstacles:
        return "rigid obstacles ([[obstacles]])"
    elements = sum(b.elements for b in case.beams)
    if elements > ALL_PAIRS_LIMIT:
        return (f"contact between more than {ALL_PAIRS_LIMIT} elements ({elements}; the grid "
                f"broad phase)")
    return None


# the contact laws with native kernels (contact/laws/*_native.py); a law of another class,
# a user's own, runs on the JAX engine
_NATIVE_LAWS = (CoarseGrained, Penalty)


def choose_engine(case: Case, law=None) -> tuple[str, str]:
    """The engine that runs ``case`` (with its contact law object ``law``, when built)
    and why (``solver.engine``; docs/architecture.md, "Engines"); "native" asked for a
    case it cannot run is a CaseError."""
    asked = case.solver.engine
    lacking = native_unsupported(case, law)
    if asked == "jax":
        return "jax", "asked for (solver.engine = \"jax\")"
    if asked == "native":
        if lacking is not None:
            raise CaseError(f"solver.engine: the native engine cannot run {lacking} yet; "
                            f"use \"auto\" or \"jax\"")
        return "native", "asked for (solver.engine = \"native\")"
    if lacking is not None:
        return "jax", f"the native engine cannot run {lacking} yet"
    if gpu_plugin_installed():
        return "jax", "a GPU plugin of JAX is installed"
    return "native", "every term of the case has a native kernel"

