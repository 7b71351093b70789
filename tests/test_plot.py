"""The figures of a run (beamcontact/plot.py): what they show, not how they look."""

import numpy as np
from matplotlib import colormaps
from PIL import Image

from beamcontact.plot import animate


def _pixels_of(frame: Image.Image, colour: tuple[int, int, int]) -> np.ndarray:
    """(row, column) of the pixels of one RGB colour in a frame."""
    rgb = np.asarray(frame.convert("RGB")).astype(int)
    return np.argwhere(np.all(rgb == colour, axis=-1))


def test_animation_frames_follow_the_beams(tmp_path):
    """One frame per instant, each beam in its tab10 colour, and a beam that falls is
    drawn lower (further down the image) frame after frame while the other stays."""
    x = np.linspace(0.0, 10.0, 50)
    still = np.c_[x, np.zeros_like(x)]
    drops = [0.0, 0.5, 1.0, 1.5]
    frames = [(0.1 * k, [still, np.c_[x[10:40], np.full(30, 2.0 - d)]])
              for k, d in enumerate(drops)]
    path = tmp_path / "a.gif"
    animate(frames, path, "falling")
    blue, orange = ([int(255 * c) for c in colormaps["tab10"](k)[:3]] for k in range(2))
    with Image.open(path) as gif:
        assert gif.n_frames == len(drops)
        rows = {"still": [], "falling": []}
        for k in range(gif.n_frames):
            gif.seek(k)
            frame = gif.copy()
            for name, colour in (("still", tuple(blue)), ("falling", tuple(orange))):
                pixels = _pixels_of(frame, colour)
                assert pixels.shape[0] > 20, (k, name)
                rows[name].append(pixels[:, 0].mean())
    assert np.ptp(rows["still"]) < 1.0
    assert np.all(np.diff(rows["falling"]) > 5.0)


def test_snapshot_panels_keep_their_labels_clear(tmp_path):
    """The grid of snapshots (its layout measures the outer panels' labels only): every
    title and shown tick label lies within the figure and clear of every other panel, for
    full and partial grids, wide and tall views, and the offset labels of micrometre
    coordinates."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from beamcontact.plot import plot_snapshots

    x = np.linspace(0.0, 10.0, 40)
    for scale, count, tall in ((1.0, 9, False), (1.0, 4, False), (1.0, 2, False),
                               (1e-6, 5, False), (1.0, 9, True), (1e-6, 4, True)):
        frames = [(0.25 * k, [scale * np.c_[x, np.sin(x + k)],
                              scale * np.c_[x[10:30], 2.0 + np.zeros(20)]])
                  for k in range(count)]
        if tall:  # the panels' height sets their size, not their width
            frames = [(t, [b[:, ::-1] for b in beams]) for t, beams in frames]
        fig = plot_snapshots(frames, [0.1 * scale, 0.1 * scale], tmp_path / "s.png", "title")
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
        page = fig.bbox
        panels = [ax for ax in fig.axes if ax.axison]
        assert len(panels) == count
        boxes = [ax.get_window_extent(renderer) for ax in panels]
        for i, ax in enumerate(panels):
            (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
            texts = [ax.title] + [  # the labels drawn: those of ticks within the view
                t for t in ax.get_xticklabels() if x0 <= t.get_position()[0] <= x1
            ] + [t for t in ax.get_yticklabels() if y0 <= t.get_position()[1] <= y1]
            texts = [t for t in texts if t.get_visible() and t.get_text()]
            for text in texts:
                box = text.get_window_extent(renderer)
                assert page.x0 <= box.x0 and box.x1 <= page.x1, (scale, count, text)
                assert page.y0 <= box.y0 and box.y1 <= page.y1, (scale, count, text)
                for j, other in enumerate(boxes):
                    assert j == i or not box.overlaps(other), (scale, count, i, j, text)
