"""One run per output folder (io/output_folder.py): a second run meets the first's lock,
a folder with an earlier run's results is refused unless --overwrite (which removes
them) or --restart, and the refused run leaves the earlier results as they were."""

import subprocess
import sys
import time
import tomllib
from pathlib import Path

import tomli_w

REPO = Path(__file__).resolve().parents[1]
VIBRATION = REPO / "examples" / "pinned_beam_vibration" / "case.toml"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "beamcontact.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600)


def _case(tmp_path: Path, t_end: float, name: str = "case.toml") -> Path:
    raw = tomllib.loads(VIBRATION.read_text(encoding="utf-8"))
    raw["analysis"]["t_end"] = t_end
    raw["output"]["vtk_interval"] = 0.002
    path = tmp_path / name
    path.write_text(tomli_w.dumps(raw), encoding="utf-8")
    return path


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".beamcontact.lock"}


def _one_line(proc, *parts: str) -> None:
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and all(p in lines[0] for p in parts), proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_used_folder_is_refused_unless_overwritten(tmp_path):
    out = tmp_path / "out"
    long_case, short_case = _case(tmp_path, 0.02, "long.toml"), _case(tmp_path, 0.006)
    assert _cli("run", long_case, "--out", out, "-q").returncode == 0
    before = _files(out)
    assert (out / "case.toml").read_text(encoding="utf-8") == long_case.read_text(
        encoding="utf-8")  # the effective case, as a sweep's runs have it
    refused = _cli("run", short_case, "--out", out, "-q")
    assert refused.returncode == 2
    _one_line(refused, f"--out {out}", "results of an earlier run", "--overwrite")
    assert _files(out) == before
    replaced = _cli("run", short_case, "--out", out, "-q", "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    # nothing of the longer earlier run is left beside the new one's files
    vtu = sorted(p.name for p in (out / "vtk").iterdir())
    assert len(vtu) == 4 and len(before) > len(_files(out))  # t = 0, 2, 4, 6 ms
    assert (out / "case.toml").read_text(encoding="utf-8") == short_case.read_text(
        encoding="utf-8")


_HOLD = """
import sys, time
from filelock import FileLock
lock = FileLock(sys.argv[1], timeout=0)
lock.acquire()
print("held", flush=True)
time.sleep(60)
"""


def test_a_second_run_meets_the_first_runs_lock(tmp_path):
    """Another process holds the folder (as a running run does): a run into it stops at
    once with exit code 2 and writes nothing; once that process is gone (killed, without
    releasing anything itself) the folder is free again."""
    out = tmp_path / "out"
    case = _case(tmp_path, 0.004)
    assert _cli("run", case, "--out", out, "-q").returncode == 0
    before = _files(out)
    holder = subprocess.Popen([sys.executable, "-c", _HOLD, str(out / ".beamcontact.lock")],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        for args in ((), ("--overwrite",), ("--restart",)):
            second = _cli("run", case, "--out", out, "-q", *args)
            assert second.returncode == 2
            _one_line(second, f"--out {out}", "another beamcontact run is writing")
            assert _files(out) == before
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)
    assert _cli("run", case, "--out", out, "-q", "--overwrite").returncode == 0


def test_restart_and_overwrite_exclude_each_other(tmp_path):
    proc = _cli("run", _case(tmp_path, 0.004), "--out", tmp_path / "out", "--restart",
                "--overwrite")
    assert proc.returncode == 2
    _one_line(proc, "--restart", "--overwrite")
