"""The case: TOML validated by pydantic v2 (docs/case_file.md), or built in Python.

Every invalid value is reported as one line naming the key, e.g.
``beams[0] (lower).section.radius: must be > 0, got -0.1``. SI units throughout.
A :class:`Case` built in Python from these classes (``Case(analysis=Analysis(...),
beams=[Beam(...)], ...)``) runs the same checks, cross-checks between sections included,
and converts to and from TOML (:meth:`Case.to_toml`, :meth:`Case.from_toml`).
"""

import re
import tomllib
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

# the tables, importable from here as well (``from beamcontact.io.case import Beam``)
from beamcontact.io.case_tables import (  # noqa: F401
    Analysis,
    Arc,
    Beam,
    CaseError,
    Circle,
    CircleSection,
    Contact,
    Line,
    Load,
    Material,
    Nurbs,
    Obstacle,
    Output,
    OutputPoint,
    RectangleSection,
    Solver,
    Support,
    Wall,
    _Strict,
    at_fraction,
)


class Case(_Strict):
    """A whole case file."""

    title: str = ""
    analysis: Analysis
    beams: Annotated[list[Beam], Field(min_length=1)]
    loads: list[Load] = []
    contact: Contact = Contact()
    obstacles: list[Obstacle] = []
    solver: Solver = Solver()
    output: Output = Output()

    @model_validator(mode="after")
    def _cross_checks(self):
        try:
            _check_references(self)
        except CaseError as exc:  # its message names the key; keep it as it is
            raise PydanticCustomError("cross_check", str(exc)) from None
        return self

    def beam_index(self, name: str) -> int:
        """Index of the beam called ``name``."""
        return [b.name for b in self.beams].index(name)

    def to_toml(self) -> str:
        """The case as a TOML case file (every value that is set; None means "default"
        and is left out, as TOML has no null)."""
        import tomli_w

        text = tomli_w.dumps(self.model_dump(mode="json", exclude_none=True))
        # tomli_w puts every array element on a line of its own; short arrays of numbers
        # and strings read better on one line, as a person writes them
        return re.sub(r"\[\n((?:    [^\[\]{}\n]+,\n)+)\]",
                      lambda m: "[" + ", ".join(v.strip().rstrip(",")
                                                for v in m.group(1).splitlines()) + "]", text)

    @classmethod
    def from_toml(cls, text: str) -> "Case":
        """Parse and validate the text of a TOML case file (raises CaseError)."""
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise CaseError(f"invalid TOML: {exc}") from None
        return parse_case(raw)


def _key_path(loc: tuple, raw: dict) -> str:
    parts: list[str] = []
    node: Any = raw
    for item in loc:
        if isinstance(item, int):
            label = f"[{item}]"
            if isinstance(node, list) and item < len(node):
                node = node[item]
                if isinstance(node, dict) and isinstance(node.get("name"), str):
                    label += f" ({node['name']})"
            parts.append(label)
            continue
        if isinstance(node, dict) and item in node:
            node = node[item]
        elif item in ("circle", "rectangle"):  # discriminated-union tag, not a key
            continue
        parts.append(("." if parts else "") + str(item))
    return "".join(parts) or "case"


def _describe(err: dict, raw: dict) -> str:
    path = _key_path(tuple(err["loc"]), raw)
    kind = err["type"]
    if kind == "cross_check":
        return err["msg"]
    if kind == "missing":
        return f"{path}: required key is missing"
    if kind == "extra_forbidden":
        return f"{path}: unknown key"
    msg = err["msg"].removeprefix("Value error, ")
    msg = msg.replace("Input should be", "must be")
    return f"{path}: {msg}, got {err['input']!r}" if "got" not in msg else f"{path}: {msg}"


def parse_case(raw: dict) -> Case:
    """Validate a case given as a dict (from TOML); raise CaseError naming the key."""
    try:
        case = Case.model_validate(raw)
    except ValidationError as exc:
        # every problem, one line each (the checks across tables run only once every
        # table is valid)
        raise CaseError("\n".join(dict.fromkeys(_describe(e, raw) for e in exc.errors()))) \
            from None
    return case


def _check_references(case: Case) -> None:
    names = [b.name for b in case.beams]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise CaseError(f"beams[{i}].name: duplicate beam name {name!r}")
    known = ", ".join(names)
    for group, items in (("loads", case.loads), ("output.points", case.output.points)):
        for i, item in enumerate(items):
            if item.beam not in names:
                raise CaseError(f"{group}[{i}].beam: unknown beam {item.beam!r} "
                                f"(beams are: {known})")
    point_names = [p.name for p in case.output.points]
    for i, name in enumerate(point_names):
        if name in point_names[:i]:
            raise CaseError(f"output.points[{i}].name: duplicate point name {name!r}")
    seen = set()
    for i, pair in enumerate(case.contact.pairs or []):
        for name in pair:
            if name not in names:
                raise CaseError(f"contact.pairs[{i}]: unknown beam {name!r} (beams are: "
                                f"{known})")
        if pair[0] == pair[1]:
            raise CaseError(f"contact.pairs[{i}]: list pairs of different beams; for a "
                            f"beam touching itself set contact.self_contact = true")
        if frozenset(pair) in seen:
            raise CaseError(f"contact.pairs[{i}]: the pair {pair} is listed twice")
        seen.add(frozenset(pair))
    nd = len(case.contact.densities)
    if nd not in (1, len(case.beams)):
        raise CaseError(f"contact.densities: give one value per beam ({len(case.beams)}) or "
                        f"one for all, got {nd}")
    if case.contact.self_exclusion is not None and not case.contact.self_contact:
        raise CaseError("contact.self_exclusion: applies only with contact.self_contact = "
                        "true")
    if case.contact.model == "cg" and case.contact.pairing is not None:
        raise CaseError("contact.pairing: applies to model \"ipip\" only (model is "
                        "\"cg\")")
    if case.contact.model == "cg":
        radii = [b.section.radius if b.section.shape == "circle" else 0.5 * b.section.height
                 for b in case.beams]
        if case.contact.cutoff <= 2 * min(radii):
            raise CaseError(f"contact.cutoff: must exceed the sum of two radii "
                            f"({2 * min(radii)}), got {case.contact.cutoff}")
    _check_obstacles(case)
    _check_free_ends(case)
    for i, b in enumerate(case.beams):
        r = b.section.radius if b.section.shape == "circle" else 0.5 * b.section.height
        if b.arc is not None and r >= b.arc.radius:
            raise CaseError(f"beams[{i}] ({b.name}).section: half-depth {r} must be smaller "
                            f"than the arc radius {b.arc.radius}")


def _check_free_ends(case: Case) -> None:
    """remove_outliers (dynamics; ignored in statics, :func:`ignored_keys`): no load at an
    end it constrains (a force or a moment there breaks the shear-free condition
    u''' = 0 that it imposes)."""
    for b in case.beams:
        if not b.remove_outliers or case.analysis.kind != "dynamic":
            continue
        for j, load in enumerate(case.loads):
            end = {0.0: "start", 1.0: "end"}.get(at_fraction(load.at))
            if load.beam == b.name and end in b.unsupported_ends:
                raise CaseError(f"loads[{j}].at: a load at the {end} of beam {b.name!r}, "
                                f"whose remove_outliers makes that end shear-free; load "
                                f"it inside the beam or set remove_outliers = false")


def _check_obstacles(case: Case) -> None:
    names = [o.name for o in case.obstacles]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise CaseError(f"obstacles[{i}].name: duplicate obstacle name {name!r}")
    if case.obstacles and case.contact.model == "none":
        raise CaseError("obstacles: need a contact law; set contact.model = \"ipip\" or "
                        "\"cg\"")
    for i, o in enumerate(case.obstacles):
        if o.density is not None and case.contact.model != "cg":
            raise CaseError(f"obstacles[{i}] ({o.name}).density: applies to model \"cg\" "
                            f"only (model is \"{case.contact.model}\")")
    if case.obstacles and case.contact.model == "cg" and case.contact.exponent <= 4.5:
        raise CaseError(f"contact.exponent: the coarse-grained law against an obstacle "
                        f"needs m > 4.5 (section to half-space), got {case.contact.exponent}")


# the keys of [contact] that each law reads; the others are ignored (listed by
# ignored_keys) rather than refused: a sweep over contact.model carries both laws' keys
_LAW_KEYS = {"ipip": {"penalty", "pairing"},
             "cg": {"exponent", "k", "densities", "cutoff", "q_reg"}}


def ignored_keys(case: Case) -> list[str]:
    """Warnings, one per key set in the case that the chosen model or analysis does not
    use (it would otherwise be silently ignored): a law's parameters under the other law
    or without contact, time-stepping keys in statics, load_steps in dynamics. Warnings,
    not errors, so that one case file serves a sweep over contact.model or a static and a
    dynamic run; a pairing with "cg" stays an error (it would say something about the
    coarse-grained law that is not so)."""
    found = []
    contact, given = case.contact, case.contact.model_fields_set
    for law, keys in _LAW_KEYS.items():
        if contact.model != law:
            for key in sorted(keys & given - ({"pairing"} if contact.model == "cg" else set())):
                used = "no contact law" if contact.model == "none" else \
                    f"model \"{contact.model}\""
                found.append(f"contact.{key}: ignored with {used} (it applies to "
                             f"model \"{law}\")")
    if contact.model == "none":
        for key in sorted(given & {"segments_per_element", "max_penetration", "capacity",
                                   "self_contact", "self_exclusion", "pairs"}):
            found.append(f"contact.{key}: ignored with no contact law (contact.model = "
                         f"\"none\")")
    an, given = case.analysis, case.analysis.model_fields_set
    unused = ({"t_end", "dt", "dt_min", "alpha"} if an.kind == "static" else {"load_steps"})
    for key in sorted(unused & given):
        found.append(f"analysis.{key}: ignored in a {an.kind} analysis")
    if an.kind == "static":
        for i, b in enumerate(case.beams):
            if b.remove_outliers:
                found.append(f"beams[{i}].remove_outliers: ignored in a static analysis "
                             f"(it removes modes, which statics does not have)")
    return found


def read_case_file(path: str | Path) -> tuple[Case, str]:
    """Read and validate a TOML case file; returns the case and the file's text."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise CaseError(f"{path}: cannot read the case file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise CaseError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at "
                        f"position {exc.start}); save the case file as UTF-8") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"{path}: invalid TOML: {exc}") from None
    return parse_case(raw), text
