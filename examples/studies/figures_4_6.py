"""The paper's Figs. 4 and 6 as figures: the cubic B-spline of Fig. 4 with its basis
functions, and snapshots of the bundled free-fall run (Fig. 6).

Fig. 4 (paper Sec. 3): a cubic B-spline on the open knot vector
xi = {0, 0, 0, 0, 0.25, 0.5, 0.75, 0.75, 0.75, 1, 1, 1, 1}, nine control points, drawn with
this package's basis (P&T A2.1, A2.3; spline/basis.py). The paper gives the knot vector,
not the control points: ours are a zigzag of the same count. What the figure shows does
not depend on them: the curve starts and ends at P1 and P9 tangent to the control
polygon (open knot vector), passes through P6 (the knot 0.75 of multiplicity p = 3 makes
the basis C^0 there and N_6(0.75) = 1), and the basis functions are non-negative and sum
to one (tests/test_spline_basis.py checks these on this knot vector:
test_interpolation_at_triple_knot_paper_fig4 and the continuity test beside it).

Fig. 6 (paper Sec. 5): the bundled benchmark (examples/free_fall/case_cg.toml, 3 s, run
here in memory on the native engine, about 20 s on two cores) at nine instants: the
fall, the first impact at 0.75 s, the lower beam's first amplitude near 1.67 s, the
later collisions.

    python examples/studies/figures_4_6.py [--out examples/studies/figures]
"""

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import beamcontact as bc
from beamcontact.plot import plot_snapshots
from beamcontact.spline.basis import nurbs_basis_derivatives
from beamcontact.spline.curve import NurbsCurve

HERE = Path(__file__).resolve().parent

# Fig. 4's knot vector (paper, caption of Fig. 4) and our control points
FIG4_KNOTS = np.array([0, 0, 0, 0, 0.25, 0.5, 0.75, 0.75, 0.75, 1, 1, 1, 1], dtype=float)
FIG4_POINTS = np.array([[0.0, 0.0], [0.6, 1.4], [1.6, 1.6], [2.2, 0.4], [3.0, 0.2],
                        [3.6, 1.2], [4.4, 1.8], [5.2, 1.0], [5.6, 0.0]])
FIG4_DEGREE = 3

# the instants of the snapshots of Fig. 6 [s]: saved states (every 0.02 s), 0.76 s just
# after the first impact, 1.66 s near the first amplitude of the lower beam
FIG6_TIMES = (0.0, 0.5, 0.76, 1.0, 1.3, 1.66, 2.0, 2.5, 3.0)


def figure_4(path: Path) -> None:
    """The curve with its control polygon (top) and the nine basis functions (bottom)."""
    curve = NurbsCurve(FIG4_DEGREE, FIG4_KNOTS, FIG4_POINTS, np.ones(len(FIG4_POINTS)))
    u = np.linspace(0.0, 1.0, 801)
    xy = curve.evaluate(u)[0]
    first, ders = nurbs_basis_derivatives(FIG4_KNOTS, FIG4_DEGREE, curve.weights, u)
    basis = np.zeros((len(u), len(FIG4_POINTS)))
    for k in range(FIG4_DEGREE + 1):
        basis[np.arange(len(u)), first + k] = ders[:, 0, k]
    fig = Figure(figsize=(7.0, 6.4))
    top, bottom = fig.subplots(2, 1, gridspec_kw={"height_ratios": [1.2, 1.0]})
    top.plot(FIG4_POINTS[:, 0], FIG4_POINTS[:, 1], "o--", color="0.55", lw=1, ms=5,
             label="control polygon")
    top.plot(xy[:, 0], xy[:, 1], color="C0", lw=2, label="B-spline curve")
    for i, (x, y) in enumerate(FIG4_POINTS, start=1):
        top.annotate(f"$P_{{{i}}}$", (x, y), textcoords="offset points", xytext=(4, 6),
                     fontsize=9)
    knots_xy = curve.evaluate(np.unique(FIG4_KNOTS))[0]
    top.plot(knots_xy[:, 0], knots_xy[:, 1], "s", color="C3", ms=4, label="knots")
    top.set_aspect("equal")
    top.set_ylim(-0.3, 2.4)
    top.set_title("cubic B-spline, knot vector {0, 0, 0, 0, 0.25, 0.5, 0.75, 0.75, 0.75, "
                  "1, 1, 1, 1}", fontsize=9)
    top.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    for i in range(len(FIG4_POINTS)):
        bottom.plot(u, basis[:, i], lw=1.5, label=f"$N_{{{i + 1},3}}$")
    for k in np.unique(FIG4_KNOTS):
        bottom.axvline(k, color="0.85", lw=0.8, zorder=0)
    bottom.set_xlabel(r"$\xi$")
    bottom.set_ylabel("basis functions")
    bottom.legend(fontsize=7, ncol=1, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def figure_6(path: Path) -> dict:
    """Snapshots of the bundled run at FIG6_TIMES (the saved states nearest them, every
    0.02 s); returns the run's summary."""
    case = bc.load_case(bc.examples.path("free_fall") / "case_cg.toml")
    result = bc.simulate(case)
    states = result.states
    frames = []
    for t in FIG6_TIMES:
        k = int(np.argmin(np.abs(states.parameter - t)))
        frames.append((float(states.parameter[k]),
                       [axis[k] for axis in states.centrelines.values()]))
    plot_snapshots(frames, [b.section.radius for b in case.beams], path,
                   title="Fig. 6: the bundled benchmark (coarse-grained contact)")
    return result.summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "figures")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    figure_4(args.out / "fig4_bspline.png")
    print(f"wrote {args.out / 'fig4_bspline.png'}")
    summary = figure_6(args.out / "fig6_snapshots.png")
    print(f"wrote {args.out / 'fig6_snapshots.png'} ({summary['steps']} steps, "
          f"{summary['wall_time_s']:.1f} s)")


if __name__ == "__main__":
    main()
