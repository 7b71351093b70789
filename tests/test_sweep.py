"""Parameter sweeps: key expansion and rejection, local and loopback Dask clusters, resume,
failing members (issue 5)."""

import csv
import socket
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_cli import _cli, _write_case
from test_free_fall import _small_drop

from beamcontact.io.case import CaseError, parse_case
from beamcontact.runner import run_case
from beamcontact.sweep import run_sweep
from beamcontact.sweep_settings import (
    Setting,
    apply_setting,
    expand,
    format_value,
    parse_setting,
)

REPO = Path(__file__).resolve().parents[1]
BASE = tomllib.loads((REPO / "examples" / "free_fall" / "case_cg.toml").read_text())


def _drop(t_end=0.26) -> dict:
    """The small IPIP drop of test_free_fall (impact at 0.247 s), cut at t_end."""
    raw = _small_drop("ipip")
    raw["analysis"]["t_end"] = t_end
    raw["output"]["vtk_interval"] = 0.13
    return raw


def _table(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


# --- key expansion and rejection ------------------------------------------------------


def test_values_are_toml_and_commas_inside_brackets_do_not_split():
    s = parse_setting("analysis.gravity=[0.0, -9.81],[0, -1.62]")
    assert s == Setting("analysis.gravity", ([0.0, -9.81], [0, -1.62]))
    assert parse_setting("contact.model=cg, ipip").values == ("cg", "ipip")
    assert parse_setting("contact.penalty=1e5,1e6").values == (1e5, 1e6)
    assert parse_setting("beams.upper.gravity=true,false").values == (True, False)
    assert parse_setting('title="a, b",c').values == ("a, b", "c")


@pytest.mark.parametrize("text, fragment", [
    ("contact.penalty", "expected KEY=V1,V2"),
    ("=1,2", "expected KEY=V1,V2"),
    ("contact..penalty=1", "dotted path"),
    ("contact.penalty=1e5,,1e6", "empty value"),
    ("contact.penalty=1e6,1e6", "given twice"),
])
def test_malformed_settings_are_rejected(text, fragment):
    with pytest.raises(CaseError, match=fragment):
        parse_setting(text)


def test_product_order_labels_and_list_entries_by_name():
    lower_E, upper_E = (b["material"]["E"] for b in BASE["beams"])
    members = expand(BASE, [parse_setting("contact.model=cg,ipip"),
                            parse_setting("beams.upper.material.E=1e6,2.5e6")])
    assert [m.params for m in members] == [
        (("contact.model", "cg"), ("beams.upper.material.E", 1e6)),
        (("contact.model", "cg"), ("beams.upper.material.E", 2.5e6)),
        (("contact.model", "ipip"), ("beams.upper.material.E", 1e6)),
        (("contact.model", "ipip"), ("beams.upper.material.E", 2.5e6))]
    assert members[1].label == "model=cg, E=2.5e6"
    assert len({m.name for m in members}) == 4
    case = parse_case(tomllib.loads(members[3].case_text))
    assert case.contact.model == "ipip"
    assert [b.material.E for b in case.beams] == [lower_E, 2.5e6]  # only the upper beam
    # the base case is left alone
    assert BASE["beams"][1]["material"]["E"] == upper_E != 2.5e6


def test_entries_by_index_and_same_suffix_keys_get_longer_labels():
    members = expand(BASE, [parse_setting("beams.0.material.E=1e6"),
                            parse_setting("beams.upper.material.E=3e6")])
    case = parse_case(tomllib.loads(members[0].case_text))
    assert [b.material.E for b in case.beams] == [1e6, 3e6]
    assert members[0].label == "0.material.E=1e6, upper.material.E=3e6"


def test_format_value():
    assert [format_value(v) for v in (1e6, 1.22e6, 5e-25, 0.3, -0.33, 2, True, [0, -9.81])] \
        == ["1e6", "1.22e6", "5e-25", "0.3", "-0.33", "2", "true", "[0,-9.81]"]
    # values one unit in the last place apart keep every digit, and read back exactly
    for v in (1000.0, np.nextafter(1000.0, 2000.0), np.nextafter(1000.0, 0.0), 0.1 + 0.2,
              np.nextafter(1e-5, 1.0)):
        assert float(format_value(float(v))) == v
    assert format_value(float(np.nextafter(1000.0, 2000.0))) == "1000.0000000000001"
    # TOML's infinities and NaN (a sweep over a bound that may be switched off) read back
    text = ",".join(format_value(v) for v in (float("inf"), float("-inf"), float("nan")))
    back = parse_setting(f"contact.max_penetration={text}").values
    assert back[:2] == (float("inf"), float("-inf")) and np.isnan(back[2])


@pytest.mark.parametrize("sets, fragment", [
    (["contact.penalti=1,2"], "contact.penalti: unknown key"),
    (["contct.penalty=1"], "contct: unknown key"),
    (["beams.middle.material.E=1"], "beams has no entry 'middle'"),
    (["beams.upper=1"], "names a whole entry"),
    (["analysis.alpha.x=1"], "analysis.alpha is a value"),
    (["contact.penalty=1e6,-1"], "contact.penalty: must be greater than 0"),
    (["analysis.alpha=-0.5"], "analysis.alpha"),
    (["contact.cutoff=0.3,0.1"], "contact.cutoff: must exceed"),
    (["contact.model=cg,dem"], "contact.model"),
    (["analysis.alpha=0", "analysis.alpha=-0.1"], "given twice"),
])
def test_bad_keys_and_values_are_rejected_before_running(sets, fragment):
    with pytest.raises(CaseError, match=fragment.replace(".", r"\.")):
        expand(BASE, [parse_setting(s) for s in sets])


def test_cli_rejects_bad_sweep_with_exit_2_and_no_traceback(tmp_path):
    case = REPO / "examples" / "free_fall" / "case_cg.toml"
    for args in (["--set", "beams.upper.material.E=1e6,-2"], ["--set", "contact.foo=1"], []):
        r = _cli("sweep", case, *args, "--out", tmp_path / "s")
        assert r.returncode == 2, r.stderr
        assert "Traceback" not in r.stderr and r.stderr.startswith("error:")
    assert not (tmp_path / "s").exists()  # nothing ran
    r = _cli("sweep", case, "--set", "beams.upper.material.E=1e6,-2", "--out", tmp_path / "s")
    assert "beams[1] (upper).material.E" in r.stderr


def test_apply_setting_creates_missing_tables():
    raw = {"analysis": {"kind": "static"}}
    apply_setting(raw, "solver.rtol", 1e-6)
    assert raw["solver"] == {"rtol": 1e-6}


# --- running ---------------------------------------------------------------------------


def test_local_cluster_two_runs_table_plots_and_resume(tmp_path):
    case = _write_case(tmp_path / "drop.toml", _drop())
    out = tmp_path / "sweep"
    args = ("sweep", case, "--set", "contact.penalty=1e5,1e6", "--out", out, "--workers", "2",
            "--quiet")
    r = _cli(*args)
    assert r.returncode == 0, r.stderr
    rows = _table(out / "sweep.csv")
    assert [row["contact.penalty"] for row in rows] == ["1e5", "1e6"]
    assert all(row["status"] == "completed" for row in rows)
    g = 9.81
    for row in rows:
        # the upper beam falls freely onto the lower one (surface gap 0.3 m)
        assert abs(float(row["first_impact_time"]) - np.sqrt(2 * 0.299 / g)) <= 1e-3 + 1e-12
        assert float(row["min_gap"]) < 0
        assert float(row["wall_time_s"]) > 0
        # the energy account of each run closes (docs/theory.md, item "Energy account")
        e0 = float(row["E_total_initial"])
        assert e0 > 0
        assert abs(float(row["balance_residual"])) <= 1e-9 * e0
        assert abs(float(row["E_total_final"]) + float(row["E_dissipated"])
                   - float(row["E_set_change"]) - e0) <= 1e-9 * e0
    # a softer penalty lets the beams penetrate deeper
    assert float(rows[0]["max_penetration"]) > float(rows[1]["max_penetration"])
    for name in ("A_uy.png", "A_ux.png", "min_gap.png", "E_total.png"):
        assert (out / "plots" / name).stat().st_size > 0
    for row in rows:
        assert (out / row["run"] / "history.csv").is_file()
        assert (out / row["run"] / "beams.pvd").is_file()

    # resume: delete one run's output; only that run is redone, with identical results
    kept, deleted = out / rows[0]["run"], out / rows[1]["run"]
    kept_mtime = (kept / "summary.json").stat().st_mtime_ns
    history = (deleted / "history.csv").read_text()
    import shutil

    shutil.rmtree(deleted)
    r = _cli(*args)
    assert r.returncode == 0, r.stderr
    assert (kept / "summary.json").stat().st_mtime_ns == kept_mtime
    assert (deleted / "history.csv").read_text() == history
    assert [row["wall_time_s"] for row in _table(out / "sweep.csv")][0] == rows[0]["wall_time_s"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_existing_scheduler_on_loopback_equals_serial_runs(tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, cwd=tmp_path)]
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "the scheduler did not start"
                time.sleep(0.2)
        procs.append(subprocess.Popen(
            [*dask, "worker", address, "--nworkers", "2", "--nthreads", "1", "--no-dashboard",
             "--local-directory", str(tmp_path / "dask")], stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL, cwd=tmp_path))
        members = expand(_drop(0.2), [parse_setting("analysis.alpha=0,-0.2")])
        rows = run_sweep(members, tmp_path / "sweep", ["A"], scheduler=address)
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait(timeout=30)
    assert [r["status"] for r in rows] == ["completed", "completed"]
    for m in members:
        serial = tmp_path / "serial" / m.name
        summary = run_case(parse_case(tomllib.loads(m.case_text)), m.case_text, serial)
        assert summary["status"] == "completed"
        remote = tmp_path / "sweep" / m.name
        assert (remote / "history.csv").read_text() == (serial / "history.csv").read_text()
        with h5py.File(remote / "results.h5") as a, h5py.File(serial / "results.h5") as b:
            for key in ("u", "v", "a"):
                assert np.array_equal(a["states"][key][:], b["states"][key][:])


def test_failing_member_is_recorded_and_others_complete(tmp_path):
    # a nonlinear vibration needs more than one Newton iteration per step to pass the
    # residual test (Newton's error test off: one iteration usually passes that)
    raw = tomllib.loads((REPO / "examples" / "pinned_beam_vibration" / "case.toml").read_text())
    raw["analysis"]["t_end"] = 0.02
    raw["solver"] = {"max_cutbacks": 0, "newton_error_fraction": 0.0}
    members = expand(raw, [parse_setting("solver.max_iterations=1,25")])
    rows = run_sweep(members, tmp_path / "sweep", ["mid"], workers=2)
    assert [r["status"] for r in rows] == ["failed", "completed"]
    assert "Newton did not converge" in rows[0]["message"]
    table = _table(tmp_path / "sweep" / "sweep.csv")
    assert [r["status"] for r in table] == ["failed", "completed"]


def test_crashing_member_is_recorded(tmp_path, monkeypatch):
    """A member whose task raises outside the run (e.g. its worker died) is 'crashed'."""
    from distributed import LocalCluster

    import beamcontact.sweep as sweep

    def explode(member, run_dir, report=None):
        if "0.1" in member.name:
            raise RuntimeError("worker lost")
        return {"status": "completed", "message": "stub"}

    monkeypatch.setattr(sweep, "run_member", explode)
    members = expand(_drop(0.05), [parse_setting("analysis.alpha=0,-0.1")])
    with LocalCluster(n_workers=1, processes=False, dashboard_address=None) as cluster:
        rows = run_sweep(members, tmp_path / "sweep", ["A"],
                         scheduler=cluster.scheduler_address)
    assert [r["status"] for r in rows] == ["completed", "crashed"]
    assert "worker lost" in rows[1]["message"]


_LISTENERS = """
import json, urllib.error, urllib.request
from beamcontact.sweep import dask_client

def get(port, route):
    try:
        return urllib.request.urlopen(f"http://127.0.0.1:{port}/{route}", timeout=10).status
    except urllib.error.HTTPError as exc:
        return exc.code

if __name__ == "__main__":
    found = {}
    for dashboard in (False, True):
        with dask_client(1, None, dashboard) as client:
            info = client.scheduler_info()
            http = client.run_on_scheduler(lambda dask_scheduler: [
                s.getsockname()[:2] for s in dask_scheduler.http_server._sockets.values()])
            port = info["services"]["dashboard"]
            found[str(dashboard)] = {"scheduler": info["address"],
                                     "workers": list(info["workers"]), "http": http,
                                     "status": get(port, "status")}
    print(json.dumps(found))
"""


def test_a_local_cluster_listens_on_loopback_and_serves_no_dashboard_unless_asked(
        tmp_path):
    """Every listener of a sweep's local cluster is on 127.0.0.1; without --dashboard the
    scheduler's HTTP server (health routes only) is on a port the system picks, so two
    sweeps never compete for 8787, and it serves no dashboard page."""
    import json
    import subprocess
    import sys

    script = tmp_path / "listeners.py"  # a file: the workers' processes import __main__
    script.write_text(_LISTENERS, encoding="utf-8")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         check=True, timeout=300)
    found = json.loads(out.stdout.strip().splitlines()[-1])
    for dashboard, seen in found.items():
        addresses = [seen["scheduler"], *seen["workers"]]
        assert all(a.startswith("tcp://127.0.0.1:") for a in addresses), seen
        assert all(host == "127.0.0.1" for host, _ in seen["http"]), seen
        if dashboard == "False":
            assert all(port != 8787 for _, port in seen["http"]) and seen["status"] == 404
        else:
            assert seen["status"] == 200
