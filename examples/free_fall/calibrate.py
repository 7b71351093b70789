"""Calibrate Young's modulus of the free-fall benchmark (paper Fig. 5 is not available).

Finds E (the same for both beams) such that the first amplitude of point A after the first
impact is -2.25 m with the coarse-grained model (paper Sec. 5), by the secant method on
log E. Prints one row per trial; one to two minutes per trial on 2 cores.

    python examples/free_fall/calibrate.py [--target -2.25] [--e0 1e6 --e1 0.95e6]
"""

import argparse
import math
import tempfile
import tomllib
from pathlib import Path

import beamcontact

beamcontact.enable_x64()

from beamcontact.io.case import parse_case  # noqa: E402
from beamcontact.runner import run_case  # noqa: E402

HERE = Path(__file__).resolve().parent


def first_amplitude(E: float) -> float:
    raw = tomllib.loads((HERE / "case_cg.toml").read_text())
    raw["analysis"]["t_end"] = 2.5
    for b in raw["beams"]:
        b["material"]["E"] = E
    with tempfile.TemporaryDirectory() as tmp:
        s = run_case(parse_case(raw), "", Path(tmp) / "out")
    if "A" not in s["first_amplitude"]:
        raise SystemExit(f"E = {E:.4g} Pa: no first amplitude of A before t = 2.5 s")
    return s["first_amplitude"]["A"]["uy"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--target", type=float, default=-2.25)
    ap.add_argument("--e0", type=float, default=1.0e6)
    ap.add_argument("--e1", type=float, default=0.95e6)
    ap.add_argument("--tol", type=float, default=0.01)
    args = ap.parse_args()
    x0, x1 = math.log(args.e0), math.log(args.e1)
    f0 = first_amplitude(args.e0) - args.target
    print(f"E = {args.e0:.6g} Pa: first amplitude of A {f0 + args.target:.4f} m", flush=True)
    for _ in range(8):
        f1 = first_amplitude(math.exp(x1)) - args.target
        print(f"E = {math.exp(x1):.6g} Pa: first amplitude of A {f1 + args.target:.4f} m",
              flush=True)
        if abs(f1) < args.tol:
            break
        x0, x1, f0 = x1, x1 - f1 * (x1 - x0) / (f1 - f0), f1
    print(f"calibrated E = {math.exp(x1):.4g} Pa")


if __name__ == "__main__":
    main()
