"""Kernel of the pictures' depth test: the body's surface nearest the viewer, cell by cell (a z-buffer).

The caller (:mod:`hairinv.export.picture`) projects the body orthographically, allocates the grid filled
with ``-inf`` and reads it; nothing here allocates, raises or prints.
"""

from __future__ import annotations

import math

from .._jit import jit

# Barycentric weights down to -EDGE count as inside: a cell centre on the edge shared by two triangles
# is covered by both, so no crack opens between them.
EDGE = 1e-12


@jit
def nearest_depth(xy, depth, faces, x0, y0, cell, out):
    """The largest depth (nearest the viewer) of the triangles covering each cell centre.

    Parameters
    ----------
    xy : (V, 2) float64, m, the vertices' screen coordinates
    depth : (V,) float64, m, the vertices' depth towards the viewer
    faces : (T, 3) int64, vertex indices
    x0, y0 : float, m, the grid's lower-left corner; cell ``(j, i)`` has its centre at
        ``(x0 + (i + 0.5) cell, y0 + (j + 0.5) cell)``
    cell : float, m, > 0
    out : (ny, nx) float64, filled with ``-inf`` by the caller; raised in place to the depth of the surface
        at each covered cell centre, interpolated linearly over the triangle

    Returns
    -------
    int, the number of (triangle, cell) pairs written: 0 when no triangle covers a cell centre.
    """
    ny, nx = out.shape
    written = 0
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, bx, by, cx, cy = xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], xy[c, 0], xy[c, 1]
        area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if area == 0.0:  # seen edge-on: covers no area
            continue
        i0 = max(0, int(math.ceil((min(ax, bx, cx) - x0) / cell - 0.5)))
        i1 = min(nx - 1, int(math.floor((max(ax, bx, cx) - x0) / cell - 0.5)))
        j0 = max(0, int(math.ceil((min(ay, by, cy) - y0) / cell - 0.5)))
        j1 = min(ny - 1, int(math.floor((max(ay, by, cy) - y0) / cell - 0.5)))
        for j in range(j0, j1 + 1):
            py = y0 + (j + 0.5) * cell
            for i in range(i0, i1 + 1):
                px = x0 + (i + 0.5) * cell
                wa = ((bx - px) * (cy - py) - (cx - px) * (by - py)) / area
                wb = ((cx - px) * (ay - py) - (ax - px) * (cy - py)) / area
                wc = 1.0 - wa - wb
                if wa >= -EDGE and wb >= -EDGE and wc >= -EDGE:
                    d = wa * depth[a] + wb * depth[b] + wc * depth[c]
                    if d > out[j, i]:
                        out[j, i] = d
                    written += 1
    return written
