"""A user's mistake is one line and an exit code, never a traceback (issue 23, item 4),
from the command line and from the Python API (one error type, CaseError, naming the
key, whether a case comes from TOML, a constructor or model_copy)."""

import subprocess
import sys
from pathlib import Path

import pytest

import beamcontact as bc

REPO = Path(__file__).resolve().parents[1]
VIBRATION = REPO / "examples" / "pinned_beam_vibration" / "case.toml"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "beamcontact.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def _one_line(proc, code: int, *parts: str) -> None:
    assert proc.returncode == code, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and all(p in lines[0] for p in parts), proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_case_file_that_is_not_utf8(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(VIBRATION.read_text(encoding="utf-8").replace(
        "Pinned-pinned", "Caf\u00e9").encode("latin-1"))
    for command in ("check", "run"):
        _one_line(_cli(command, path, "--out", tmp_path / "o") if command == "run"
                  else _cli(command, path), 2, str(path), "not UTF-8 text (byte 0xe9")
    with pytest.raises(bc.CaseError, match="not UTF-8 text"):
        bc.load_case(path)


def test_compare_into_an_unknown_figure_format(tmp_path):
    run = tmp_path / "run"
    short = tmp_path / "case.toml"
    short.write_text(VIBRATION.read_text(encoding="utf-8").replace(
        "t_end = 0.5", "t_end = 0.003"), encoding="utf-8")
    assert _cli("run", short, "--out", run, "-q").returncode == 0
    _one_line(_cli("compare", run, "--point", "mid", "--out", tmp_path / "x.xyz"), 2,
              "x.xyz: unknown figure format '.xyz'", ".png")


def test_sweep_with_a_malformed_scheduler_address(tmp_path):
    proc = _cli("sweep", VIBRATION, "--set", "analysis.t_end=0.001", "--out", tmp_path / "s",
                "--scheduler", "notaurl", "-q")
    _one_line(proc, 2, "--scheduler notaurl: not a scheduler address")


def test_the_api_raises_case_errors_naming_the_key(tmp_path):
    with pytest.raises(bc.CaseError, match=r"^Material\.E: must be greater than 0, got -1"):
        bc.Material(E=-1.0, density=1000.0)
    case = bc.load_case(VIBRATION)
    # model_copy skips pydantic's checks; simulate validates what it is given
    backwards = case.model_copy(update={"analysis": case.analysis.model_copy(
        update={"dt": -1e-3})})
    with pytest.raises(bc.CaseError, match=r"^analysis\.dt: must be greater than 0"):
        bc.simulate(backwards)
    no_elements = case.model_copy(update={"beams": [case.beams[0].model_copy(
        update={"elements": 0})]})
    with pytest.raises(bc.CaseError, match=r"^beams\[0\] \(beam\)\.elements: must be"):
        bc.simulate(no_elements)
    a_file = tmp_path / "a_file"
    a_file.write_text("not a folder", encoding="utf-8")
    with pytest.raises(bc.CaseError, match="cannot create this output folder"):
        bc.simulate(case, out=a_file)


def test_the_examples_are_reachable_from_python_and_a_result_prints_short():
    """The bundled examples from Python wherever beamcontact is installed (the Python API
    page's first example uses them), and a Result that prints as one line, not as its
    history and states."""
    assert {"free_fall", "cantilever_end_moment"} <= set(bc.examples.names())
    path = bc.examples.path("free_fall", "case_cg.toml")
    assert bc.load_case(path).contact.model == "cg"
    with pytest.raises(ValueError, match="the examples are: cantilever_end_moment"):
        bc.examples.path("no_such_example")
    case = bc.load_case(bc.examples.path("pinned_beam_vibration", "case.toml"))
    case = case.model_copy(update={"analysis": case.analysis.model_copy(
        update={"t_end": 0.004})})
    result = bc.simulate(case)
    text = repr(result)
    assert "\n" not in text and len(text) < 200
    assert text.startswith("Result('Pinned-pinned beam") and "4 steps" in text
    assert "<table>" in result._repr_html_()


def _variant(tmp_path: Path, name: str, change) -> Path:
    import tomllib

    import tomli_w

    raw = tomllib.loads((REPO / "examples" / "free_fall" / "case_cg.toml").read_text(
        encoding="utf-8"))
    change(raw)
    path = tmp_path / name
    path.write_text(tomli_w.dumps(raw), encoding="utf-8")
    return path


def test_check_is_as_strict_as_run(tmp_path):
    """check reports every invalid value at once (one line each), the initial overlap
    that run refuses, and warns of keys that the case's model or analysis ignores."""
    def many(raw):
        raw["beams"][0]["material"]["E"] = -1.0
        raw["beams"][1]["elements"] = 0
        raw["analysis"]["dt"] = -1.0

    proc = _cli("check", _variant(tmp_path, "many.toml", many))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [
        "error: analysis.dt: must be greater than 0, got -1.0",
        "error: beams[0] (lower).material.E: must be greater than 0, got -1.0",
        "error: beams[1] (upper).elements: must be greater than or equal to 1, got 0"]

    def overlap(raw):
        raw["beams"][1]["line"] = {"start": [3.5, 0.05], "end": [6.5, 0.05]}

    path = _variant(tmp_path, "overlap.toml", overlap)
    checked, ran = _cli("check", path), _cli("run", path, "--out", tmp_path / "o", "-q")
    _one_line(checked, 2, "beams 'lower' and 'upper' interpenetrate in the initial")
    assert checked.stderr == ran.stderr and ran.returncode == 2

    def ignored(raw):
        raw["contact"]["penalty"] = 1.0e6
        raw["analysis"]["load_steps"] = 5

    proc = _cli("check", _variant(tmp_path, "ignored.toml", ignored))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        'warning: contact.penalty: ignored with model "cg" (it applies to model "ipip")',
        "warning: analysis.load_steps: ignored in a dynamic analysis"]


@pytest.mark.parametrize("model,error", [("none", False), ("ipip", False), ("cg", True)])
def test_pairing_is_an_error_only_with_the_coarse_grained_law(tmp_path, model, error):
    """Keys of a law the case does not use are warnings, so that one file serves a sweep
    over contact.model (none, ipip, cg); only a pairing with "cg" is refused, since it
    would say something about the coarse-grained law that is not so."""
    def pairing(raw):
        raw["contact"].update(model=model, pairing="zones")

    proc = _cli("check", _variant(tmp_path, f"{model}.toml", pairing))
    if error:
        _one_line(proc, 2, 'contact.pairing: applies to model "ipip" only')
        return
    assert proc.returncode == 0, proc.stderr
    warned = [w for w in proc.stderr.splitlines() if "contact.pairing" in w]
    assert warned == ([] if model == "ipip" else [
        'warning: contact.pairing: ignored with no contact law (it applies to model "ipip")'])


def test_progress_into_a_log_is_lines_not_a_bar(monkeypatch):
    """Where the output is not a terminal (a batch job's log) the progress is the title
    and a readable line every LOG_SECONDS and at the end, not a bar's frames."""
    import io

    from rich.console import Console

    import beamcontact.progress as progress

    monkeypatch.setattr(progress, "LOG_SECONDS", 0.0)
    out = io.StringIO()
    with progress.progress_bar("a title", console=Console(file=out), lines=True) as show:
        for step, t in ((0, 0.0), (1, 0.5), (2, 1.0)):
            show(progress.ProgressInfo(t, "t", t, step, 0.5, 3))
    lines = out.getvalue().splitlines()
    assert lines[0] == "a title" and len(lines) == 3
    assert lines[1].startswith(" 50.0 %  t 0.5 s  dt 5.0e-01 s  it 3  step 1")
    assert lines[2].startswith("100.0 %  t 1 s")
