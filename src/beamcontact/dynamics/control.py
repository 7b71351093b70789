"""Step control of the time integration (the host side of dynamics/driver.py's loop):
the controller's settings, the energy account, the tests an attempt must pass and the
size of the next step.

* Local error (Zienkiewicz & Xie 1991) and the step after it: the elementary controller
  h (tol / e)^(1/3) with a safety factor (Hairer, Norsett & Wanner, Solving ODEs I,
  Sec. II.4), see :func:`next_step` and :func:`retry_step`.
* The tests of an attempt, in order (:func:`verdict`): Newton converged, no contact block
  missed, penetration within bounds, the conservative advancement respected, the local
  error within ``error_tol``, the energy created within ``energy_tol`` (with its floor),
  and a set change refined while that shrinks its jump. A failed test is a
  :class:`Rejection` naming its kind, the reason and the step to retry with.
"""

from dataclasses import dataclass, field

from beamcontact.dynamics.report import StepFlags

# step controller (Hairer, Norsett & Wanner, Solving ODEs I, Sec. II.4): safety factor and
# the bounds of the change of the step after an accepted or rejected step
SAFETY, GROW_MAX, SHRINK_MIN = 0.9, 2.0, 0.2
# conservative advancement: the predictor's approach is kept below ADVANCE_FRACTION of the
# gap before the solve; a solved step whose actual approach exceeds ADVANCE_ACCEPT is redone
ADVANCE_FRACTION, ADVANCE_ACCEPT = 0.5, 0.8
# a step that needed more Newton iterations is not followed by a longer one
GROW_ITERATIONS = 3
# halvings of a step allowed to shrink a jump of the contact energy at a set change
SET_CHANGE_REFINEMENTS = 4
# relative round-off of a total energy that is a sum of terms of either sign
ENERGY_ROUNDOFF = 1e-12


@dataclass(frozen=True)
class Rejection:
    """Why an attempt is redone: ``kind`` (newton, missing_block, penetration,
    advancement, error, energy, set_change; counted in the run's summary), a message,
    and the step to retry with [s]."""

    kind: str
    reason: str
    retry: float


@dataclass(frozen=True)
class StepControl:
    """Settings of the step controller.

    Attributes:
        dt: the first and the largest step [s].
        dt_min: a step that would have to be shorter stops the run [s].
        error_tol: bound of the local error estimate of one step, a fraction of the
            length scale L (0: fixed steps, shortened only on failure).
        energy_tol: fraction of the energy scale E_kin + E_strain + |E_contact| that one
            step may create, or a set change may jump (0: no energy test).
        max_cutbacks: successive rejected attempts at one step before the run stops.
    """

    dt: float
    dt_min: float
    error_tol: float = 0.0
    energy_tol: float = 0.0
    max_cutbacks: int = 40

    @classmethod
    def fixed(cls, dt: float, max_halvings: int = 12) -> "StepControl":
        """Fixed steps of dt, halved only when Newton fails (theory tests of HHT)."""
        return cls(dt, dt * 0.5 ** (max_halvings + 0.5), 0.0, 0.0, max_halvings)


@dataclass
class Attempts:
    """The rejected attempts of a run, for load stepping and time stepping alike: in all
    (``cutbacks``), in a row at the current step (``consecutive``) and by kind. Local to
    one solve (the loops own it)."""

    cutbacks: int = 0
    consecutive: int = 0
    by_kind: dict = field(default_factory=dict)

    def reject(self, rejection: Rejection, control: StepControl) -> bool:
        """Count a rejected attempt; True when the run must stop: the step to retry is
        shorter than dt_min, or more than max_cutbacks attempts in a row failed."""
        self.cutbacks += 1
        self.consecutive += 1
        self.by_kind[rejection.kind] = self.by_kind.get(rejection.kind, 0) + 1
        return rejection.retry < control.dt_min or self.consecutive > control.max_cutbacks

    def accept(self) -> None:
        """A step was accepted: the count in a row starts again."""
        self.consecutive = 0

    def stop_reason(self, rejection: Rejection, control: StepControl) -> str:
        """Why the run stops after :meth:`reject` said so."""
        if rejection.retry < control.dt_min:
            return f"the step would have to be shorter than dt_min = {control.dt_min:.3g} s"
        return f"{self.consecutive} successive attempts were rejected"


@dataclass(frozen=True)
class EnergyAccount:
    """Cumulative energy removed by the integrator and changed by contact-set changes,
    and the energies of the last accepted state (the reference of the next step)."""

    E_dissipated: float = 0.0
    E_set_change: float = 0.0
    last: dict | None = None


def total_energy(d: dict) -> float:
    """E_kin + E_strain + E_gravity + E_ext + E_contact."""
    return d["E_kin"] + d["E_strain"] + d["E_gravity"] + d["E_ext"] + d["E_contact"]


def energy_scale(d: dict) -> float:
    """The energy a step's tolerance refers to: E_kin + E_strain + |E_contact|."""
    return d["E_kin"] + d["E_strain"] + abs(d["E_contact"])




def energy_change(diag: dict, last: dict, e_contact_before: float, energy_floor: float,
                  energy_tol: float) -> tuple[float, float, float]:
    """(created, jump, allowance) of an attempt: ``jump`` the change of the contact energy
    when the frozen set changed (evaluated at the old state), ``created`` the change of
    the total energy under one set (what the integrator added, negative when it removed),
    ``allowance`` what the energy test admits: energy_tol times the energy scale plus the
    floor (the resolution of the converged solve and round-off); 0 without energy test."""
    scale = max(energy_scale(diag), energy_scale(last))
    floor = energy_floor + ENERGY_ROUNDOFF * sum(
        abs(diag[k]) + abs(last[k]) for k in ("E_kin", "E_strain", "E_gravity", "E_ext",
                                             "E_contact"))
    jump = e_contact_before - last["E_contact"]
    created = total_energy(diag) - (total_energy(last) + jump)
    return created, jump, energy_tol * scale + floor if energy_tol > 0 else 0.0


def next_step(h: float, error: float, tol: float, dt: float, after_rejection: bool,
              iterations: int) -> float:
    """The step after an accepted step h with local error ``error`` (tolerance ``tol``,
    same units): h (tol/error)^(1/3) times SAFETY, between SHRINK_MIN h and GROW_MAX h, at
    most dt. It does not grow right after a rejection, nor after a step that needed more
    than GROW_ITERATIONS Newton iterations (a strongly nonlinear phase, an impact, where a
    longer step would make Newton diverge). Without error control (tol = 0) the step
    doubles back towards dt under the same two conditions."""
    cap = 1.0 if after_rejection or iterations > GROW_ITERATIONS else GROW_MAX
    if tol <= 0.0:
        return min(cap * h, dt)
    grow = GROW_MAX if error <= 0.0 else SAFETY * (tol / error) ** (1.0 / 3.0)
    return min(h * min(max(grow, SHRINK_MIN), cap), dt)


def retry_step(h: float, error: float, tol: float) -> float:
    """The step to retry after a rejection for too large an error (always shorter)."""
    return h * min(max(SAFETY * (tol / error) ** (1.0 / 3.0), SHRINK_MIN), SAFETY)


def verdict(report: dict, flags: StepFlags, h: float, max_penetration: float | None,
            tol: float, energy_allowance: float, created: float, jump: float,
            set_jumps: list[float], dt_min: float = 0.0) -> Rejection | None:
    """None if the attempt is accepted, else the :class:`Rejection`
    (``max_penetration`` None: no contact).

    A set change is refined while halving the step at least halves its jump (the jump
    came from choosing the set at a far predictor), at most SET_CHANGE_REFINEMENTS
    times and never below ``dt_min``; a jump that does not shrink is a change of the
    model itself (IPIP "zones" gains or loses a contact zone, a jump of the same size
    however short the step) and is accepted and accounted in E_set_change, never a
    reason to stop the run.
    """
    rejected = _rejection(report, flags, h, max_penetration, tol, energy_allowance, created)
    if rejected is not None:
        return rejected
    shrinking = not set_jumps or abs(jump) <= 0.5 * set_jumps[-1]
    if (abs(jump) > energy_allowance > 0.0 and shrinking
            and len(set_jumps) < SET_CHANGE_REFINEMENTS and 0.5 * h >= dt_min):
        return Rejection("set_change", f"the contact energy jumped by {jump:.3g} J when the "
                         f"contact set changed (allowed {energy_allowance:.3g} J)", 0.5 * h)
    return None


def _rejection(report: dict, flags: StepFlags, h: float, max_penetration: float | None,
               tol: float, energy_allowance: float, created: float) -> Rejection | None:
    """The :class:`Rejection` of an attempt that fails a test other than the set change,
    else None."""
    if StepFlags.CONVERGED not in flags:
        return Rejection("newton", "Newton did not converge", 0.5 * h)
    if max_penetration is not None:
        if StepFlags.MISSING_BLOCK in flags:
            return Rejection("missing_block", "the step moved further than the candidate "
                             "search foresaw (a contact block was missing)", 0.5 * h)
        if report["min_gap"] < -max_penetration:
            return Rejection("penetration", f"penetration {-report['min_gap']:.3g} m exceeded "
                             f"max_penetration = {max_penetration:.3g} m", 0.5 * h)
        if report["approach"] > ADVANCE_ACCEPT:
            return Rejection("advancement", f"a contact point approached by "
                             f"{report['approach']:.3g} of its gap in one step (tunnelling "
                             f"guard)", h * ADVANCE_FRACTION / report["approach"])
    if tol > 0.0 and report["error"] > tol:
        return Rejection("error", f"local error {report['error']:.3g} m above error_tol "
                         f"({tol:.3g} m)", retry_step(h, report["error"], tol))
    if energy_allowance > 0.0 and not abs(created) <= energy_allowance:
        return Rejection("energy", f"the total energy {'grew' if created > 0 else 'fell'} by "
                         f"{abs(created):.3g} J in one step (allowed {energy_allowance:.3g} "
                         f"J)", 0.5 * h)
    return None


def step_size(t: float, t_end: float, h_try: float) -> float:
    """The next step: h_try, shortened to land on t_end without leaving a sliver."""
    remaining = t_end - t
    if abs(remaining - h_try) <= 1e-9 * h_try:
        return h_try  # exactly nominal, so a restart repeats the same arithmetic
    h = min(h_try, remaining)
    return remaining if remaining - h < 1e-6 * h else h


def on_grid(t: float, dt: float, t_end: float) -> float:
    """Snap a time within round-off of a multiple of the largest step (or of t_end) onto
    it, so that fixed-step times do not drift and a restarted run repeats an uninterrupted
    one."""
    k = round(t / dt)
    if abs(t - k * dt) <= 1e-9 * dt:
        return k * dt
    return t_end if abs(t - t_end) <= 1e-9 * dt else t


