"""Figures: deformed shapes and histories of the output points.

Built on matplotlib's object-oriented API (``matplotlib.figure.Figure``), never on
``pyplot``: making and saving a figure here neither selects a backend nor registers the
figure with pyplot, so plots written by a run leave a notebook's or a script's matplotlib
state alone. Every ``plot_*`` function saves to ``path`` when it is given and returns the
figure (which Jupyter displays).
"""

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure


def _save(fig: Figure, path: Path | None, dpi: int = 150) -> Figure:
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig


def draw_obstacles(ax, obstacles, lo, hi) -> None:
    """The rigid obstacles (case ``[[obstacles]]``) in grey under everything else: a wall
    as its surface line with the solid side shaded, a circle as a filled disk; the view
    [lo, hi] set by the caller is kept."""
    from matplotlib.patches import Polygon

    from beamcontact.obstacle_outlines import obstacle_outlines, solid_side

    if not obstacles:
        return
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    for o, (_, line) in zip(obstacles, obstacle_outlines(obstacles, lo, hi), strict=True):
        ax.add_patch(Polygon(solid_side(o, line), closed=True, facecolor="0.88",
                             edgecolor="none", zorder=0))
        ax.plot(line[:, 0], line[:, 1], color="0.45", lw=1.0, zorder=0.5)
    ax.set_xlim(xlim)
    ax.set_ylim(ylim)


def _view(beams: list[np.ndarray], obstacles) -> tuple[np.ndarray, np.ndarray]:
    """The box of all beam points, and of the circles among the obstacles (walls are
    infinite: the view follows the beams)."""
    pts = [np.concatenate(beams)]
    for o in obstacles or ():
        if o.circle is not None:
            c, r = np.asarray(o.circle.center), o.circle.radius
            pts.append(np.array([c - r, c + r]))
    allpts = np.concatenate(pts)
    return allpts.min(axis=0), allpts.max(axis=0)


def plot_shapes(shapes: list[tuple[str, list[np.ndarray]]], reference: list[np.ndarray],
                path: Path | None = None, title: str = "", obstacles=()) -> Figure:
    """Axes of all beams: reference dashed, then one colour per labelled state; the
    obstacles (case ``[[obstacles]]`` tables) in grey."""
    fig = Figure(figsize=(7, 5))
    ax = fig.subplots()
    for k, pts in enumerate(reference):
        ax.plot(pts[:, 0], pts[:, 1], "k--", lw=0.8, label="reference" if k == 0 else None)
    cmap = colormaps["viridis"]
    for i, (label, beams) in enumerate(shapes):
        colour = cmap(i / max(len(shapes) - 1, 1))
        for k, pts in enumerate(beams):
            ax.plot(pts[:, 0], pts[:, 1], color=colour, lw=1.5, label=label if k == 0 else None)
    if obstacles:
        lo, hi = _view(reference + [p for _, beams in shapes for p in beams], obstacles)
        pad = 0.05 * max(hi - lo)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        draw_obstacles(ax, obstacles, lo, hi)
    # with the view fixed (obstacles) the box adapts to the aspect, else the data limits
    ax.set_aspect("equal", adjustable="box" if obstacles else "datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if len(shapes) <= 12:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return _save(fig, path)


def _finish(fig: Figure, ax, path: Path | None, xlabel: str, ylabel: str,
            title: str) -> Figure:
    """Labels, grid and legend; save.

    The legend sits outside the axes, right of them: it never hides a curve, and
    matplotlib's search for the "best" place inside tests every point of every curve
    against candidate boxes (0.2 s for the energies of a 12 000-step history, a third of
    that figure's cost).
    """
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    return _save(fig, path)


def plot_point_histories(history: dict[str, np.ndarray], abscissa: str, points: list[str],
                         path: Path | None = None, title: str = "") -> Figure:
    """Displacements u_x, u_y of every output point against ``abscissa``."""
    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    for name in points:
        for comp, style in (("ux", "--"), ("uy", "-")):
            ax.plot(history[abscissa], history[f"{name}_{comp}"], style, label=f"{name} {comp}")
    xlabel = {"t": "t [s]", "load_factor": "load factor"}.get(abscissa, abscissa)
    return _finish(fig, ax, path, xlabel, "displacement [m]", title)


def plot_energies(history: dict[str, np.ndarray], path: Path | None = None,
                  title: str = "") -> Figure:
    """Kinetic, strain, gravity, contact and total energy against time, and the energy
    account: E_dissipated (removed by the integrator) and E_set_change (jumps of the
    contact set), so that a change of E_total is seen next to what explains it."""
    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    for name in ("E_kin", "E_strain", "E_gravity", "E_ext", "E_contact", "E_total",
                 "E_dissipated", "E_set_change"):
        if name in history and np.any(history[name] != 0.0):
            ax.plot(history["t"], history[name], lw=2.0 if name == "E_total" else 1.2,
                    ls=":" if name in ("E_dissipated", "E_set_change") else "-", label=name)
    return _finish(fig, ax, path, "t [s]", "energy [J]", title)


def plot_snapshots(frames: list[tuple[float, list[np.ndarray]]], radii: list[float],
                   path: Path | None = None, title: str = "", obstacles=()) -> Figure:
    """A grid of snapshots of all beams' axes (paper Fig. 6); ``radii`` pad the view;
    the obstacles in grey.

    Every panel shows the same view, so the panels share their axes: tick labels on the
    outer panels only, and four ticks a side. matplotlib's cost here is its ticks (made,
    measured for the layout, drawn): these halve the figure's time (0.57 -> 0.30 s). The
    layout measures only what shows beside the panels, the axes with tick labels; the
    others and the spines (within the layout's padding either way) are left out of it,
    and the titles sit at a fixed height (an automatic one measures the panel's ticks in
    case they are on top, which they never are here); the bundled benchmark's figure then
    takes 0.39 s instead of 0.54 s (benchmarks/README.md, session 34). tests/test_plot.py
    checks that no label is clipped or overlaps another panel.
    """
    n = len(frames)
    cols = min(n, 3)
    rows = int(np.ceil(n / cols))
    lo, hi = _view([p for _, beams in frames for p in beams], obstacles)
    pad = 0.05 * max(hi - lo) + max(radii)
    fig = Figure(figsize=(4 * cols, 2.6 * rows))
    axes = fig.subplots(rows, cols, squeeze=False, sharex=True, sharey=True)
    for ax, (t, beams) in zip(axes.ravel(), frames, strict=False):
        for k, pts in enumerate(beams):
            ax.plot(pts[:, 0], pts[:, 1], lw=2.5, solid_capstyle="round",
                    color=colormaps["tab10"](k))
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        draw_obstacles(ax, obstacles, lo, hi)
        ax.set_aspect("equal")
        ax.set_title(f"t = {t:.3f} s", fontsize=9, y=1.0)
        ax.tick_params(labelsize=7)
        ax.locator_params(nbins=4)
    for k, ax in enumerate(axes.ravel()[:n]):
        ax.label_outer()
        lowest = k + cols >= n  # the lowest panel of its column: its x labels show
        if lowest:
            ax.tick_params(labelbottom=True)
        ax.xaxis.set_in_layout(lowest)
        ax.yaxis.set_in_layout(k % cols == 0)  # the first column's y labels show
        for spine in ax.spines.values():
            spine.set_in_layout(False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path, dpi=120)


def animate(frames: list[tuple[float, list[np.ndarray]]], path: Path, title: str = "",
            fps: int = 20, obstacles=()) -> None:
    """GIF of the beams' axes over time (the obstacles drawn once, in the background).

    matplotlib draws the axes, ticks and title once; every frame is that background with
    the beams drawn on it by Pillow, through the axes' data-to-pixel transform. Redrawing
    the whole figure per frame with matplotlib cost about 100 ms a frame (10 s for the
    100 frames of a default run); this costs a few ms. The background is reduced to a
    palette once, with the beam colours and black for the label added to it, and the
    frames are drawn in palette indices: quantising every frame cost 70 % of the time.
    The frames are written as they are (``optimize=False``): Pillow's search for a smaller
    palette and its remapping of each frame halved the time for a 25 % smaller file.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image, ImageDraw, ImageFont

    lo, hi = _view([p for _, beams in frames for p in beams], obstacles)
    pad = 0.05 * max(hi - lo)
    dpi = 80
    fig = Figure(figsize=(6, 4), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    draw_obstacles(ax, obstacles, lo, hi)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    canvas.draw()
    background = Image.frombuffer("RGBA", canvas.get_width_height(),
                                  canvas.buffer_rgba()).convert("RGB")
    height = background.height
    box = ax.get_window_extent()
    label_at = (box.x0 + 0.02 * box.width, height - (box.y0 + 0.95 * box.height))
    font = ImageFont.load_default(size=9 * dpi / 72)
    colours = [tuple(int(255 * c) for c in colormaps["tab10"](k)[:3])
               for k in range(len(frames[0][1]))] + [(0, 0, 0)]
    # the background's own colours first, then one index per beam and black
    n_own = 255 - len(colours)
    base = background.quantize(colors=min(64, n_own), method=Image.Quantize.MEDIANCUT)
    palette = base.getpalette()[:3 * n_own]
    palette += [0] * (3 * n_own - len(palette))
    for colour in colours:
        palette += list(colour)
    base.putpalette(palette)
    index = [n_own + k for k in range(len(colours))]
    width = max(1, round(3 * dpi / 72))  # matplotlib's lw = 3 points
    images = []
    for t, beams in frames:
        image = base.copy()
        draw = ImageDraw.Draw(image)
        for pts, colour in zip(beams, index[:-1], strict=True):
            xy = ax.transData.transform(pts)
            xy[:, 1] = height - xy[:, 1]  # Pillow's rows run downwards
            draw.line([tuple(p) for p in xy], fill=colour, width=width, joint="curve")
        draw.text(label_at, f"t = {t:.3f} s", fill=index[-1], font=font)
        images.append(image)
    images[0].save(path, save_all=True, append_images=images[1:],
                   duration=round(1000 / fps), loop=0, optimize=False)


def plot_overlay(curves: list[tuple[str, np.ndarray, np.ndarray]], path: Path | None,
                 xlabel: str, ylabel: str, title: str = "") -> Figure:
    """Several labelled curves on one axis (paper Figs. 7-10)."""
    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    for label, x, y in curves:
        ax.plot(x, y, lw=1.2, label=label)
    return _finish(fig, ax, path, xlabel, ylabel, title)


def plot_run_overlay(runs: list[tuple[str, dict[str, np.ndarray]]], column: str,
                     path: Path | None, title: str = "") -> Figure:
    """One history column of several labelled runs against time or load factor."""
    abscissa = "t" if "t" in runs[0][1] else "load_factor"
    named = {"min_gap": "smallest gap [m]", "E_total": "total energy E_total [J]"}
    ylabel = named.get(column) or f"{column.rsplit('_', 1)[0]} {column.rsplit('_', 1)[-1]} [m]"
    return plot_overlay([(label, h[abscissa], h[column]) for label, h in runs], path,
                 "t [s]" if abscissa == "t" else "load factor", ylabel, title)
