"""beams.pvd of io/vtk.py's VtkSeries: valid ParaView collection after every snapshot,
the same text whether it was written entry by entry or at once, continued runs and a
file removed meanwhile."""

import xml.etree.ElementTree as ET

import numpy as np

from beamcontact.io.vtk import VtkSeries


def _series(folder, resume_until=None):
    # two beams: 7 and 4 samples of 3 and 2 control points
    maps = [np.linspace(0.0, 1.0, 21).reshape(7, 3), np.linspace(0.0, 1.0, 8).reshape(4, 2)]
    x_ref = np.arange(10.0).reshape(5, 2)
    return VtkSeries(folder, maps, [0.1, 0.05], x_ref, [0, 3], [3, 2],
                     resume_until=resume_until), x_ref


def _expected(entries):
    """The collection as ParaView's PVD format lays it out, written at once."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" part="0" file="{f}"/>' for t, f in entries]
    return "\n".join(lines + ["  </Collection>", "</VTKFile>", ""])


def test_the_series_is_whole_after_every_snapshot(tmp_path):
    series, x = _series(tmp_path)
    entries = []
    for k, t in enumerate([0.0, 0.1, 0.2 + 1e-17, 1.0 / 3.0]):
        series.write(t, x + k)
        entries.append((t, f"vtk/beams_{k:05d}.vtu"))
        text = (tmp_path / "beams.pvd").read_text(encoding="utf-8")
        assert text == _expected(entries)
        datasets = ET.fromstring(text).findall("./Collection/DataSet")
        assert [float(d.get("timestep")) for d in datasets] == [t for t, _ in entries]
        assert all((tmp_path / d.get("file")).is_file() for d in datasets)


def test_a_continued_series_and_a_removed_file(tmp_path):
    series, x = _series(tmp_path)
    for k in range(4):
        series.write(0.5 * k, x)
    # a run continued from t = 1.0: the later entries are dropped, the next one follows
    again, x = _series(tmp_path, resume_until=1.0)
    assert again.resumed
    again.write(1.25, x)
    kept = [(0.0, "vtk/beams_00000.vtu"), (0.5, "vtk/beams_00001.vtu"),
            (1.0, "vtk/beams_00002.vtu"), (1.25, "vtk/beams_00003.vtu")]
    assert (tmp_path / "beams.pvd").read_text(encoding="utf-8") == _expected(kept)
    # removed (or changed) meanwhile: written whole again
    (tmp_path / "beams.pvd").unlink()
    again.write(1.5, x)
    kept.append((1.5, "vtk/beams_00004.vtu"))
    assert (tmp_path / "beams.pvd").read_text(encoding="utf-8") == _expected(kept)
    (tmp_path / "beams.pvd").write_text("<VTKFile", encoding="utf-8")
    again.write(1.75, x)
    kept.append((1.75, "vtk/beams_00005.vtu"))
    assert (tmp_path / "beams.pvd").read_text(encoding="utf-8") == _expected(kept)
