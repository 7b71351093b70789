"""Outlines of the rigid obstacles (case ``[[obstacles]]``) for figures and ParaView: a
wall as a segment of its surface line across a region of interest, a circle as a closed
polygon (:mod:`beamcontact.contact.obstacles` holds their mechanics)."""

import numpy as np

CIRCLE_SIDES = 128


def obstacle_outlines(obstacles, lo, hi) -> list[tuple[str, np.ndarray]]:
    """(name, polyline (n, 2)) of every obstacle; a wall's segment is centred on the
    point of its line closest to the middle of the box [lo, hi] and three times the box's
    diagonal long, so that it crosses any view of the box."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre, size = 0.5 * (lo + hi), max(float(np.linalg.norm(hi - lo)), 1e-12)
    out = []
    for o in obstacles:
        if o.circle is not None:
            phi = np.linspace(0.0, 2.0 * np.pi, CIRCLE_SIDES + 1)
            ring = np.asarray(o.circle.center) + o.circle.radius * np.column_stack(
                [np.cos(phi), np.sin(phi)])
            out.append((o.name, ring))
            continue
        p = np.asarray(o.wall.point, float)
        n = np.asarray(o.wall.normal, float) / np.hypot(*o.wall.normal)
        t = np.array([-n[1], n[0]])
        foot = p + t * float(t @ (centre - p))
        out.append((o.name, np.array([foot - 1.5 * size * t, foot + 1.5 * size * t])))
    return out


def solid_side(obstacle, outline: np.ndarray) -> np.ndarray:
    """The polygon to shade for a wall: its segment and the same segment moved by the
    segment's length into the solid; a circle's own outline."""
    if obstacle.circle is not None:
        return outline
    n = np.asarray(obstacle.wall.normal, float) / np.hypot(*obstacle.wall.normal)
    depth = np.linalg.norm(outline[1] - outline[0])
    return np.array([outline[0], outline[1], outline[1] - depth * n, outline[0] - depth * n])
