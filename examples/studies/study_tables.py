"""The tables of examples/studies/README.md from the study folders of run_all.sh.

For every run: the first impact, the second collision (the start of the second contact
episode, summary.json's ``impacts``), the first amplitude of point A and when, the
smallest gap, the energy account (E_total at the start and the end, what HHT dissipated,
what the contact set's changes added: docs/theory.md) and the cost. For Fig. 10 also the
coarse-grained potential (eq. 9) and its force at the cutoff, the only place where the
cutoff acts, next to the spread that a change of one unit in the last place of one input
makes (the ``roundoff`` study).

    python examples/studies/study_tables.py STUDIES_DIR   # prints; writes STUDIES_DIR/tables.md
"""

import argparse
import csv
import json
import math
import tomllib
from pathlib import Path

STUDIES = (
    ("models", "Fig. 7: the two beam models (adaptive steps)"),
    ("penalty", "Fig. 8: IPIP penalty eps [N/m], adaptive steps"),
    ("penalty_fixed", "Fig. 8 at the paper's fixed step (dt = 1 ms, error and energy "
                      "control off)"),
    ("alpha", "Fig. 9: HHT alpha, adaptive steps"),
    ("alpha_fixed", "Fig. 9 at the paper's fixed step (dt = 1 ms, error and energy control "
                    "off)"),
    ("alpha_points", "Fig. 9 with IPIP \"points\" (no energy jumps at set changes), "
                     "adaptive steps"),
    ("alpha_points_fixed", "Fig. 9 with IPIP \"points\" at the paper's fixed step"),
    ("cutoff", "Fig. 10: coarse-grained cutoff [m], adaptive steps"),
    ("roundoff", "Fig. 10's yardstick: the cutoff-0.3 case with the upper beam's density "
                 "moved by -1 to +3 units in the last place (1.1e-16 of it each)"),
    ("roundoff_ipip", "Figs. 8 and 9's yardstick: the IPIP case (eps = 1e6, alpha = -0.33) "
                      "with the upper beam's density moved by -1 to +3 units in the last "
                      "place"),
    ("roundoff_bundled", "Fig. 7's yardstick: the bundled benchmark (CG, 60 segments per "
                         "element) with the upper beam's density moved by -1 to +3 units in "
                         "the last place"),
)

HEADER = ("| run | first impact [s] | second collision [s] | first amplitude of A [m] | "
          "at [s] | smallest gap [m] | E_total start -> end [J] | dissipated [J] | "
          "set changes [J] | steps | rejected | wall [s] |")


def _runs(folder: Path) -> list[tuple[str, Path]]:
    """(label, run folder) of a sweep (sweep.csv order) or of the two model runs."""
    table = folder / "sweep.csv"
    if table.is_file():
        with open(table, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        fixed = ("solver.error_tol", "solver.energy_tol", "contact.pairing")
        return [(", ".join(f"{k.split('.')[-1]} = {v}" for k, v in r.items()
                           if "." in k and k not in fixed), folder / r["run"]) for r in rows]
    return [(name, folder / name) for name in ("cg", "ipip") if (folder / name).is_dir()]


def _row(label: str, run: Path) -> str:
    if not (run / "summary.json").is_file():
        return f"| {label} | not run yet |"
    s = json.loads((run / "summary.json").read_text())
    if s.get("status") != "completed":
        return f"| {label} | {s.get('status')}: {s.get('message', '')} |"
    impacts = s.get("impacts") or []
    second = f"{impacts[1]['start']:.3f}" if len(impacts) > 1 else "-"
    amp = (s.get("first_amplitude") or {}).get("A", {})
    e = s["energy"]
    return (f"| {label} | {s['first_impact_time']:.3f} | {second} | "
            f"{amp.get('uy', math.nan):.4f} | {amp.get('t', math.nan):.3f} | {s['min_gap']:.2e} | "
            f"{e['E_total_initial']:.1f} -> {e['E_total_final']:.1f} | "
            f"{e['E_dissipated']:.1f} | {e['E_set_change']:.1f} | {s['steps']} | "
            f"{s['cutbacks']} | {s['wall_time_s']:.0f} |")


def departures(runs: list[tuple[str, Path]], reference: Path) -> list[str]:
    """Rows: when each run's A_uy first departs from the reference run's by 1 um, 1 mm and
    1 cm (both interpolated on a 0.1 ms grid), and its first amplitude's distance from the
    reference's."""
    import numpy as np

    from beamcontact.io.results import read_history

    def load(run):
        h = read_history(run / "history.csv")
        amp = json.loads((run / "summary.json").read_text())["first_amplitude"]["A"]["uy"]
        return h["t"], h["A_uy"], amp

    t_ref, a_ref, amp_ref = load(reference)
    grid = np.arange(0.0, t_ref[-1], 1e-4)
    rows = []
    for label, run in runs:
        if run == reference or not (run / "summary.json").is_file():
            continue
        t, a, amp = load(run)
        d = np.abs(np.interp(grid, t, a) - np.interp(grid, t_ref, a_ref))
        when = [f"{grid[np.argmax(d > lim)]:.3f}" if np.any(d > lim) else "-"
                for lim in (1e-6, 1e-3, 1e-2)]
        rows.append(f"| {reference.parent.name} | {label} | {' | '.join(when)} | "
                    f"{1e3 * (amp - amp_ref):+.1f} |")
    return rows


def cutoff_potential(case: Path, cutoff: float) -> tuple[float, float, float]:
    """(q, Phi, -dPhi/dq) of eq. (9) per unit length of both axes at the gap q = cutoff -
    R1 - R2 of the centre-line distance ``cutoff``, for the case's k, m, densities and
    radii."""
    from beamcontact import enable_x64

    enable_x64()
    from beamcontact.contact.laws.coarse_grained import cg_constant

    c = tomllib.loads(case.read_text())
    contact = c["contact"]
    r1, r2 = (b["section"]["radius"] for b in c["beams"][:2])
    m = contact["exponent"]
    beta1, beta2 = contact["densities"]
    q = cutoff - r1 - r2
    phi = contact["k"] * beta1 * beta2 * float(cg_constant(m, r1, r2)) * q ** (3.5 - m)
    return q, phi, (m - 3.5) * phi / q


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("studies", type=Path, help="the OUT_DIR of run_all.sh")
    root = ap.parse_args().studies
    lines = []
    for name, title in STUDIES:
        folder = root / name
        runs = _runs(folder) if folder.is_dir() else []
        if not runs:
            continue
        lines += ["", f"{title} (`{name}/`)", "", HEADER, "|" + "---|" * 12]
        lines += [_row(label, run) for label, run in runs]
    cutoff_runs = _runs(root / "cutoff") if (root / "cutoff").is_dir() else []
    if cutoff_runs:
        case = cutoff_runs[0][1] / "case.toml"
        c = tomllib.loads(case.read_text())
        upper = c["beams"][1]
        weight = (upper["material"]["density"] * math.pi * upper["section"]["radius"] ** 2
                  * math.hypot(*c["analysis"]["gravity"]))
        lines += ["", "The coarse-grained potential at the cutoff (eq. 9, per unit length of "
                  f"both axes; the upper beam's weight is {weight:.0f} N/m):", "",
                  "| cutoff [m] | gap there [m] | Phi [J/m^2] | force -dPhi/dq [N/m^2] |",
                  "|---|---|---|---|"]
        for _label, run in cutoff_runs:
            cutoff = tomllib.loads((run / "case.toml").read_text())["contact"]["cutoff"]
            q, phi, force = cutoff_potential(case, cutoff)
            lines.append(f"| {cutoff:g} | {q:.3g} | {phi:.2e} | {force:.2e} |")
    pairs = (("cutoff", "cutoff=0.3"), ("roundoff", "density=1000"),
             ("roundoff_ipip", "density=1000"), ("roundoff_bundled", "density=1000"))
    rows = []
    for name, ref in pairs:
        folder = root / name
        if (folder / ref / "summary.json").is_file():
            rows += departures(_runs(folder), folder / ref)
    if rows:
        lines += ["", "Where point A of each run departs from the run with cutoff 0.3 (`cutoff/`) "
                  "or with the unperturbed density (`roundoff*/`), and how "
                  "far its first amplitude lies from that run's:", "",
                  "| study | run | 1 um at [s] | 1 mm at [s] | 1 cm at [s] | first amplitude "
                  "- reference's [mm] |", "|---|---|---|---|---|---|"] + rows
    text = "\n".join(lines).lstrip("\n") + "\n"
    print(text)
    (root / "tables.md").write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
