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
