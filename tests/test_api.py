"""The Python API (beamcontact.api): the README's example verbatim, in-memory results
equal to the files of a run, Ctrl-C keeping everything, cases built in Python checked like
case files and round-tripped through TOML, and an import free of side effects."""

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import beamcontact as bc
from beamcontact.io.case import CaseError, parse_case
from beamcontact.io.results import read_history, read_summary
from beamcontact.progress import ProgressInfo

ROOT = Path(__file__).resolve().parents[1]
CASE_FILES = sorted(ROOT.glob("examples/**/*.toml")) + sorted(ROOT.glob("tests/**/*.toml"))


def _rod(elements: int = 6, moment_fraction: float = 0.5, steps: int = 4) -> bc.Case:
    """A clamped 1 m rod under an end moment: a fraction of pi EI / L."""
    ei = 2.1e11 * math.pi * 0.01**4 / 4
    return bc.Case(
        title="rod",
        analysis=bc.Analysis(kind="static", load_steps=steps),
        beams=[bc.Beam(name="rod", line=bc.Line(start=(0, 0), end=(1, 0)), degree=3,
                       elements=elements, section=bc.CircleSection(radius=0.01),
                       material=bc.Material(E=2.1e11, density=7850.0),
                       supports=[bc.Support(at="start", type="clamped")])],
        loads=[bc.Load(beam="rod", at="end", moment=moment_fraction * math.pi * ei)],
        output=bc.Output(points=[bc.OutputPoint(name="tip", beam="rod", at="end")]))


def test_readme_python_example_runs_verbatim(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"## Python API.*?```python\n(.*?)```", text, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(block, "README.md", "exec"), namespace)  # its asserts check the physics
    assert namespace["result"].status == "completed"
    assert (tmp_path / "tip.png").stat().st_size > 0
    assert bc.load_case(tmp_path / "rod.toml") == namespace["case"]


def test_import_has_no_side_effects():
    code = ("import sys, beamcontact\n"
            "heavy = [m for m in sys.modules if m.split('.')[0] in ('jax', 'matplotlib')]\n"
            "assert not heavy, heavy\n"
            "beamcontact.Case, beamcontact.Beam\n"  # the case classes need neither
            "heavy = [m for m in sys.modules if m.split('.')[0] in ('jax', 'matplotlib')]\n"
            "assert not heavy, heavy\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_simulate_in_memory_writes_nothing_and_matches_the_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = _rod()
    memory = bc.simulate(case)
    assert memory.out is None and list(tmp_path.iterdir()) == []
    bc.simulate(case, out=tmp_path / "run")
    for name in ("history.csv", "summary.json", "results.h5", "beams.pvd",
                 "plots/points.png", "plots/shapes.png"):
        assert (tmp_path / "run" / name).is_file(), name
    h = read_history(tmp_path / "run" / "history.csv")
    assert list(h) == list(memory.history.columns)
    for column, values in h.items():  # the CSV holds repr() of the floats: exact
        np.testing.assert_array_equal(memory.history[column].to_numpy(), values)
    stored = read_summary(tmp_path / "run" / "summary.json")
    assert stored["steps"] == memory.summary["steps"] == 4
    assert stored["extremes"] == memory.summary["extremes"]
    # the saved states: the tip of the last centre line is the tip point of the history
    tip = memory.states.centrelines["rod"][-1, -1]
    np.testing.assert_allclose(tip, [h["tip_x"][-1], h["tip_y"][-1]], atol=1e-12)
    assert memory.states.control_points.shape == (len(memory.states), 6 + 3, 2)
    np.testing.assert_array_equal(memory.states.parameter, h["load_factor"])


def test_pyplot_is_never_touched(tmp_path):
    """Writing the plots of a run neither imports pyplot nor selects a backend."""
    code = ("import sys, beamcontact as bc\n"
            f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
            "from test_api import _rod\n"
            f"bc.simulate(_rod(), out={str(tmp_path / 'run')!r})\n"
            "assert 'matplotlib.pyplot' not in sys.modules\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "run" / "plots" / "points.png").is_file()


def test_interrupt_keeps_every_counter(tmp_path):
    """Ctrl-C after the third accepted step (simulated by the progress callback): the
    run returns status "interrupted" with the counters of the three steps, and the
    summary.json on disk holds them as well."""
    from beamcontact.runner import execute

    case = _rod(steps=8)

    def interrupt(info: ProgressInfo) -> None:
        if info.step == 3:
            raise KeyboardInterrupt

    bc.enable_x64()
    summary, record = execute(case, case.to_toml(), tmp_path, interrupt)
    assert summary["status"] == "interrupted"
    assert summary["steps"] == 3 and summary["final_load_factor"] == pytest.approx(3 / 8)
    assert summary["newton_iterations"] >= 3 and summary["compile_time_s"] > 0
    assert summary["solver"]["max_iterations"] == 25 and "wall_time_s" in summary
    assert len(record.history()["step"]) == 4  # the initial row and three steps
    assert read_summary(tmp_path / "summary.json")["steps"] == 3
    assert len(read_history(tmp_path / "history.csv")["step"]) == 4


@pytest.mark.parametrize("path", CASE_FILES, ids=[p.name for p in CASE_FILES])
def test_toml_round_trip(path):
    case = bc.load_case(path)
    text = case.to_toml()
    assert bc.Case.from_toml(text) == case
    assert bc.Case.from_toml(text).to_toml() == text


def test_python_values_are_accepted_like_toml_values():
    a = bc.Line(start=(0, 0), end=np.array([1.0, 0.0]))
    b = bc.Line.model_validate({"start": [0.0, 0.0], "end": [1.0, 0.0]})
    assert a == b
    nurbs = bc.Nurbs(degree=2, knots=np.array([0, 0, 0, 1, 1, 1.0]),
                     points=np.array([[0, 0], [1, 1], [2, 0.0]]))
    assert nurbs.points == [[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]]


def test_cases_built_in_python_are_cross_checked():
    rod = _rod().beams[0]
    # one error type whether a case comes from TOML or from the constructors
    with pytest.raises(CaseError, match=r"^beams\[1\]\.name: duplicate beam name 'rod'$"):
        bc.Case(analysis=bc.Analysis(kind="static"), beams=[rod, rod])
    with pytest.raises(CaseError, match=r"^loads\[0\]\.beam: unknown beam 'other'"):
        bc.Case(analysis=bc.Analysis(kind="static"), beams=[rod],
                loads=[bc.Load(beam="other", at="end", moment=1.0)])
    raw = {"analysis": {"kind": "static"}, "beams": [rod.model_dump(), rod.model_dump()]}
    with pytest.raises(CaseError, match=r"^beams\[1\]\.name: duplicate beam name 'rod'$"):
        parse_case(raw)


def test_python_built_free_fall_is_the_toml_case_and_runs_identically():
    sys.path.insert(0, str(ROOT / "examples" / "python_api"))
    try:
        from free_fall import TOML, free_fall_case
    finally:
        sys.path.pop(0)
    assert free_fall_case(3.0) == bc.load_case(TOML)
    short = free_fall_case(0.004)
    from_file = bc.load_case(TOML)
    from_file = bc.Case.model_validate({**from_file.model_dump(),
                                        "analysis": {**from_file.analysis.model_dump(),
                                                     "t_end": 0.004}})
    a, b = bc.simulate(short), bc.simulate(from_file)
    assert len(a.history) == 5 and a.history.equals(b.history)


def test_ipip_pairs_every_point_unless_the_case_asks_for_zones():
    """The default IPIP rule is the conservative "points"; the paper's "zones" is asked for
    (examples/free_fall/case_ipip.toml does, for the paper's figures)."""
    assert bc.Contact(model="ipip").law([0.1]).pairing == "points"
    assert bc.Contact(model="ipip", pairing="zones").law([0.1]).pairing == "zones"
    assert bc.load_case(ROOT / "examples/free_fall/case_ipip.toml").contact.pairing == "zones"
