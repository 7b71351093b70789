"""Diagnostic: the peer drop in beamcontact with the peers' axial laws swapped in.

Runs compare.py's drop case (coarse-grained contact by default, HHT alpha = 0, the same
discretisation and contact parameters) with beamcontact's own fibre law (St. Venant-
Kirchhoff in the Green-Lagrange strain, ``svk``) and with the fibre law replaced at run
time by the ANCF cable's engineering-strain law (``engineering``, Exudyn) or by
PyElastica's axial law n = EA (e - 1)/e (``pyelastica``); see
vibration_beamcontact.patch_strain_law (nothing under src/ is changed). Each law runs in
its own process (the patch must precede JAX's tracing). Writes
results/drop_bc-<law>.csv (t, A_uy, E_total) and prints the largest |difference| of A_uy from
each peer over 0..0.9, 1.0, 1.1, 1.2 s and the signed differences at a few times.

Usage (from the repository root; about 45 s per law, one after the other):

    python benchmarks/peers/drop_strain_law.py [--laws svk engineering pyelastica]
    python benchmarks/peers/drop_strain_law.py --table-only   # only the table
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import _common as common  # noqa: E402


def run_one(law: str, model: str, out: Path) -> None:
    import beamcontact

    beamcontact.enable_x64()
    from vibration_beamcontact import patch_strain_law

    patch_strain_law(law)
    from compare import drop_case

    from beamcontact.io.case import parse_case
    from beamcontact.io.results import read_history
    from beamcontact.runner import run_case

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_case(parse_case(drop_case(model)), "", Path(tmp))
        h = read_history(Path(tmp) / "history.csv")
    print(f"beamcontact drop ({model}, fibre law {law}): {summary['status']}, "
          f"{summary['steps']} steps, {time.perf_counter() - t0:.1f} s; energy "
          f"{summary['energy']}", flush=True)
    common.write_csv(out, ["t", "A_uy", "E_total"],
                     zip(h["t"], h["A_uy"], h["E_total"], strict=True), [".9g", ".10g", ".10g"])


def table(files: dict[str, Path]) -> None:
    curves = {}
    for k, p in files.items():
        d = np.genfromtxt(p, delimiter=",", names=True)
        curves[k] = (d["t"], d["A_uy"])
    grid = np.arange(0.0, 1.2 + 1e-12, 2.5e-4)
    on = {k: np.interp(grid, t, a) for k, (t, a) in curves.items()}
    windows, at = (0.9, 1.0, 1.1, 1.2), (0.95, 1.05, 1.1, 1.15, 1.18, 1.2)
    print("max |difference| of A_uy [cm] over 0..T, signed difference [cm] at t")
    print("| pair | " + " | ".join(f"0..{w:g}" for w in windows) + " | "
          + " | ".join(f"d({x:g})" for x in at) + " |")
    print("|---" * (len(windows) + len(at) + 1) + "|")
    names = list(on)
    for i, x in enumerate(names):
        for y in names[i + 1:]:
            d = on[x] - on[y]
            cells = [f"{100 * np.abs(d[grid <= w + 1e-9]).max():.2f}" for w in windows]
            cells += [f"{100 * d[np.argmin(np.abs(grid - s))]:+.2f}" for s in at]
            print(f"| {x} - {y} | " + " | ".join(cells) + " |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--laws", nargs="+", default=["svk", "engineering", "pyelastica"],
                    choices=["svk", "engineering", "pyelastica"],
                    help="fibre laws to run (svk: beamcontact's own)")
    ap.add_argument("--model", default="cg", choices=["cg", "ipip", "ipip-points"],
                    help="beamcontact's contact model (ipip: the paper's pairing rule, "
                    "ipip-points: contact.pairing = \"points\")")
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)  # worker: law
    ap.add_argument("--out", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--table-only", action="store_true", help="only compare existing CSVs")
    a = ap.parse_args(argv)
    if a.one is not None:
        run_one(a.one, a.model, a.out)
        return
    files = {"PyElastica": HERE / "results" / "pyelastica.csv",
             "Exudyn": HERE / "results" / "exudyn.csv"}
    for law in a.laws:
        suffix = "" if a.model == "cg" else f"-{a.model}"
        out = HERE / "results" / f"drop_bc-{law}{suffix}.csv"
        if not a.table_only:
            subprocess.run([sys.executable, __file__, "--one", law, "--model", a.model,
                            "--out", str(out)], check=True)
        files[f"bc {a.model} {law}"] = out
    table(files)


if __name__ == "__main__":
    main()
