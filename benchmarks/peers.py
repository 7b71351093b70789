"""Wall time of beamcontact against the peer codes, side by side (the targets of issues 12
and 22).

Runs, each in its own process, one after the other on this machine:

* ``drop``: the peer drop of benchmarks/peers (4 m beam onto a pinned 10 m beam,
  E = 1e7 Pa), 2 s simulated: PyElastica at dt = 1e-4 s and at its largest stable step
  (the first of ``--pyelastica-dt-large`` times 1, 0.8, 0.8^2, ... that runs),
  Exudyn at dt = 1e-3 s, and ``beamcontact run`` (every default output written) for each
  of ``--models``, with the falling beam as discretised and without the outlier modes
  of its free ends (``--outliers``: ``beams.remove_outliers``);
* ``stiff``: the same drop with E = 1e9 Pa, 1 s simulated (through the first impact):
  PyElastica at dt = 1e-5 s and ``beamcontact run``;
* ``bundled``: ``beamcontact run`` of the bundled benchmark (3 s, every output), with the
  compilation cache cold (a fresh cache folder), then warm (once the cold run's helper,
  which goes on compiling the time loop after a short run, has filled it);
* ``scaling``: the cost per step of one pinned beam vibrating without contact with 100
  and with 800 quartic elements (500 fixed steps: ``error_tol = 0``);
* ``solid`` (not by default): the paper's Fig. 7 complete, the bundled benchmark with both
  beam models, the continuum model in Kratos (peers/drop_solid.py) and PyElastica and
  Exudyn on the same problem, overlaid (peers/fig7.py), every output in ``--solid-out``;
  about 25 minutes (the hard-contact solid 15 of them);
* ``solid-studies`` (not by default): the continuum model's studies (penalty, numerical
  damping, step, mesh), about 3 hours on one core.

Wall times: every code's *whole process* (start of Python to exit: for beamcontact the
case check, the compiled kernels from the warm cache, the step loop and every output
file: plots, animation, ParaView series) and its *step loop* (the peers' as their scripts
print it: numba or C++ compiled, the energy sampling of PyElastica excluded;
beamcontact's ``solve_time_s`` of summary.json, which includes writing history.csv,
results.h5 and the VTU series as the steps come), and beside it the *steps alone*: the
step loop without its output (beamcontact's ``solve_time_s - writing_time_s``; a peer's
loop, which writes nothing), the like-for-like comparison of the stepping itself.
Before the timed runs beamcontact runs each case once, untimed, to fill the compilation
cache (the targets are "warm caches"), and PyElastica runs 0.01 s once, untimed, to fill
its numba cache.
Prints one table per case with both times, both as ratios to the first code of the table
(PyElastica at its reference step) and the largest |difference| of the midspan
deflection A_uy from it (for the peer drop also up to 1.2 s: its later contacts depend
on the phase of the beams' vibration, and the histories of any two runs part there),
and for each run of beamcontact what an empty two-thread parallel loop costs more than
a one-thread one just before and just after it (peers/fork_join.py: about 0.2 us or 1.4
us on the machine of benchmarks/README.md, whose two vCPUs share a cache in some
minutes and not in others; the two-thread loops are fast or slow accordingly).

    pip install ".[peers]"                      # PyElastica and Exudyn
    python benchmarks/peers.py [--cases drop stiff bundled scaling] [--repeat 3]
                               [--engines native jax] [--outliers keep remove]
    python benchmarks/peers.py --cases solid solid-studies [--solid-out DIR]
                               [--kratos-python PYTHON]

A full run takes 15-25 minutes here (the bundled benchmark alone about 6 minutes per run
today). Numbers and machine: benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import functools
import importlib.util
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
from _shared import pinned_beam_case

HERE = Path(__file__).resolve().parent
PEERS = HERE / "peers"
REPO = HERE.parent
sys.path.insert(0, str(PEERS))


def _run(cmd: list[str], env: dict | None = None) -> tuple[float, str]:
    """Run cmd; (wall seconds of the whole process, stdout). Fails loudly."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **(env or {})})
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return wall, proc.stdout


def _loop_time(stdout: str) -> float:
    """The step-loop time a peer script prints."""
    m = re.search(r"wall time: step loop ([0-9.]+) s", stdout) or \
        re.search(r"wall time \(SolveDynamic[^)]*\): ([0-9.]+) s", stdout)
    if m is None:
        raise RuntimeError(f"no wall time in:\n{stdout}")
    return float(m.group(1))


@functools.cache
def warm_up_pyelastica(tmp: Path) -> None:
    """Run PyElastica once, untimed, for 0.01 s: it compiles its numba kernels at their
    first use and keeps them on disk, so that a first timed run in a fresh environment
    would time its compilation (36.7 s against 9.4 s of process in session 21). The
    timed runs of both codes then start with warm caches (beamcontact's own warm-up run
    is in :func:`case_drop`). Once per folder (``functools.cache``)."""
    pyelastica(1e-4, 0.01, tmp / "pe_warm_up.csv", 1.0e7)


def pyelastica(dt: float, t_end: float, out: Path, E: float, max_rows: int | None = None) -> dict:
    """PyElastica's drop (peers/drop_pyelastica.py); ``max_rows`` the rows of its CSV at
    most (its own default: 2000)."""
    rows = [] if max_rows is None else ["--max-rows", str(max_rows)]
    wall, stdout = _run([sys.executable, str(PEERS / "drop_pyelastica.py"), "--dt", f"{dt:g}",
                         "--t-end", f"{t_end:g}", "--out", str(out), *rows],
                        {"PEER_E": f"{E:g}"})
    return {"code": f"PyElastica dt={dt:g}", "time": _loop_time(stdout), "process": wall,
            "csv": out}


def largest_stable(dt: float, t_end: float, out: Path, E: float) -> dict:
    """PyElastica at the largest step of dt, 0.8 dt, 0.8^2 dt, ... that stays stable (its
    script stops with an error when the state explodes)."""
    while True:
        try:
            return pyelastica(dt, t_end, out, E)
        except RuntimeError as exc:
            if "unstable" not in str(exc) or dt < 1e-5:
                raise
            print(f"PyElastica unstable at dt = {dt:.3g} s; trying {0.8 * dt:.3g} s",
                  flush=True)
            dt *= 0.8


def exudyn(dt: float, t_end: float, out: Path, E: float) -> dict:
    wall, stdout = _run([sys.executable, str(PEERS / "drop_exudyn.py"), "--dt", f"{dt:g}",
                         "--t-end", f"{t_end:g}", "--no-energy", "--out", str(out)],
                        {"PEER_E": f"{E:g}"})
    return {"code": f"Exudyn dt={dt:g}", "time": _loop_time(stdout), "process": wall,
            "csv": out}


def _fork_join_us() -> float:
    """What an empty two-thread parallel loop costs more than a one-thread one on this
    machine now [us] (peers/fork_join.py, in a process of its own): about 0.2 us when
    the two vCPUs share a cache, about 1.4 us when not (benchmarks/README.md, session
    30); beamcontact's two-thread loops follow it."""
    _, out = _run([sys.executable, str(PEERS / "fork_join.py")])
    return float(out.strip())


def beamcontact_run(case: Path | None, out: Path, label: str, env: dict | None = None) -> dict:
    """``beamcontact run`` as a user types it; the whole process is timed, and the
    two-thread cost of :func:`_fork_join_us` measured before and after it."""
    cmd = [sys.executable, "-m", "beamcontact.cli", "run"] + ([str(case)] if case else []) \
        + ["--out", str(out), "--quiet"]
    before = _fork_join_us()
    wall, _ = _run(cmd, env)
    after = _fork_join_us()
    summary = json.loads((out / "summary.json").read_text())
    return {"code": label, "time": wall, "process": wall, "csv": out / "history.csv",
            "loop": summary["solve_time_s"],
            "stepping": summary["solve_time_s"] - summary["writing_time_s"],
            "steps": summary["steps"],
            "iterations": summary["newton_iterations"],
            "compile": summary.get("compile_time_s", 0.0),
            "fork_join": f"{before:.2f} / {after:.2f}"}


def _drop_case_file(model: str, t_end: float, E: float, folder: Path,
                    engine: str = "auto", outliers: str = "keep") -> Path:
    import tomli_w
    from compare import drop_case

    case = drop_case(model, t_end=t_end, E=E)
    case["output"]["vtk_interval"] = t_end / 100  # the default cadence
    case.setdefault("solver", {})["engine"] = engine
    # the falling beam's free ends without their outlier modes (beams.remove_outliers)
    case["beams"][1]["remove_outliers"] = outliers == "remove"
    path = folder / f"drop_{model}_E{E:g}_{engine}_{outliers}.toml"
    path.write_text(tomli_w.dumps(case))
    return path


def _deviations(ref: Path, other: Path, ends: list[float]) -> list[float]:
    """Largest |A_uy difference| [m] between two result CSVs from t = 0 to each of
    ``ends`` (on a common grid of each window)."""
    d_ref, d_other = (np.genfromtxt(p, delimiter=",", names=True) for p in (ref, other))
    out = []
    for end in ends:
        grid = np.linspace(0.0, end, 4001)
        out.append(float(np.max(np.abs(np.interp(grid, d_ref["t"], d_ref["A_uy"])
                                       - np.interp(grid, d_other["t"], d_other["A_uy"])))))
    return out


# the peer drop's histories part after its second contact episode (about 1.25 s) by
# 6-16 cm under any perturbation, a 1 % change of the step tolerance included
# (benchmarks/README.md, session 25): the codes are compared up to this time too
COMPARABLE_UNTIL = 1.2


def _table(title: str, rows: list[dict], t_end: float | None,
           until: float | None = None) -> None:
    """One table: every code's whole process and step loop, and both as ratios to the
    first row's (the reference: how many times faster than it); the largest deviation of
    A_uy from the first row's over the run and, with ``until``, up to that time."""
    print(f"\n{title}")
    window = "" if until is None else f" | to {until:g} s [cm]"
    print("| code | process [s] | step loop [s] | steps alone [s] | first row / this: "
          "process | step loop | steps alone | steps | Newton it. | max dev. of A_uy from "
          f"the first [cm]{window} | two-thread fork-join before / after [us] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|" + ("---|" if until is not None else ""))
    ref = rows[0]
    for r in rows:
        ends = [] if t_end is None else [t_end] + ([] if until is None else [until])
        dev = " | ".join(f"{100 * d:.2f}" for d in _deviations(ref["csv"], r["csv"], ends))
        loop = r.get("loop", r["time"])
        stepping = r.get("stepping", loop)
        print(f"| {r['code']} | {r['process']:.2f} | {loop:.2f} | {stepping:.2f} | "
              f"{ref['process'] / r['process']:.2f} | "
              f"{ref.get('loop', ref['time']) / loop:.2f} | "
              f"{ref.get('stepping', ref.get('loop', ref['time'])) / stepping:.2f} | "
              f"{r.get('steps', '')} | {r.get('iterations', '')} | {dev} | "
              f"{r.get('fork_join', '')} |")


def case_drop(tmp: Path, args, E: float = 1.0e7, t_end: float = 2.0, stiff: bool = False):
    warm_up_pyelastica(tmp)
    rows = []
    rows.append(pyelastica(1e-5 if stiff else 1e-4, t_end, tmp / f"pe_{E:g}.csv", E))
    if not stiff:
        rows.append(largest_stable(args.pyelastica_dt_large, t_end, tmp / "pe_large.csv", E))
    if not stiff:
        if importlib.util.find_spec("exudyn") is None:
            print("Exudyn is not installed (pip install \".[peers]\"): its row is left out",
                  flush=True)
        else:
            rows.append(exudyn(1e-3, t_end, tmp / f"ex_{E:g}.csv", E))
    for engine in args.engines:
        for model in args.models:
            for outliers in args.outliers:
                case = _drop_case_file(model, t_end, E, tmp, engine, outliers)
                name = f"{model}_{E:g}_{engine}_{outliers}"
                beamcontact_run(case, tmp / f"warm_{name}", "warm-up")
                extra = ", no outliers" if outliers == "remove" else ""
                rows.append(beamcontact_run(case, tmp / f"bc_{name}",
                                            f"beamcontact {model} ({engine}{extra})"))
    _table(f"{'stiff drop (E = 1e9 Pa)' if stiff else 'peer drop (E = 1e7 Pa)'}, "
           f"{t_end:g} s simulated", rows, t_end,
           None if stiff or t_end <= COMPARABLE_UNTIL else COMPARABLE_UNTIL)


def _helper_done(cache: Path, limit_s: float = 600.0) -> None:
    """Wait until no helper compiles the native time loop into ``cache`` (its lock file
    gone): a cold run's helper finishes the loop after a short run has ended, and the
    warm run is meant to find the cache filled."""
    deadline = time.monotonic() + limit_s
    while any(cache.glob("numba/*/loop-*.lock")) and time.monotonic() < deadline:
        time.sleep(0.5)


def case_bundled(tmp: Path, args):
    rows = [beamcontact_run(None, tmp / "bundled_cold", "bundled, cold cache",
                            {"BEAMCONTACT_CACHE_DIR": str(tmp / "fresh_cache")})]
    _helper_done(tmp / "fresh_cache")
    rows.append(beamcontact_run(None, tmp / "bundled_warm", "bundled, warm cache",
                                {"BEAMCONTACT_CACHE_DIR": str(tmp / "fresh_cache")}))
    _table("bundled benchmark, 3 s simulated (the cold run compiles "
           f"{rows[0]['compile']:.1f} s)", rows, 3.0)


def case_scaling(tmp: Path, args):
    import tomli_w

    rows = []
    for n in (100, 800):
        case = pinned_beam_case(n)
        # 500 steps, and a ParaView snapshot only at the end: the default cadence would
        # write one every step here (t_end / 100 = dt), and the cost per step measured
        # would be that of the VTU writer
        case["analysis"]["t_end"] = 0.05
        case.update(solver={"error_tol": 0.0},
                    output={"points": [{"name": "A", "beam": "beam", "at": 0.5}],
                            "vtk_interval": 0.05})
        path = tmp / f"scaling_{n}.toml"
        path.write_text(tomli_w.dumps(case))
        beamcontact_run(path, tmp / f"warm_s{n}", "warm-up")
        r = beamcontact_run(path, tmp / f"scaling_{n}", f"{n} elements")
        # ms per step after the first, whose time is the kernels' loading (compile_time_s)
        r["time"] = (r["loop"] - r["compile"]) / (r["steps"] - 1) * 1e3
        rows.append(r)
    print("\ncost per step, one beam without contact (fixed steps)")
    print("| elements | ms per step | Newton it. per step | ratio to 100 elements |")
    print("|---|---|---|---|")
    for r in rows:
        print(f"| {r['code']} | {r['time']:.3f} | {r['iterations'] / r['steps']:.2f} | "
              f"{r['time'] / rows[0]['time']:.1f} |")


def _kratos(args, out: Path, *options: str) -> float:
    """drop_solid.py (Kratos, one thread) into out (its CSV; out.json beside it); the wall
    seconds of the whole process."""
    wall, _ = _run([args.kratos_python, str(PEERS / "drop_solid.py"), "--out", str(out),
                    *options], {"OMP_NUM_THREADS": "1"})
    return wall


# the continuum model that converges with the mesh through the first amplitude (the mesh
# study below): Kratos' augmented Lagrangian ("hard" contact), Bossak -0.1, twice as fine
BOSSAK = ("--time-scheme", "bossak", "--alpha-m", "-0.1")
MESH2 = ("--nx-lower", "200", "--nx-upper", "60", "--ny", "8")
MESH3 = ("--nx-lower", "300", "--nx-upper", "90", "--ny", "12")
SOLID_HARD = BOSSAK + MESH2 + ("--contact", "alm")


def case_solid(tmp: Path, args):
    """The paper's Fig. 7 complete (issue 24): the bundled benchmark with both beam models
    (the bundled 60 segments per element and the paper's 20 for CG; IPIP with the paper's
    "zones" and with "points"), the continuum model twice (drop_solid.py: its reference
    settings, the paper's linear penalty law on the reference mesh; and hard contact on the
    mesh twice as fine, SOLID_HARD, the converged one), the independent beam codes on the
    same problem (PEER_PROBLEM=bundled); the overlay and the table of
    benchmarks/peers/fig7.py; every output kept in --solid-out."""
    del tmp
    out = args.solid_out
    out.mkdir(parents=True, exist_ok=True)
    import tomli_w

    free_fall = REPO / "examples" / "free_fall"
    # IPIP once more with the conservative pairing: the paper's "zones" add energy when
    # the contact set changes, "points" do not
    points = tomllib.loads((free_fall / "case_ipip.toml").read_text())
    points["contact"]["pairing"] = "points"
    (out / "case_ipip_points.toml").write_text(tomli_w.dumps(points))
    curves, walls = [], []
    for label, name, case in (("CG, 60 segments (bundled)", "cg", free_fall / "case_cg.toml"),
                              ("CG, 20 segments (paper)", "cg_paper",
                               free_fall / "case_cg_paper.toml"),
                              ("IPIP zones (paper)", "ipip", free_fall / "case_ipip.toml"),
                              ("IPIP points", "ipip_points", out / "case_ipip_points.toml")):
        r = beamcontact_run(case, out / name, label)
        curves.append(f"{label}={out / name}")
        walls.append((label, r["process"]))
    walls.append(("solid, Kratos (one thread)", _kratos(args, out / "solid.csv")))
    curves.append(f"solid (Kratos)={out / 'solid.csv'}")
    # the converged continuum model: hard contact on the mesh twice as fine (the mesh
    # study, SOLID_STUDIES: the penalty fails there in the third contact)
    walls.append(("solid, hard contact, finer mesh (Kratos, one thread)",
                  _kratos(args, out / "solid_hard.csv", *SOLID_HARD)))
    curves.append(f"solid, hard contact (Kratos)={out / 'solid_hard.csv'}")
    bundled = {"PEER_PROBLEM": "bundled"}
    for label, script in (("PyElastica", "drop_pyelastica.py"), ("Exudyn", "drop_exudyn.py")):
        csv = out / f"{script.removeprefix('drop_').removesuffix('.py')}.csv"
        wall, _ = _run([sys.executable, str(PEERS / script), "--t-end", "3", "--out",
                        str(csv)], bundled)
        curves.append(f"{label}={csv}")
        walls.append((label, wall))
    import fig7

    fig7.main([arg for c in curves for arg in ("--curve", c)]
              + ["--out", str(out / "fig7.png")])
    print("\n| run | whole process [s] |\n|---|---|")
    for label, wall in walls:
        print(f"| {label} | {wall:.1f} |")


# The continuum model's studies (issue 24, item 2): the paper's Abaqus studies of Figs. 11
# and 12 on this model, and its mesh convergence; (name, drop_solid.py options)
SOLID_STUDIES = (
    ("reference", ()),
    ("penalty_3e7", ("--penalty", "3e7")),
    ("penalty_3e8", ("--penalty", "3e8")),
    ("penalty_1e9", ("--penalty", "1e9")),
    ("bossak_0.3", ("--time-scheme", "bossak", "--alpha-m", "-0.3")),
    ("dt_2.5e-4", ("--dt", "2.5e-4")),
    # the mesh study, with a little Bossak damping (undamped Newmark went unstable on the
    # finer meshes: the energy grew without bound in free flight after the first impact).
    # Kratos' mortar penalty is softer on a finer mesh (the same 1e8 let the bodies overlap
    # by 0.9 cm at the first impact on the reference mesh, 1.8 cm on the one twice as
    # fine), so each finer mesh runs with several penalties
    ("bossak_0.1_mesh1_1e8", BOSSAK),
    ("bossak_0.1_mesh1_3e8", BOSSAK + ("--penalty", "3e8")),
    ("bossak_0.1_mesh2_1e8", BOSSAK + MESH2),
    ("bossak_0.1_mesh2_2e8", BOSSAK + MESH2 + ("--penalty", "2e8")),
    ("bossak_0.1_mesh2_4e8", BOSSAK + MESH2 + ("--penalty", "4e8")),
    ("bossak_0.1_mesh3_3e8", BOSSAK + MESH3 + ("--penalty", "3e8", "--t-end", "1.8")),
    ("bossak_0.1_mesh3_5.2e8", BOSSAK + MESH3 + ("--penalty", "5.2e8", "--t-end", "1.8")),
    # the same meshes with the augmented Lagrangian ("hard" contact: no penalty to scale),
    # through the third contact where the penalty fails on the finer meshes
    ("bossak_0.1_mesh1_alm", BOSSAK + ("--contact", "alm", "--t-end", "1.8")),
    ("bossak_0.1_mesh2_alm", BOSSAK + MESH2 + ("--contact", "alm", "--t-end", "1.8")),
    ("bossak_0.1_mesh3_alm", BOSSAK + MESH3 + ("--contact", "alm", "--t-end", "1.8")),
)


def case_solid_studies(tmp: Path, args):
    """The continuum model's studies (SOLID_STUDIES), one Kratos run after the other (about
    3 hours on one core); a run whose JSON exists in --solid-out/studies is kept; the table
    of benchmarks/peers/README.md. A first amplitude that comes after the run's
    ``valid_until`` (its own overlap check) is marked: it is not a result."""
    import fig7

    del tmp
    out = args.solid_out / "studies"
    out.mkdir(parents=True, exist_ok=True)
    print("| run | overlap at the first impact [cm] | first dip of A [m] | at [s] | "
          "second collision [s] | first amplitude of A [m] | at [s] | valid until [s] | "
          "E_total min-max, at the end [J] | steps not converged | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, options in SOLID_STUDIES:
        csv = out / f"{name}.csv"
        if not Path(str(csv) + ".json").is_file():
            _kratos(args, csv, *options)
        s = json.loads(Path(str(csv) + ".json").read_text())
        h = fig7.read_table(csv)
        first = h["t"] < 0.8  # the first impact is at 0.750 s
        overlap = -100 * min(0.0, float(h["min_gap"][first].min()))
        dip = (h["t"] > 1.0) & (h["t"] < 1.2)  # before the second collision
        k = int(np.argmin(h["A_uy"][dip]))
        amp, when = s["first_amplitude_A"], s["first_amplitude_t"]
        amp_text = "-" if amp is None else f"{amp:.3f}" + (
            " (after valid until)" if when > s["valid_until"] else "")
        second = s["second_collision_t"]
        print(f"| {name} | {overlap:.2f} | {h['A_uy'][dip][k]:.3f} | {h['t'][dip][k]:.3f} | "
              f"{'-' if second is None else f'{second:.3f}'} | {amp_text} | "
              f"{'-' if when is None else f'{when:.3f}'} | {s['valid_until']:.3f} | "
              f"{s['E_total_min']:.0f}-{s['E_total_max']:.0f}, {s['E_total_end']:.0f} | "
              f"{s['nonconverged_steps']} | {s['wall_time_s']:.0f} |", flush=True)


CASES = {"drop": case_drop, "stiff": lambda tmp, a: case_drop(tmp, a, 1.0e9, 1.0, True),
         "bundled": case_bundled, "scaling": case_scaling, "solid": case_solid,
         "solid-studies": case_solid_studies}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", choices=list(CASES),
                    default=["drop", "stiff", "bundled", "scaling"],
                    help="what to run (default: the timing cases; solid and solid-studies "
                    "are issue 24's continuum model)")
    ap.add_argument("--engines", nargs="+", default=["auto"],
                    choices=["auto", "native", "jax"],
                    help="beamcontact engines (solver.engine) of the drop cases")
    ap.add_argument("--models", nargs="+", default=["ipip-points", "cg"],
                    choices=["cg", "ipip", "ipip-points"], help="beamcontact contact models")
    ap.add_argument("--outliers", nargs="+", default=["keep", "remove"],
                    choices=["keep", "remove"],
                    help="the drop cases' falling beam as discretised (keep) and with the "
                    "outlier modes of its free ends removed (remove: beams.remove_outliers)")
    ap.add_argument("--pyelastica-dt-large", type=float, default=4e-4,
                    help="the first step tried for PyElastica's largest stable step at its "
                    "default mesh; 0.8 times shorter until it is stable [s]")
    ap.add_argument("--repeat", type=int, default=1, help="run every case this many times")
    ap.add_argument("--solid-out", type=Path, default=Path("results_solid"),
                    help="where the cases solid and solid-studies keep every output")
    ap.add_argument("--kratos-python", default=sys.executable,
                    help="the Python with KratosMultiphysics (the [peers] extra) for "
                    "drop_solid.py")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores; python {sys.version.split()[0]}; "
          f"{time.strftime('%Y-%m-%d %H:%M')}")
    for k in range(args.repeat):
        for name in args.cases:
            with tempfile.TemporaryDirectory() as tmp:
                print(f"\n## {name} (run {k + 1} of {args.repeat})", flush=True)
                CASES[name](Path(tmp), args)
                sys.stdout.flush()


if __name__ == "__main__":
    main()
