"""The bundled examples (the repository's ``examples/`` folder, installed with the package
as ``beamcontact/examples``), reachable from Python wherever beamcontact is installed::

    import beamcontact as bc
    case = bc.load_case(bc.examples.path("free_fall", "case_cg.toml"))

:func:`names` lists them; :func:`path` is an example's folder or one of its files.
"""

from importlib import resources
from pathlib import Path


def folder() -> Path:
    """The folder of the examples: the installed package's copy, else (a source checkout)
    the repository's."""
    installed = Path(str(resources.files("beamcontact"))) / "examples"
    if installed.is_dir():
        return installed
    return Path(__file__).resolve().parents[2] / "examples"


def names() -> list[str]:
    """The examples there are (their folder names)."""
    return sorted(p.name for p in folder().iterdir()
                  if p.is_dir() and not p.name.startswith((".", "_")))


def path(name: str, file: str | None = None) -> Path:
    """The folder of example ``name``, or its ``file`` (e.g. "case.toml"); a ValueError
    naming what there is when either does not exist."""
    base = folder() / name
    if not base.is_dir():
        raise ValueError(f"no example {name!r}; the examples are: {', '.join(names())}")
    if file is None:
        return base
    target = base / file
    if not target.is_file():
        there = sorted(p.name for p in base.iterdir() if p.suffix == ".toml")
        raise ValueError(f"example {name!r} has no file {file!r}; its case files: "
                         f"{', '.join(there)}")
    return target
