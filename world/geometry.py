"""Plain 2-D geometry helpers for scenario shapes (no pymunk, no numpy needed).

Polygons are lists of ``(x, y)`` tuples. "CCW" means counter-clockwise, i.e. positive
signed area. Everything here is exact (no tolerance-based approximation), so a
scenario always produces the same shapes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from cekm_swarm.angles import wrap_scalar

Point = tuple[float, float]
Poly = list[Point]

TAU = 2.0 * math.pi


wrap_angle = wrap_scalar  # to (-pi, pi], the project's one formula (cekm_swarm.angles)


def signed_area(poly: Sequence[Point]) -> float:
    """Shoelace signed area (positive for CCW)."""
    s = 0.0
    n = len(poly)
    for i in range(n):
        x1, y1 = poly[i]
        x2, y2 = poly[(i + 1) % n]
        s += x1 * y2 - x2 * y1
    return 0.5 * s


def ccw(poly: Sequence[Point]) -> Poly:
    """The polygon with counter-clockwise winding."""
    p = [(float(x), float(y)) for x, y in poly]
    return p if signed_area(p) > 0 else p[::-1]


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _segments_intersect(p1: Point, p2: Point, q1: Point, q2: Point) -> bool:
    """Closed-segment intersection test (touching counts)."""
    d1 = _cross(q1, q2, p1)
    d2 = _cross(q1, q2, p2)
    d3 = _cross(p1, p2, q1)
    d4 = _cross(p1, p2, q2)
    if ((d1 > 0 and d2 < 0) or (d1 < 0 and d2 > 0)) and ((d3 > 0 and d4 < 0) or (d3 < 0 and d4 > 0)):
        return True

    def on_seg(a: Point, b: Point, c: Point) -> bool:
        return min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1])

    if d1 == 0 and on_seg(q1, q2, p1):
        return True
    if d2 == 0 and on_seg(q1, q2, p2):
        return True
    if d3 == 0 and on_seg(p1, p2, q1):
        return True
    return d4 == 0 and on_seg(p1, p2, q2)


def simple_polygon_problem(poly: Sequence[Point]) -> str | None:
    """Why ``poly`` is not a simple polygon with non-zero area, or None if it is."""
    n = len(poly)
    if n < 3:
        return f"needs at least 3 vertices, got {n}"
    for i in range(n):
        if poly[i] == poly[(i + 1) % n]:
            return f"vertices {i} and {(i + 1) % n} coincide"
    for i in range(n):
        a1, a2 = poly[i], poly[(i + 1) % n]
        for j in range(i + 1, n):
            if j == i or (j + 1) % n == i or j == (i + 1) % n:
                continue  # adjacent edges share a vertex
            b1, b2 = poly[j], poly[(j + 1) % n]
            if _segments_intersect(a1, a2, b1, b2):
                return f"edges {i} and {j} intersect (the polygon must be simple)"
    if abs(signed_area(poly)) < 1e-12:
        return "has zero area"
    return None


def is_convex(poly: Sequence[Point]) -> bool:
    """True if the CCW polygon is convex (collinear vertices allowed)."""
    n = len(poly)
    return all(_cross(poly[i], poly[(i + 1) % n], poly[(i + 2) % n]) >= -1e-15 for i in range(n))


def _point_in_triangle(p: Point, a: Point, b: Point, c: Point) -> bool:
    return _cross(a, b, p) >= 0 and _cross(b, c, p) >= 0 and _cross(c, a, p) >= 0


def triangulate(poly: Sequence[Point]) -> list[Poly]:
    """Ear-clipping triangulation of a simple CCW polygon."""
    idx = list(range(len(poly)))
    tris: list[Poly] = []
    guard = 0
    while len(idx) > 3:
        guard += 1
        if guard > 10000:  # pragma: no cover - only for degenerate input
            raise ValueError("triangulation failed")
        m = len(idx)
        for k in range(m):
            i0, i1, i2 = idx[(k - 1) % m], idx[k], idx[(k + 1) % m]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if _cross(a, b, c) <= 1e-15:
                continue  # reflex or collinear vertex, not an ear
            if any(
                _point_in_triangle(poly[j], a, b, c)
                for j in idx
                if j not in (i0, i1, i2)
            ):
                continue
            tris.append([a, b, c])
            del idx[k]
            break
        else:  # pragma: no cover - only collinear leftovers
            break
    if len(idx) == 3:
        a, b, c = (poly[i] for i in idx)
        if abs(_cross(a, b, c)) > 1e-15:
            tris.append([a, b, c])
    return tris


def _try_merge(p: Poly, q: Poly) -> Poly | None:
    """Merge two CCW convex polygons sharing an edge if the union is convex."""
    for i in range(len(p)):
        a, b = p[i], p[(i + 1) % len(p)]
        for j in range(len(q)):
            if q[j] == b and q[(j + 1) % len(q)] == a:
                merged = p[: i + 1] + [q[(j + k) % len(q)] for k in range(2, len(q))] + p[i + 1 :]
                return merged if is_convex(merged) else None
    return None


def convex_parts(poly: Sequence[Point]) -> list[Poly]:
    """Exact convex decomposition of a simple polygon (ear clipping, then greedy
    Hertel-Mehlhorn merging of triangles). Returns CCW convex polygons."""
    p = ccw(poly)
    if is_convex(p):
        return [p]
    parts = triangulate(p)
    changed = True
    while changed:
        changed = False
        for i in range(len(parts)):
            for j in range(i + 1, len(parts)):
                m = _try_merge(parts[i], parts[j])
                if m is not None:
                    parts[i] = m
                    del parts[j]
                    changed = True
                    break
            if changed:
                break
    return parts


def transform(poly: Sequence[Point], center: Point, angle: float) -> Poly:
    """Rotate local vertices by ``angle`` and translate by ``center``."""
    c, s = math.cos(angle), math.sin(angle)
    cx, cy = center
    return [(cx + c * x - s * y, cy + s * x + c * y) for x, y in poly]


def box_local(width: float, height: float) -> Poly:
    """CCW rectangle centred at the origin."""
    w, h = 0.5 * width, 0.5 * height
    return [(-w, -h), (w, -h), (w, h), (-w, h)]


def wall_outline(a: Point, b: Point, thickness: float) -> Poly:
    """CCW rectangle of a wall: the segment a-b widened by thickness/2 on each side
    (square ends, no extension beyond a and b)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length = math.hypot(dx, dy)
    nx, ny = -dy / length * 0.5 * thickness, dx / length * 0.5 * thickness
    return ccw([(a[0] - nx, a[1] - ny), (b[0] - nx, b[1] - ny), (b[0] + nx, b[1] + ny), (a[0] + nx, a[1] + ny)])


def concave_local(width: float, depth: float, thickness: float) -> tuple[Poly, list[Poly]]:
    """A U-shaped obstacle in its local frame: the opening faces +x, the mouth (the
    line between the tips of the two arms) is centred on the origin, the cavity is
    ``width`` wide (inner) and ``depth`` deep (inner), walls ``thickness`` thick.

    Returns (outline, convex parts): the outline is the CCW concave polygon, the parts
    are the back wall and the two arms as rectangles.
    """
    w2, t, d = 0.5 * width, thickness, depth
    outline = [
        (0.0, -w2 - t),
        (0.0, -w2),
        (-d, -w2),
        (-d, w2),
        (0.0, w2),
        (0.0, w2 + t),
        (-d - t, w2 + t),
        (-d - t, -w2 - t),
    ]
    back = [(-d - t, -w2 - t), (-d, -w2 - t), (-d, w2 + t), (-d - t, w2 + t)]
    lower = [(-d, -w2 - t), (0.0, -w2 - t), (0.0, -w2), (-d, -w2)]
    upper = [(-d, w2), (0.0, w2), (0.0, w2 + t), (-d, w2 + t)]
    return ccw(outline), [back, lower, upper]


def disc_outline(center: Point, radius: float, n: int = 32) -> Poly:
    """A regular n-gon approximating a disc (for drawing only)."""
    return [
        (center[0] + radius * math.cos(TAU * k / n), center[1] + radius * math.sin(TAU * k / n))
        for k in range(n)
    ]
