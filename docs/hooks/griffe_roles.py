"""Griffe extension: show Sphinx cross-reference roles of the docstrings as inline code.

Some docstrings use reStructuredText roles such as ``:func:`name``` or
``:mod:`~pkg.module```; Markdown would print the role itself. This extension rewrites them
to plain inline code (``~`` keeps only the last component, as in Sphinx) before rendering.
The source files are not changed.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(
    r":(?:py:)?(?:func|class|meth|mod|attr|data|obj|exc|const|type):`(~?)([^`]+)`"
)


def _code(match: re.Match) -> str:
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


class RolesToCode(griffe.Extension):
    """Replace ``:role:`target``` by ```target``` in every docstring."""

    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(_code, obj.docstring.value)
