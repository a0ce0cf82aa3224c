"""Generate ringtune's test part as an ASCII STL (pure numpy, deterministic): ``python make_part.py [OUT]``.

The part (mm; X 0–60, Y 0–20, Z 0–20; Y−: front):

- a block 60 × 20 mm whose front and back walls are straight for 50 mm, square at the left end and
  rounded at the right (a half cylinder of radius 10 mm in 48 facets: the curve a slicer writes as
  short segments);
- two vertical through holes, Ø 10 mm at (15, 10) and Ø 6 mm at (45, 10);
- from Z 12 to 20 the block carries on and a shelf sticks out 8 mm behind it (X 10–40, Y 20–28):
  a horizontal overhang, printed as bridges and overhang perimeters.

How the surface is built (watertight, every edge shared by exactly two triangles): the footprint is
two cells, X 0–30 and X 30–60, each star-shaped around its hole; a cell's top and bottom are quads
between each outline vertex and the hole vertex at the same angle; walls are quads between
outline rings at Z 0, 12 and 20. Straight edges are divided every 2 mm at points that do not depend
on which way the edge is walked, so the cells and the shelf share the vertices of their common
edges.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

W, D = 60.0, 20.0          # footprint, mm
Z_SHELF, Z_TOP = 12.0, 20.0
R_CORNER, N_CORNER = 10.0, 24  # the right end: a half cylinder of 2 × 24 facets
HOLES = (((15.0, 10.0), 5.0), ((45.0, 10.0), 3.0))   # centre, radius mm
SHELF = (10.0, 40.0, 8.0)   # X from, X to, depth behind the back wall (mm)


STEP = 2.0                 # mm between outline points on straight edges (the holes' facets follow)


def _arc(cx, cy, r, a0, a1, n):
    """n + 1 points on the arc of radius r (mm) about (cx, cy) from angle a0 to a1 (rad)."""
    a = np.linspace(a0, a1, n + 1)
    return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])


def _edge(p, q) -> np.ndarray:
    """Points from ``p`` up to (not including) ``q``, evenly every ≤ STEP mm: the same points
    whichever way the edge is walked, so two cells sharing it share its vertices."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    n = max(1, int(np.ceil(np.linalg.norm(q - p) / STEP - 1e-9)))
    return p + (q - p) * (np.arange(n) / n)[:, None]


def _polyline(corners) -> np.ndarray:
    """A closed outline through ``corners`` with its straight edges divided by :func:`_edge`."""
    return np.vstack([_edge(p, q) for p, q in zip(corners, corners[1:] + corners[:1])])


def cell_outlines() -> list[np.ndarray]:
    """The two cells' outlines, counter-clockwise seen from above, sharing the edge X = 30 and the
    shelf's edge on Y = D."""
    x0, x1, _ = SHELF
    left = _polyline([(0, 0), (30, 0), (30, D), (x0, D), (0, D)])
    cx, cy = W - R_CORNER, D / 2
    right = np.vstack([_edge((30, 0), (cx, 0)),
                       _arc(cx, cy, R_CORNER, -np.pi / 2, np.pi / 2, 2 * N_CORNER)[:-1],
                       _edge((cx, D), (x1, D)), _edge((x1, D), (30, D)), _edge((30, D), (30, 0))])
    return [left, right]


def _ring(outline: np.ndarray, centre, radius) -> np.ndarray:
    """The hole's points at the angles of the outline's points (same count)."""
    a = np.arctan2(outline[:, 1] - centre[1], outline[:, 0] - centre[0])
    return np.column_stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)])


def _v(p, z):
    return (float(p[0]), float(p[1]), float(z))


def triangles() -> np.ndarray:
    """(T, 3, 3) triangles of the part, counter-clockwise seen from outside."""
    tris: list = []

    def quad(a, b, c, d):
        tris.extend([(a, b, c), (a, c, d)])

    for outline, (centre, radius) in zip(cell_outlines(), HOLES):
        hole = _ring(outline, centre, radius)
        for i in range(len(outline)):
            j = (i + 1) % len(outline)
            o0, o1, h0, h1 = outline[i], outline[j], hole[i], hole[j]
            quad(_v(o0, Z_TOP), _v(o1, Z_TOP), _v(h1, Z_TOP), _v(h0, Z_TOP))     # top
            quad(_v(o0, 0), _v(h0, 0), _v(h1, 0), _v(o1, 0))                     # bottom
            quad(_v(h0, 0), _v(h0, Z_TOP), _v(h1, Z_TOP), _v(h1, 0))             # hole wall
            _outer_wall(o0, o1, quad)
    _shelf(quad)
    return np.array(tris, float)


def _outer_wall(p, q, quad) -> None:
    """The wall on outline edge p→q, unless it lies between the two cells (X = 30) or, above
    Z_SHELF, under the shelf's attachment."""
    x0, x1, _ = SHELF
    if np.isclose(p[0], 30) and np.isclose(q[0], 30):
        return
    attached = np.isclose(p[1], D) and np.isclose(q[1], D) and x0 - 1e-9 <= min(p[0], q[0]) \
        and max(p[0], q[0]) <= x1 + 1e-9
    for z0, z1 in ((0.0, Z_SHELF), (Z_SHELF, Z_TOP)):
        if not (attached and z0 == Z_SHELF):
            quad(_v(p, z0), _v(q, z0), _v(q, z1), _v(p, z1))


def _shelf(quad) -> None:
    """The shelf behind the back wall: top, underside (the overhang), and its three walls; its
    edge on the back wall has the cells' points (X from x1 down to x0)."""
    x0, x1, depth = SHELF
    y1 = D + depth
    xs = np.concatenate([_edge((x1, D), (30, D))[:, 0], _edge((30, D), (x0, D))[:, 0], [x0]])   # x1 -> x0
    for a, b in zip(xs[:-1], xs[1:]):                    # strips from the back wall to the far edge
        quad(_v((a, D), Z_TOP), _v((a, y1), Z_TOP), _v((b, y1), Z_TOP), _v((b, D), Z_TOP))
        quad(_v((a, D), Z_SHELF), _v((b, D), Z_SHELF), _v((b, y1), Z_SHELF), _v((a, y1), Z_SHELF))
        quad(_v((a, y1), Z_SHELF), _v((b, y1), Z_SHELF), _v((b, y1), Z_TOP), _v((a, y1), Z_TOP))   # far wall
    for p, q in (((x1, D), (x1, y1)), ((x0, y1), (x0, D))):   # side walls
        quad(_v(p, Z_SHELF), _v(q, Z_SHELF), _v(q, Z_TOP), _v(p, Z_TOP))


def stl_text(tris: np.ndarray, name: str = "ringtune_part") -> str:
    """ASCII STL of ``tris`` with each facet's unit normal."""
    lines = [f"solid {name}"]
    for t in tris:
        n = np.cross(t[1] - t[0], t[2] - t[0])
        n = n / np.linalg.norm(n)
        lines.append(f"  facet normal {n[0]:.6e} {n[1]:.6e} {n[2]:.6e}\n    outer loop")
        lines.extend(f"      vertex {v[0]:.6f} {v[1]:.6f} {v[2]:.6f}" for v in t)
        lines.append("    endloop\n  endfacet")
    lines.append(f"endsolid {name}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("ringtune_part.stl")
    out.write_text(stl_text(triangles()))
    print(f"wrote {out}")
