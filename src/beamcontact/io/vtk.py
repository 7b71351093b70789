"""ParaView output: one VTU per snapshot (beams as polylines) and a PVD time series;
the rigid obstacles, which do not move, once in ``obstacles.vtu``.

Point data: ``displacement`` (3-vector, z = 0), ``radius`` (section half-depth, for the
Tube filter); cell data: ``beam`` (index of the beam in the case); in obstacles.vtu,
``obstacle`` (index of the obstacle in the case).
"""

import re
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np


class VtkSeries:
    """Writes ``vtk/beams_NNNNN.vtu`` and keeps ``beams.pvd`` valid after every snapshot."""

    def __init__(self, out_dir: Path, polylines: list, radii: list[float],
                 x_ref: np.ndarray, offsets: list[int], n_cps: list[int],
                 resume_until: float | None = None):
        self.out_dir = out_dir
        (out_dir / "vtk").mkdir(parents=True, exist_ok=True)
        self._maps = polylines
        self._slices = [slice(o, o + n) for o, n in zip(offsets, n_cps, strict=True)]
        self._x_ref = x_ref
        self._radii = radii
        self._entries: list[tuple[float, str]] = []
        # a continued run appends to the series of beams.pvd; without a readable one
        # (missing, damaged) ``resumed`` is False and the caller writes the series again
        self.resumed = False
        if resume_until is not None:
            try:
                text = (out_dir / "beams.pvd").read_text(encoding="utf-8")
                found = re.findall(r'timestep="([^"]+)" part="0" file="([^"]+)"', text)
                self._entries = [(float(t), f) for t, f in found
                                 if float(t) <= resume_until and (out_dir / f).is_file()]
                self.resumed = bool(self._entries)
            except (OSError, UnicodeDecodeError, ValueError):
                self._entries = []
        cells, start = [], 0
        beam_ids = []
        for b, m in enumerate(polylines):
            n = m.shape[0]
            cells.append(np.column_stack([np.arange(start, start + n - 1),
                                          np.arange(start + 1, start + n)]))
            beam_ids.append(np.full(n - 1, b))
            start += n
        self._cells = [("line", np.concatenate(cells))]
        self._beam_ids = np.concatenate(beam_ids)
        self._ref_pts = self._points(x_ref)

    def _points(self, x: np.ndarray) -> np.ndarray:
        pts = np.concatenate([m @ x[s] for m, s in zip(self._maps, self._slices, strict=True)])
        return np.column_stack([pts, np.zeros(len(pts))])

    def write(self, parameter: float, x: np.ndarray) -> None:
        """Snapshot of the current control points x (n_cp, 2) at time/load ``parameter``."""
        pts = self._points(x)
        radius = np.concatenate([np.full(m.shape[0], r)
                                 for m, r in zip(self._maps, self._radii, strict=True)])
        name = f"vtk/beams_{len(self._entries):05d}.vtu"
        meshio.write(self.out_dir / name, meshio.Mesh(
            pts, self._cells, point_data={"displacement": pts - self._ref_pts, "radius": radius},
            cell_data={"beam": [self._beam_ids]}))
        self._entries.append((parameter, name))
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t!r}" part="0" file={quoteattr(f)}/>'
                  for t, f in self._entries]
        lines += ["  </Collection>", "</VTKFile>", ""]
        (self.out_dir / "beams.pvd").write_text("\n".join(lines), encoding="utf-8")


def write_obstacles(path: Path, obstacles, lo, hi) -> None:
    """The obstacles as polylines (:func:`~beamcontact.obstacle_outlines.obstacle_outlines`
    for the box [lo, hi] of the beams): walls as segments, circles as closed polygons."""
    from beamcontact.obstacle_outlines import obstacle_outlines

    pts, cells, ids, start = [], [], [], 0
    for k, (_, line) in enumerate(obstacle_outlines(obstacles, lo, hi)):
        n = len(line)
        pts.append(line)
        cells.append(np.column_stack([np.arange(start, start + n - 1),
                                      np.arange(start + 1, start + n)]))
        ids.append(np.full(n - 1, k))
        start += n
    xyz = np.concatenate(pts)
    meshio.write(path, meshio.Mesh(np.column_stack([xyz, np.zeros(len(xyz))]),
                                   [("line", np.concatenate(cells))],
                                   cell_data={"obstacle": [np.concatenate(ids)]}))
