"""MkDocs hook: publish README files that live outside ``docs/`` at their repository paths.

The examples and benchmarks are documented by README files next to their scripts (so that
they read well on a code host too). This hook adds each of them to the site under its own
repository path (``examples/free_fall/README.md`` becomes the page ``examples/free_fall/``),
together with every file those READMEs link to that is not a Markdown page (images), so
that their relative links and images resolve unchanged. Links to pages that are not
published stay broken and fail ``mkdocs build --strict``, as they should.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File, Files

# Repository-relative paths of the READMEs to publish.
PAGES = (
    "examples/free_fall/README.md",
    "examples/studies/README.md",
    "benchmarks/README.md",
    "benchmarks/peers/README.md",
)

# Targets of Markdown links and images: ](target) or ](target "title").
_LINK = re.compile(r"\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def _linked_assets(readme: Path, root: Path) -> list[str]:
    """Repository-relative paths of the local non-Markdown files that ``readme`` links to."""
    assets = []
    for target in _LINK.findall(readme.read_text(encoding="utf-8")):
        target = target.split("#", 1)[0]
        if not target or "://" in target or target.startswith(("/", "mailto:")):
            continue
        if target.endswith(".md"):
            continue
        path = (readme.parent / target).resolve()
        if path.is_file() and path.is_relative_to(root):
            assets.append(path.relative_to(root).as_posix())
    return assets


def on_files(files: Files, config) -> Files:
    root = Path(config["config_file_path"]).resolve().parent
    wanted: list[str] = []
    for page in PAGES:
        wanted.append(page)
        wanted.extend(_linked_assets(root / page, root))
    for src_uri in dict.fromkeys(wanted):
        if files.get_file_from_path(src_uri) is None:
            files.append(File.generated(config, src_uri, abs_src_path=str(root / src_uri)))
    return files
