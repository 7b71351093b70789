"""`beamcontact check` of large models (issue 23, item 7): the wall time of the whole
command, which discretises every beam (arc-length parameters of the mesh, knot insertion,
the basis at every Gauss and contact point, the arc-length weights of the contact
segments) and runs the initial-overlap check.

Two cases, written to a temporary folder:

* 20 parallel pinned beams of 10 000 cubic elements each, 0.5 m apart (coarse-grained
  contact, 20 segments per element: 4 million contact segments);
* the bundled benchmark (examples/free_fall/case_cg.toml) with 10 000 elements in each
  of its two beams (60 segments per element: 1.2 million contact segments).

    python benchmarks/check_large.py [--repeat N]

Prints a table of the best and the median wall time of N runs (default 3) of each.
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import tomli_w

REPO = Path(__file__).resolve().parents[1]


def twenty_beams() -> dict:
    beams = [{"name": f"b{i}", "line": {"start": [0.0, 0.5 * i], "end": [10.0, 0.5 * i]},
              "degree": 3, "elements": 10_000,
              "section": {"shape": "circle", "radius": 0.1},
              "material": {"E": 1e7, "density": 1000.0},
              "supports": [{"at": "start", "type": "pinned"},
                           {"at": "end", "type": "pinned"}]} for i in range(20)]
    return {"title": "20 beams of 10 000 elements",
            "analysis": {"kind": "dynamic", "t_end": 0.01, "dt": 1e-3,
                         "gravity": [0.0, -9.81]},
            "beams": beams, "contact": {"model": "cg"}}


def bundled_refined() -> dict:
    case = tomllib.loads((REPO / "examples" / "free_fall" / "case_cg.toml").read_text())
    for beam in case["beams"]:
        beam["elements"] = 10_000
    return case


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    cases = {"20 beams x 10 000 elements, 20 segments": twenty_beams(),
             "bundled case, 2 x 10 000 elements, 60 segments": bundled_refined()}
    print("| case | best [s] | median [s] | runs |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for name, case in cases.items():
            path = Path(folder) / "case.toml"
            path.write_bytes(tomli_w.dumps(case).encode())
            times = []
            for _ in range(args.repeat):
                start = time.perf_counter()
                subprocess.run([sys.executable, "-m", "beamcontact.cli", "check", str(path)],
                               check=True, stdout=subprocess.DEVNULL)
                times.append(time.perf_counter() - start)
            print(f"| {name} | {min(times):.2f} | {statistics.median(times):.2f} | "
                  f"{len(times)} |")


if __name__ == "__main__":
    main()
