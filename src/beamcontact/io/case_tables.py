"""The tables of a case file (docs/case_file.md) as pydantic v2 models: ``[analysis]``,
``[[beams]]`` (with ``line`` / ``arc`` / ``nurbs``, ``section``, ``material``,
``supports``), ``[[loads]]``, ``[contact]``, ``[[obstacles]]``, ``[solver]``,
``[output]``. Each validates its own values; :class:`beamcontact.io.case.Case` puts
them together and checks what spans several tables. SI units throughout.
"""

import math
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

if TYPE_CHECKING:
    from beamcontact.contact.laws import ContactLaw


class CaseError(ValueError):
    """Invalid case: the message names the offending key."""


class _TableMeta(type(BaseModel)):
    """Turns the ValidationError of a table built in Python (``Material(E=-1.0)``) into a
    :class:`CaseError` naming the table and the key, as a case file's is. Only a call of
    the class comes here: the tables inside a validated case are made by pydantic."""

    def __call__(cls, *args: Any, **kwargs: Any):
        try:
            return super().__call__(*args, **kwargs)
        except ValidationError as exc:
            raise CaseError("\n".join(dict.fromkeys(
                _constructor_error(cls.__name__, e) for e in exc.errors()))) from None


class _Strict(BaseModel, metaclass=_TableMeta):
    """A table of the case: unknown keys, NaN and infinities are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


def _constructor_error(table: str, err: dict) -> str:
    """One line for an invalid value given to a table's constructor."""
    if err["type"] == "cross_check":  # a check across tables names its own keys
        return err["msg"]
    key = ".".join([table, *(str(k) for k in err["loc"])])
    if err["type"] == "missing":
        return f"{key}: required key is missing"
    if err["type"] == "extra_forbidden":
        return f"{key}: unknown key"
    msg = err["msg"].removeprefix("Value error, ").replace("Input should be", "must be")
    if "got" in msg or not err["loc"]:
        return f"{key}: {msg}"
    return f"{key}: {msg}, got {err['input']!r}"


def _as_list(value: Any) -> Any:
    """Tuples and NumPy arrays given in Python become the lists a TOML file gives."""
    if isinstance(value, tuple):
        return [_as_list(v) for v in value]
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    return value


Vec2 = Annotated[list[float], BeforeValidator(_as_list), Field(min_length=2, max_length=2)]
Positive = Annotated[float, Field(gt=0.0)]


def _check_at(value: Any) -> str | float:
    """A place on a beam: "start", "end", or a fraction of its reference length in [0, 1]."""
    if isinstance(value, str):
        if value not in ("start", "end"):
            raise ValueError(f'must be "start", "end" or a number in [0, 1], got {value!r}')
        return value
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f'must be "start", "end" or a number in [0, 1], got {value!r}')
    if not 0.0 <= float(value) <= 1.0:
        raise ValueError(f"must lie in [0, 1], got {value}")
    return float(value)


def at_fraction(at: str | float) -> float:
    """Fraction of the reference length for a validated ``at``."""
    return {"start": 0.0, "end": 1.0}.get(at, at) if isinstance(at, str) else float(at)


class Line(_Strict):
    """Straight axis from ``start`` to ``end`` [m]."""

    start: Vec2
    end: Vec2

    @model_validator(mode="after")
    def _distinct(self):
        if math.dist(self.start, self.end) == 0.0:
            raise ValueError("start and end must differ")
        return self


class Arc(_Strict):
    """Circular arc [m, rad]; angles counter-clockwise from +x, 0 < |end - start| < 2 pi."""

    center: Vec2
    radius: Positive
    start_angle: float
    end_angle: float

    @field_validator("end_angle")
    @classmethod
    def _sweep(cls, v: float, info: ValidationInfo) -> float:
        start = info.data.get("start_angle")
        if start is not None and not 0.0 < abs(v - start) < 2.0 * math.pi:
            raise ValueError(f"the sweep end_angle - start_angle must satisfy 0 < |sweep| < 2 pi,"
                             f" got {v - start}")
        return v


class Nurbs(_Strict):
    """A NURBS axis given directly (open knot vector; weights default to 1)."""

    degree: Annotated[int, Field(ge=1)]
    knots: Annotated[list[float], BeforeValidator(_as_list)]
    points: Annotated[list[Vec2], BeforeValidator(_as_list)]
    weights: Annotated[list[Positive], BeforeValidator(_as_list)] | None = None

    @model_validator(mode="after")
    def _consistent(self):
        n, p = len(self.points), self.degree
        if len(self.knots) != n + p + 1:
            raise ValueError(f"needs len(knots) = len(points) + degree + 1 = {n + p + 1}, "
                             f"got {len(self.knots)}")
        if self.weights is not None and len(self.weights) != n:
            raise ValueError(f"needs one weight per point ({n}), got {len(self.weights)}")
        k = self.knots
        if any(b < a for a, b in zip(k[:-1], k[1:], strict=True)) or k[0] == k[-1]:
            raise ValueError("knots must be non-decreasing and span a non-empty interval")
        if len(set(k[: p + 1])) != 1 or len(set(k[-p - 1 :])) != 1:
            raise ValueError(f"the knot vector must be open (first and last knot repeated "
                             f"degree + 1 = {p + 1} times)")
        inner = k[p + 1 : -p - 1]
        if any(inner.count(u) > p - 1 for u in set(inner)):
            raise ValueError("interior knots may repeat at most degree - 1 times (a beam "
                             "axis must be C^1)")
        return self


class CircleSection(_Strict):
    """Solid circle of ``radius`` [m]."""

    shape: Literal["circle"] = "circle"
    radius: Positive


class RectangleSection(_Strict):
    """Rectangle ``width`` (out of plane) x ``height`` (in the plane of bending) [m]."""

    shape: Literal["rectangle"] = "rectangle"
    width: Positive
    height: Positive


class Material(_Strict):
    """St. Venant-Kirchhoff material: Young's modulus E [Pa], density [kg/m^3]."""

    E: Positive
    density: Positive


class Support(_Strict):
    """Rotation-free support: pinned fixes the end control point, clamped also the next."""

    at: Literal["start", "end"]
    type: Literal["pinned", "clamped"]


class Beam(_Strict):
    """One beam: axis geometry, discretisation, section, material, supports."""

    name: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9_\-]+$")]
    line: Line | None = None
    arc: Arc | None = None
    nurbs: Nurbs | None = None
    degree: Annotated[int, Field(ge=2, le=10)] = 3
    elements: Annotated[int, Field(ge=1, le=10_000)] = 10
    continuity: int | None = None
    section: Annotated[CircleSection | RectangleSection, Field(discriminator="shape")]
    material: Material
    supports: list[Support] = []
    gravity: bool = True
    initial_velocity: Vec2 = [0.0, 0.0]
    remove_outliers: bool = False

    @field_validator("continuity")
    @classmethod
    def _continuity(cls, v: int | None, info: ValidationInfo) -> int | None:
        p = info.data.get("degree")
        if v is not None and p is not None and not 1 <= v <= p - 1:
            raise ValueError(f"must be between 1 and degree - 1 = {p - 1} (rotation-free beams "
                             f"need C^1), got {v}")
        return v

    @field_validator("supports")
    @classmethod
    def _one_per_end(cls, v: list[Support]) -> list[Support]:
        ends = [s.at for s in v]
        if len(set(ends)) != len(ends):
            raise ValueError("at most one support per end")
        return v

    @model_validator(mode="after")
    def _one_geometry(self):
        given = [k for k in ("line", "arc", "nurbs") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one axis geometry: line, arc or nurbs "
                             f"(got {', '.join(given) or 'none'})")
        if self.nurbs is not None and self.nurbs.degree > self.degree:
            raise ValueError(f"degree {self.degree} is below the nurbs degree "
                             f"{self.nurbs.degree}")
        if self.remove_outliers:
            if self.degree < 4:
                raise ValueError(f"remove_outliers needs degree >= 4 (a cubic's end element "
                                 f"would become a parabola), got degree {self.degree}")
            if self.elements < 2:
                raise ValueError("remove_outliers needs at least 2 elements")
            if not self.unsupported_ends:
                raise ValueError("remove_outliers applies at free ends, and both ends of "
                                 "this beam are supported")
        return self

    @property
    def unsupported_ends(self) -> tuple[str, ...]:
        """The ends ("start", "end") without a support."""
        held = {s.at for s in self.supports}
        return tuple(e for e in ("start", "end") if e not in held)

    @property
    def smoothness(self) -> int:
        """Continuity between elements (default: degree - 1, the smoothest)."""
        return self.degree - 1 if self.continuity is None else self.continuity


class Load(_Strict):
    """Dead point force [N] and moment [N m] (counter-clockwise positive) on a beam."""

    beam: str
    at: Any
    force: Vec2 = [0.0, 0.0]
    moment: float = 0.0

    _at = field_validator("at")(_check_at)


class Analysis(_Strict):
    """Kind of analysis and its parameters.

    Dynamics: ``dt`` is the first and the largest time step [s] (the controller shortens
    it for accuracy and through impacts, see ``solver.error_tol``); ``dt_min`` the
    shortest step before the run stops with a message [s] (default 1e-6 dt).
    """

    kind: Literal["static", "dynamic"]
    load_steps: Annotated[int, Field(ge=1)] = 10
    t_end: Positive | None = None
    dt: Positive | None = None
    dt_min: Positive | None = None
    alpha: Annotated[float, Field(ge=-1.0 / 3.0, le=0.0)] = 0.0
    gravity: Vec2 = [0.0, 0.0]

    @model_validator(mode="after")
    def _dynamic_needs_time(self):
        if self.kind == "dynamic":
            if self.t_end is None or self.dt is None:
                raise ValueError('kind = "dynamic" needs t_end and dt')
            if self.dt > self.t_end:
                raise ValueError(f"dt = {self.dt} exceeds t_end = {self.t_end}")
            if self.dt_min is not None and self.dt_min > self.dt:
                raise ValueError(f"dt_min = {self.dt_min} exceeds dt = {self.dt}")
        return self

    @property
    def smallest_step(self) -> float:
        """dt_min, or its default 1e-6 dt."""
        return self.dt_min if self.dt_min is not None else 1e-6 * self.dt


class Contact(_Strict):
    """Beam-to-beam contact (Sec. 2 of the paper) between every two different beams, or
    between the pairs of beams listed in ``pairs`` (by name, e.g. [["a", "b"]]).

    ``densities``: one particle density per beam, or a single value for all.
    ``q_reg``: regularisation gap of the coarse-grained potential [m] (default 1e-3 times
    the smallest radius). ``max_penetration``: a step whose smallest gap falls below
    -max_penetration is redone with half the step [m] (default: the smallest radius).
    ``capacity``: initial length of the list of candidate element pairs (it grows by
    itself when the broad phase finds more; unused entries cost nothing but memory).
    ``pairing`` (IPIP only; default "points"): "points", every integration point with its
    closest point on the other beam, 1/2 from each side (the contact energy is continuous,
    so the contact is conservative; along a line contact it acts as a line penalty of
    about eps per point spacing), or "zones", the paper's closest pair of integration
    points of each contact zone (a zone that appears while the beams overlap makes the
    contact energy jump; the case files that reproduce the paper's figures set it). See
    docs/theory.md, "IPIP pairing rules".
    ``self_contact``: every beam also touches itself (a rolled or folded beam), with the
    same law; two points of one beam interact only if they are at least
    ``self_exclusion`` apart along it in the reference configuration [m] (default: four
    times the largest radius, and at least the cutoff for "cg"), so that neighbours
    along the axis never count as a contact. See docs/theory.md, "Self-contact".
    """

    model: Literal["none", "ipip", "cg"] = "none"
    segments_per_element: Annotated[int, Field(ge=1, le=200)] = 20
    penalty: Positive = 1.0e6
    exponent: Annotated[float, Field(gt=3.5)] = 12.0
    k: Positive = 5.0e-25
    densities: Annotated[list[Positive], BeforeValidator(_as_list), Field(min_length=1)] = [1.0]
    cutoff: Positive = 0.3
    q_reg: Positive | None = None
    max_penetration: Positive | None = None
    capacity: Annotated[int, Field(ge=1)] = 128
    pairing: Literal["zones", "points"] | None = None  # None: "points" (IPIP only)
    self_contact: bool = False
    self_exclusion: Positive | None = None
    pairs: Annotated[list[Annotated[list[str], BeforeValidator(_as_list),
                                    Field(min_length=2, max_length=2)]],
                     BeforeValidator(_as_list), Field(min_length=1)] | None = None

    def law(self, radii: list[float]) -> "ContactLaw | None":
        """The contact law of these settings for beams with half-depths ``radii`` (None
        for model "none"): the one place where a law meets the case file."""
        from beamcontact.contact.laws import CoarseGrained, Penalty

        if self.model == "ipip":
            return Penalty(self.penalty, self.max_penetration_or(radii),
                           self.pairing or "points")
        if self.model == "cg":
            q_reg = self.q_reg if self.q_reg is not None else 1e-3 * min(radii)
            return CoarseGrained(self.k, self.exponent, q_reg, self.cutoff)
        return None

    def max_penetration_or(self, radii: list[float]) -> float:
        """max_penetration, or its default: the smallest half-depth."""
        return self.max_penetration if self.max_penetration is not None else min(radii)


class Wall(_Strict):
    """A rigid half-plane: ``point`` on its surface [m] and ``normal`` pointing out of the
    solid (any nonzero length); the half-plane behind the normal is solid."""

    point: Vec2
    normal: Vec2

    @model_validator(mode="after")
    def _normal(self):
        if math.hypot(*self.normal) == 0.0:
            raise ValueError("normal must be a nonzero vector")
        return self


class Circle(_Strict):
    """A rigid disk: ``center`` [m] and ``radius`` [m]."""

    center: Vec2
    radius: Positive


class Obstacle(_Strict):
    """A rigid obstacle every beam touches with the contact law of ``[contact]``: give
    exactly one of ``wall`` or ``circle``. ``density``: the obstacle's particle density
    beta_o of the coarse-grained law (default 1; model "cg" only). See docs/theory.md,
    "Rigid obstacles"."""

    name: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9_\-]+$")]
    wall: Wall | None = None
    circle: Circle | None = None
    density: Positive | None = None

    @model_validator(mode="after")
    def _one_shape(self):
        given = [k for k in ("wall", "circle") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one shape: wall or circle (got "
                             f"{', '.join(given) or 'none'})")
        return self


class Solver(_Strict):
    """Newton-Raphson and step control.

    rtol: residual reduction ||r|| <= rtol ||r_0||; utol: increment ||du||_inf <= utol L
    (L the longest beam); max_cutbacks: statics: halvings of a load increment before
    giving up; dynamics: successive rejected attempts at one time step before giving up.
    Dynamics only: error_tol bounds the local error estimate of one step (Zienkiewicz-Xie,
    the largest component over the control points) as a fraction of L: 2.5e-6 with
    L = 10 m allows 25 um per step (0: fixed steps of analysis.dt, cut only on failure);
    energy_tol: a step that creates more than this fraction of E_kin + E_strain +
    |E_contact|, or whose contact-set change jumps the energy by more, is redone shorter
    (0: no check); newton_error_fraction: Newton also stops once the error left in its
    iterate (the next increment, solved with the factors of the tangent in hand) is below
    this fraction of the local error bound error_tol L, a thousandth by default (0: only
    rtol and utol stop it; Hairer & Wanner, Solving ODEs II, Sec. IV.8). linear_solver:
    how Newton's linear systems are solved, "dense" (one n x n matrix, LU on the device),
    "sparse" (the local blocks kept as triplets, banded or sparse LU on the host; cost
    linear in the number of dofs) or "auto" (sparse on CPU from 300 dofs on, else dense;
    the jax engine's choice). engine: which engine runs the
    steps (docs/architecture.md, "Engines"): "native" (compiled for the CPU, Numba),
    "jax" (differentiable, GPUs) or "auto" (native where every term of the case has a
    native kernel and no GPU is installed, else jax; summary.json's ``solver`` says which
    ran and why).
    """

    max_iterations: Annotated[int, Field(ge=1, le=500)] = 25
    rtol: Annotated[float, Field(gt=0.0, lt=1.0)] = 1e-9
    utol: Annotated[float, Field(gt=0.0, lt=1.0)] = 1e-11
    max_cutbacks: Annotated[int, Field(ge=0, le=200)] = 20
    error_tol: Annotated[float, Field(ge=0.0, lt=1.0)] = 2.5e-6
    energy_tol: Annotated[float, Field(ge=0.0)] = 2.5e-4
    newton_error_fraction: Annotated[float, Field(ge=0.0, lt=1.0)] = 1e-3
    linear_solver: Literal["auto", "dense", "sparse"] = "auto"
    engine: Literal["auto", "native", "jax"] = "auto"


class OutputPoint(_Strict):
    """A point followed in history.csv."""

    name: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9_]+$")]
    beam: str
    at: Any

    _at = field_validator("at")(_check_at)


class Output(_Strict):
    """What is written: followed points, VTU cadence and polyline resolution.

    Statics write a VTU snapshot every ``vtk_every`` load steps; dynamics every
    ``vtk_interval`` seconds of simulated time (default t_end / 100).
    """

    points: list[OutputPoint] = []
    vtk_every: Annotated[int, Field(ge=1)] = 1
    vtk_interval: Positive | None = None
    samples_per_element: Annotated[int, Field(ge=1, le=200)] = 8
