#!/usr/bin/env python
"""The paper's Fig. 7 complete: point A of the bundled benchmark for every model, overlaid,
and the table of its events (issue 24, item 3).

Each curve is a ``beamcontact run`` output folder (history.csv and summary.json) or a CSV
with columns ``t, A_uy`` and, where the code gives it, ``min_gap`` (drop_solid.py; the
PyElastica and Exudyn scripts run with ``PEER_PROBLEM=bundled``). Every curve is measured
the same way:

* first impact: the first row whose smallest gap is below 1 mm (beamcontact's own
  criterion, 1 % of the radius, is the same 1 mm); for a code without a gap column, the
  first row where |A_uy| exceeds 1 mm (the lower beam carries no gravity, so A rests until
  the impact; this lags the contact by the few ms the bending wave needs);
* first amplitude of A and its time: :func:`beamcontact.summary.first_excursion_extreme`
  from the first impact on, the definition of summary.json;
* second collision: beamcontact's second contact episode (summary.json ``impacts``), the
  solid's (drop_solid.py's JSON, ``second_collision_t``); none for codes that do not write
  their contacts;
* where a curve ends: the solid's ``valid_until`` (its own overlap check), and for a CSV
  with ``E_total`` and no such check (PyElastica, Exudyn) where its energy first leaves
  +-10 % of its start: what comes after is not a result. beamcontact's runs end where they
  end (their energy account is in summary.json).

    python benchmarks/peers/fig7.py --curve "CG=RUN_DIR" --curve "solid=results/solid.csv" \\
        ... --out fig7.png

prints the table (Markdown) and writes the figure.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from beamcontact.io.results import read_history
from beamcontact.summary import first_excursion_extreme

GAP_CONTACT = 1e-3  # [m]
A_MOVES = 1e-3  # [m]
ENERGY_DRIFT = 0.1  # a peer's curve ends where its E_total leaves +-10 % of its start


def read_table(path: Path) -> dict[str, np.ndarray]:
    """A peer's or drop_solid.py's CSV as columns; drop_solid.py's comment lines (its
    command, valid_until) are not the header."""
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    h = np.genfromtxt(lines, delimiter=",", names=True)
    return {name: h[name] for name in h.dtype.names}


def load(path: Path) -> dict:
    """t, A_uy, the first impact and the second collision of one curve."""
    cut = None
    if path.is_dir():
        h = read_history(path / "history.csv")
        s = json.loads((path / "summary.json").read_text())
        impacts = s.get("impacts") or []
        t, uy, gap = h["t"], h["A_uy"], h["min_gap"]
        second = impacts[1]["start"] if len(impacts) > 1 else None
    else:
        h = read_table(path)
        t, uy = h["t"], h["A_uy"]
        gap = h.get("min_gap")
        # drop_solid.py writes OUT.json beside OUT (OUT.csv.json; results/solid.json)
        sidecars = [p for p in (Path(str(path) + ".json"), path.with_suffix(".json"))
                    if p.is_file()]
        side = json.loads(sidecars[0].read_text()) if sidecars else {}
        second = side.get("second_collision_t")
        until = side.get("valid_until")
        if until is None and "E_total" in h:
            drift = np.abs(h["E_total"] - h["E_total"][0]) > ENERGY_DRIFT * h["E_total"][0]
            until = float(t[np.argmax(drift)]) if drift.any() else None
        if until is not None and until < t[-1]:
            keep = t <= until
            t, uy, gap = t[keep], uy[keep], None if gap is None else gap[keep]
            cut = until
    if gap is not None:
        hit = np.nonzero(gap <= GAP_CONTACT)[0]
        how = "gap"
    else:
        hit = np.nonzero(np.abs(uy) > A_MOVES)[0]
        how = "A moves"
    first = int(hit[0]) if hit.size else None
    amp = first_excursion_extreme(t[first:], uy[first:]) if first is not None else None
    return {"t": t, "uy": uy, "impact": None if first is None else float(t[first]),
            "how": how, "amplitude": amp, "second": second, "cut": cut,
            "beamcontact": path.is_dir()}


def table(curves: list[tuple[str, dict]]) -> str:
    lines = ["| model | first impact [s] | second collision [s] | first amplitude of A [m] | "
             "at [s] | curve ends [s] |", "|---|---|---|---|---|---|"]
    for label, c in curves:
        amp = c["amplitude"] or {}
        impact = "-" if c["impact"] is None else f"{c['impact']:.4f}" + (
            " (A moves)" if c["how"] == "A moves" else "")
        second = "-" if c["second"] is None else f"{c['second']:.3f}"
        value = "-" if not amp else f"{amp['uy']:.4f}" + ("" if amp["ended"] else " (not ended)")
        when = "-" if not amp else f"{amp['t']:.3f}"
        ends = "-" if c["cut"] is None else f"{c['cut']:.3f}"
        lines.append(f"| {label} | {impact} | {second} | {value} | {when} | {ends} |")
    return "\n".join(lines)


def figure(curves: list[tuple[str, dict]], out: Path, title: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    for label, c in curves:  # beamcontact's runs solid, the other codes dashed
        ax.plot(c["t"], c["uy"], lw=1.4 if c["beamcontact"] else 1.2, label=label,
                ls="-" if c["beamcontact"] else "--")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vertical displacement of A [m]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(out, dpi=150)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--curve", action="append", required=True, metavar="LABEL=PATH",
                    help="a beamcontact run folder or a CSV with t, A_uy (repeat)")
    ap.add_argument("--out", type=Path, default=Path("fig7.png"), help="the figure")
    ap.add_argument("--title", default="Fig. 7: point A, the beam models, the solid and "
                    "the peer codes")
    a = ap.parse_args(argv)
    curves = []
    for spec in a.curve:
        label, sep, path = spec.partition("=")
        if not sep:
            ap.error(f"--curve {spec!r}: LABEL=PATH")
        curves.append((label, load(Path(path))))
    print(table(curves))
    figure(curves, a.out, a.title)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
