"""The start of a run: everything a solver takes, made from a validated case in one place
(the runner, the tests and the benchmarks all start here).

:func:`prepare` discretises the case and builds the model, the contact problem and the
Newton settings; :func:`static_engine` is the engine of load stepping
(:class:`~beamcontact.statics.step.JaxStatics`); :func:`dynamic_start` adds the engine of
the time loop (:class:`~beamcontact.dynamics.step.JaxEngine`), the step controller's
settings and the consistent state at t = 0 (paper Sec. 4: M a0 = f(u0)).
"""

from dataclasses import dataclass

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
    controller's settings and the initial state (with its contact set, None without
    contact)."""

    prepared: Prepared
    engine: object
    control: object
    state: object
    contact_set: object


def prepare(case: Case) -> Prepared:
    """Discretise ``case`` and build what every solver takes (a mesh the case cannot have
    is a CaseError naming ``beams``)."""
    try:
        disc = discretize(case)
    except ValueError as exc:
        raise CaseError(f"beams: {exc}") from None
    model, disc = build_model(case, disc)
    so = case.solver
    return Prepared(case, disc, model, build_contact(case, disc),
                    NewtonOptions(so.max_iterations, so.rtol, so.utol))


def static_engine(prepared: Prepared):
    """The engine of load stepping (:class:`~beamcontact.statics.step.JaxStatics`)."""
    from beamcontact.statics.step import JaxStatics

    return JaxStatics(prepared.model, prepared.contact, prepared.options, prepared.length)


def dynamic_start(prepared: Prepared, initial: bool = True) -> DynamicStart:
    """The engine, the step control and the state at t = 0 of a dynamic case: zero
    displacements, the beams' initial velocities, consistent accelerations under the
    contact set of the reference configuration (``initial`` False: no state, for a run
    that continues a saved one)."""
    import jax.numpy as jnp

    from beamcontact.assembly.model import initial_load_state
    from beamcontact.contact.problem import freeze
    from beamcontact.dynamics.hht import initial_state
    from beamcontact.dynamics.step import JaxEngine
    from beamcontact.setup.model import uniform_velocities

    case, model, contact = prepared.case, prepared.model, prepared.contact
    an = case.analysis
    state = cs0 = None
    if initial:
        u0 = jnp.zeros(model.n_dof)
        v0 = jnp.asarray(uniform_velocities(prepared.disc,
                                            [b.initial_velocity for b in case.beams]))
        cs0 = None if contact is None else contact.grown_set(
            model.x_ref, 0.0, contact.first_capacity(case.contact.capacity))[0]
        state = initial_state(u0, v0, model, initial_load_state(model), freeze(contact, cs0))
    engine = JaxEngine(model, contact, an.alpha, prepared.options, prepared.length, an.dt)
    return DynamicStart(prepared, engine, step_control(case), state, cs0)


def step_control(case: Case):
    """The step controller's settings (:class:`~beamcontact.dynamics.control.StepControl`)
    of a validated dynamic case."""
    from beamcontact.dynamics.control import StepControl

    an, so = case.analysis, case.solver
    return StepControl(an.dt, an.smallest_step, so.error_tol, so.energy_tol, so.max_cutbacks)
