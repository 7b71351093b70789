"""ParaView output: one VTU per snapshot (beams as polylines) and a PVD time series;
the rigid obstacles, which do not move, once in ``obstacles.vtu``.

Point data: ``displacement`` (3-vector, z = 0), ``radius`` (section half-depth, for the
Tube filter); cell data: ``beam`` (index of the beam in the case); in obstacles.vtu,
``obstacle`` (index of the obstacle in the case).

beams.pvd is valid after every snapshot: its entry is written over the closing tags,
which follow it, so a snapshot costs the same however many came before (rewriting the
whole series each time cost 1 us per earlier snapshot: 2.4 ms a snapshot after 2000).
"""

import contextlib
import os
import re
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

_HEAD = (b'<?xml version="1.0"?>\n'
         b'<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
         b"  <Collection>\n")
_TAIL = b"  </Collection>\n</VTKFile>\n"


def _entry(t: float, file: str) -> bytes:
    """The line of beams.pvd for the snapshot in ``file`` at time or load factor t."""
    return f'    <DataSet timestep="{t!r}" part="0" file={quoteattr(file)}/>\n'.encode()


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
        # where the closing tags of beams.pvd begin, as this series last wrote it
        self._tail_at: int | None = None
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
        # uncompressed: zlib took 0.4 of the 0.65 ms a snapshot of the peer drop costs the
        # time loop, to make its 39 kB 15 (benchmarks/README.md, session 38)
        meshio.write(self.out_dir / name, meshio.Mesh(
            pts, self._cells, point_data={"displacement": pts - self._ref_pts, "radius": radius},
            cell_data={"beam": [self._beam_ids]}), compression=None)
        self._entries.append((parameter, name))
        self._add_to_series(_entry(parameter, name))

    def _add_to_series(self, entry: bytes) -> None:
        """beams.pvd with ``entry`` (the newest, already in self._entries) added: written
        over the closing tags of the file as this series left it, or the whole series
        written anew (the first snapshot, a continued run, a file changed meanwhile)."""
        path = self.out_dir / "beams.pvd"
        if self._tail_at is not None:
            with contextlib.suppress(FileNotFoundError), open(path, "r+b") as f:
                if f.seek(0, os.SEEK_END) == self._tail_at + len(_TAIL):
                    f.seek(self._tail_at)
                    f.write(entry + _TAIL)
                    self._tail_at += len(entry)
                    return
        head = _HEAD + b"".join(_entry(t, f) for t, f in self._entries)
        path.write_bytes(head + _TAIL)
        self._tail_at = len(head)


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
