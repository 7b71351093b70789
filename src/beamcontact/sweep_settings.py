"""The members of a parameter sweep: ``--set KEY=V1,V2`` parsed, applied to a case, and
expanded into the Cartesian product (see :mod:`beamcontact.sweep`).

A KEY is a dotted path into the case file; entries of a list of tables (``beams``,
``loads``, ``output.points``) are addressed by their ``name`` or by their index
(``beams.upper.material.E``, ``loads.0.force``). A value is read as a TOML value (number,
boolean, array ``[0.0, -9.81]``); anything else is a string (``contact.model=cg,ipip``).
Commas inside brackets or quotes do not split values. Every member is validated by the
case schema.
"""

import copy
import itertools
import math
import re
import tomllib
from dataclasses import dataclass
from typing import Any

import tomli_w

from beamcontact.io.case import CaseError, parse_case


@dataclass(frozen=True)
class Setting:
    """One ``--set KEY=V1,V2,...``: a dotted key and the values it takes."""

    key: str
    values: tuple[Any, ...]


@dataclass(frozen=True)
class Member:
    """One run of a sweep: its folder name, parameters, legend label and case text."""

    name: str
    params: tuple[tuple[str, Any], ...]
    label: str
    case_text: str


def _split_values(text: str) -> list[str]:
    """Split at commas that are not inside brackets, braces or quotes."""
    parts, depth, quote, start = [], 0, "", 0
    for i, ch in enumerate(text):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def _parse_value(text: str) -> Any:
    """A TOML value, or the text itself as a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def parse_setting(text: str) -> Setting:
    """``KEY=V1,V2,...`` -> Setting; CaseError naming the problem."""
    key, sep, values = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise CaseError(f"--set {text!r}: expected KEY=V1,V2,... (e.g. contact.penalty=1e5,1e6)")
    if not re.fullmatch(r"[A-Za-z0-9_\-]+(\.[A-Za-z0-9_\-]+)*", key):
        raise CaseError(f"--set {key}: a key is a dotted path such as beams.upper.material.E")
    raw = _split_values(values)
    if any(not v for v in raw):
        raise CaseError(f"--set {key}: empty value in {values!r}")
    parsed = [_parse_value(v) for v in raw]
    for i, v in enumerate(parsed):
        if any(type(v) is type(w) and v == w for w in parsed[:i]):
            raise CaseError(f"--set {key}: value {raw[i]} is given twice")
    return Setting(key, tuple(parsed))


def apply_setting(raw: dict, key: str, value: Any) -> None:
    """Set ``key`` (dotted, list entries by name or index) to ``value`` in ``raw``, in place.

    Missing tables are created; whether a key exists at all is for the case schema to say.
    """
    parts = key.split(".")
    node: Any = raw
    for depth, part in enumerate(parts):
        where = ".".join(parts[:depth]) or "the case"
        last = depth == len(parts) - 1
        if isinstance(node, list):
            names = [e.get("name") if isinstance(e, dict) else None for e in node]
            if part in names:
                index = names.index(part)
            elif part.isdigit() and int(part) < len(node):
                index = int(part)
            else:
                known = ", ".join(str(n) for n in names if n is not None)
                raise CaseError(f"--set {key}: {where} has no entry {part!r} (entries are "
                                f"addressed by name{': ' + known if known else ''}, or by "
                                f"index 0..{len(node) - 1})")
            if last:
                raise CaseError(f"--set {key}: names a whole entry of {where}; name one of "
                                f"its keys")
            node = node[index]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise CaseError(f"--set {key}: {where} is a value, not a table")


def _short_keys(keys: list[str]) -> list[str]:
    """The shortest dotted suffixes that still tell the keys apart (for labels)."""
    split = [k.split(".") for k in keys]
    for n in range(1, max(len(s) for s in split) + 1):
        short = [".".join(s[-n:]) for s in split]
        if len(set(short)) == len(short):
            return short
    return keys


def format_value(v: Any) -> str:
    """Compact text of a parameter value (labels, folder names, sweep.csv) that reads back
    as the same value: 12 significant digits where they do, else every digit (a study of
    round-off moves a value by one unit in the last place)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if not math.isfinite(v):  # TOML's inf, -inf, nan
            return repr(v)
        if v != 0.0 and not 1e-3 <= abs(v) < 1e4:
            mantissa, exponent = f"{v:.12e}".split("e")
            text = f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"
        else:
            text = f"{v:.12g}"
        return text if float(text) == v else repr(v)
    if isinstance(v, list):
        return "[" + ",".join(format_value(x) for x in v) + "]"
    return str(v)


def expand(raw: dict, settings: list[Setting]) -> list[Member]:
    """The Cartesian product of ``settings`` applied to the case ``raw``, each validated.

    Raises CaseError (naming the key and the member) before anything runs.
    """
    keys = [s.key for s in settings]
    if not settings:
        raise CaseError("--set: give at least one KEY=V1,V2,...")
    for i, k in enumerate(keys):
        if k in keys[:i]:
            raise CaseError(f"--set {k}: the key is given twice")
    short = _short_keys(keys)
    members, names = [], set()
    for combo in itertools.product(*(s.values for s in settings)):
        member_raw = copy.deepcopy(raw)
        for key, value in zip(keys, combo, strict=True):
            apply_setting(member_raw, key, value)
        label = ", ".join(f"{s}={format_value(v)}" for s, v in zip(short, combo, strict=True))
        try:
            parse_case(member_raw)
        except CaseError as exc:
            raise CaseError(f"sweep member {label}: {exc}") from None
        name = re.sub(r"[^A-Za-z0-9_.,=+\-\[\]]", "-", label.replace(", ", "_"))[:120]
        base, k = name, 1
        while name in names:
            k += 1
            name = f"{base}_{k}"
        names.add(name)
        members.append(Member(name, tuple(zip(keys, combo, strict=True)), label,
                              tomli_w.dumps(member_raw)))
    return members
