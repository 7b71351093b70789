"""The free-fall benchmark (examples/free_fall/case_cg.toml) built in Python.

Builds the case from the API's objects instead of a TOML file, checks that it is the
same case as the file (the same checks run; the objects compare equal), runs both and
checks that the histories are identical to the last digit.

    python examples/python_api/free_fall.py [--t-end 3.0] [--out DIR]

With ``--out`` the Python-built run writes exactly what ``beamcontact run`` writes.
"""

import argparse
from pathlib import Path

import beamcontact as bc

HERE = Path(__file__).resolve().parent
TOML = HERE.parent / "free_fall" / "case_cg.toml"


def free_fall_case(t_end: float = 3.0) -> "bc.Case":
    """The coarse-grained free-fall benchmark (paper Sec. 5; reconstruction documented in
    examples/free_fall/README.md)."""
    section = bc.CircleSection(radius=0.1)
    material = bc.Material(E=0.98e6, density=1000.0)
    return bc.Case(
        title="Free fall of an elastic beam onto another beam (coarse-grained contact)",
        analysis=bc.Analysis(kind="dynamic", t_end=t_end, dt=1.0e-3, alpha=-0.33,
                             gravity=(0.0, -9.81)),
        beams=[
            bc.Beam(name="lower", line=bc.Line(start=(0.0, 0.0), end=(10.0, 0.0)),
                    degree=4, elements=20, continuity=1, section=section, material=material,
                    supports=[bc.Support(at="start", type="pinned"),
                              bc.Support(at="end", type="pinned")],
                    gravity=False),
            bc.Beam(name="upper", line=bc.Line(start=(3.5, 2.959), end=(6.5, 2.959)),
                    degree=4, elements=6, continuity=1, section=section, material=material,
                    gravity=True),
        ],
        contact=bc.Contact(model="cg", segments_per_element=60, exponent=12, k=5.0e-25,
                           densities=[1.0, 1.0], cutoff=0.3),
        output=bc.Output(points=[bc.OutputPoint(name="A", beam="lower", at=0.5)],
                         vtk_interval=0.02),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=3.0, help="simulated time [s]")
    ap.add_argument("--out", type=Path, default=None, help="output folder of the Python run")
    args = ap.parse_args()

    case = free_fall_case(args.t_end)
    from_file = bc.load_case(TOML)
    from_file = from_file.model_copy(
        update={"analysis": from_file.analysis.model_copy(update={"t_end": args.t_end})})
    assert case == from_file, "the Python-built case differs from case_cg.toml"

    python_run = bc.simulate(case, out=args.out, progress=True, overwrite=True)
    toml_run = bc.simulate(from_file)
    identical = python_run.history.equals(toml_run.history)
    print(f"{python_run.status}: {python_run.summary['message']}")
    print(f"first amplitude of A: {python_run.summary['first_amplitude'].get('A')}")
    print(f"histories identical: {identical} ({len(python_run.history)} rows)")
    if not identical:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
