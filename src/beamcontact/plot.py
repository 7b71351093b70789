"""Figures: deformed shapes and histories of the output points (matplotlib, Agg)."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_shapes(shapes: list[tuple[str, list[np.ndarray]]], reference: list[np.ndarray],
                path: Path, title: str = "") -> None:
    """Axes of all beams: reference dashed, then one colour per labelled state."""
    fig, ax = plt.subplots(figsize=(7, 5))
    for k, pts in enumerate(reference):
        ax.plot(pts[:, 0], pts[:, 1], "k--", lw=0.8, label="reference" if k == 0 else None)
    cmap = plt.get_cmap("viridis")
    for i, (label, beams) in enumerate(shapes):
        colour = cmap(i / max(len(shapes) - 1, 1))
        for k, pts in enumerate(beams):
            ax.plot(pts[:, 0], pts[:, 1], color=colour, lw=1.5, label=label if k == 0 else None)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if len(shapes) <= 12:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def plot_point_histories(history: dict[str, np.ndarray], abscissa: str, points: list[str],
                         path: Path, title: str = "") -> None:
    """Displacements u_x, u_y of every output point against ``abscissa``."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for name in points:
        for comp, style in (("ux", "--"), ("uy", "-")):
            ax.plot(history[abscissa], history[f"{name}_{comp}"], style, label=f"{name} {comp}")
    ax.set_xlabel({"t": "t [s]", "load_factor": "load factor"}.get(abscissa, abscissa))
    ax.set_ylabel("displacement [m]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def plot_energies(history: dict[str, np.ndarray], path: Path, title: str = "") -> None:
    """Kinetic, strain, gravity and total energy against time."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for name in ("E_kin", "E_strain", "E_gravity", "E_ext", "E_total"):
        if name in history and np.any(history[name] != 0.0):
            ax.plot(history["t"], history[name], lw=2.0 if name == "E_total" else 1.2,
                    label=name)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("energy [J]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
