"""Loop subdivision of a triangle mesh as pbrt does it, vectorised over faces, edges and vertices.

pbrt-v2 and pbrt-v3 ``src/shapes/loopsubdiv.cpp`` and pbrt-v4 ``src/pbrt/util/loopsubdiv.cpp``
(``LoopSubdivide``) refine the control mesh ``levels`` times, splitting each triangle into four:

- an odd (new) vertex on an interior edge (a, b) between triangles whose third points are c and d
  is 3/8 (a + b) + 1/8 (c + d); on a boundary edge it is the midpoint 1/2 (a + b);
- an even (old) interior vertex v of valence n moves to (1 - n beta) v + beta * (sum of its n
  neighbours) with Warren's beta: 3/16 for n = 3, 3 / (8 n) otherwise (pbrt's ``beta``; its
  "regular" vertices, n = 6, take 1/16, the same number); an even boundary vertex moves to
  3/4 v + 1/8 (a + b), a and b its neighbours along the boundary (pbrt's ``weightBoundary`` with
  1/8). Boundaries therefore follow the cubic B-spline's subdivision rules and depend on boundary
  points alone.

After the last level every vertex is pushed to its limit position: interior ones by the same mask
with chi = 1 / (n + 3 / (8 beta)) in place of beta (pbrt's ``loopGamma``), boundary ones by
3/5 v + 1/5 (a + b) (pbrt's ``weightBoundary`` with 1/5; the cubic B-spline's own limit mask is
1/6, 2/3, 1/6, so pbrt's boundary points lie off the limit curve by a fraction of a level's second
difference, kept here to give pbrt's surface). The normal at each vertex is the cross product of
two tangents pbrt computes on its ordered one-ring of limit points: sum_j cos(2 pi j / n) p_j and
sum_j sin(2 pi j / n) p_j inside, and Hoppe et al.'s boundary masks (per valence 2, 3, 4 and
more) on the boundary. Its ring runs around each vertex the way pbrt's ``nextFace`` walks, so the
normals point against the faces' counter-clockwise winding normal (pbrt's limit normals point out
of a mesh whose faces run clockwise seen from outside; pbrt's triangles then face their normals).

pbrt links each triangle to the others through a set of edges holding two triangles at most and
trusts the mesh to be manifold and consistently wound: a third triangle on an edge starts a new,
unpaired edge and the one-ring walks then describe a different surface than the file's, without
a message. Here such a mesh is a one-line ``UserError`` (an edge with three or more triangles,
one run the same way by both its triangles, a triangle repeating a point, or a point whose
triangles do not form one fan around it). Points no triangle uses are dropped (pbrt's walk would
start from a missing face).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from realistic.errors import UserError

#: The most triangles one subdivision makes (4^levels times the control mesh's); the caller lowers
#: the levels to stay under it, as a billion triangles would exhaust memory rather than render.
MAX_TRIANGLES = 1 << 24


@dataclass(frozen=True)
class Subdivided:
    """A subdivided mesh: limit points (V, 3), triangles (F, 3) and pbrt's unit limit normals (V, 3)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray


@dataclass(frozen=True)
class _Topology:
    """One level's edges: ``edges`` (E, 2) endpoints, ``edge_of`` (3F,) the edge under half-edge
    3 f + k (from corner k of face f to corner k + 1), ``twin`` (3F,) the half-edge running the
    other way along the same edge or -1 on the boundary, ``boundary`` (E,) edges with one face."""

    edges: np.ndarray
    edge_of: np.ndarray
    twin: np.ndarray
    boundary: np.ndarray


def levels_that_fit(triangles: int, levels: int) -> int:
    """The largest number of levels, at most ``levels``, whose 4^levels x ``triangles`` stays
    within ``MAX_TRIANGLES`` (0 when even the control mesh does not)."""
    fitting = 0
    while fitting < levels and triangles * 4 ** (fitting + 1) <= MAX_TRIANGLES:
        fitting += 1
    return fitting


def loop_subdivide(vertices: np.ndarray, faces: np.ndarray, levels: int) -> Subdivided:
    """The control mesh (points (N, 3), triangles (M, 3) of point numbers) subdivided ``levels``
    times and pushed to its limit surface, with pbrt's limit normals (the module docstring)."""
    points, triangles = refine(vertices, faces, levels)
    topology = _topology(triangles, len(points))
    limit = _limit_points(points, topology)
    return Subdivided(limit, triangles, _limit_normals(limit, triangles, topology))


def refine(vertices: np.ndarray, faces: np.ndarray, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """The control mesh subdivided ``levels`` times without the push to the limit: the first points
    are the control points' descendants, in order (less those no triangle uses), and converge to
    their limit positions."""
    points, triangles = _checked(vertices, faces)
    for _ in range(levels):
        points, triangles = _refine_once(points, triangles, _topology(triangles, len(points)))
    return points, triangles


def _checked(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The used points and the triangles renumbered onto them, after the manifold checks (their
    messages name the caller's point and triangle numbers)."""
    points = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    triangles = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    repeats = (triangles[:, 0] == triangles[:, 1]) | (triangles[:, 1] == triangles[:, 2]) | \
              (triangles[:, 2] == triangles[:, 0])
    if np.any(repeats):
        bad = int(np.argmax(repeats))
        raise UserError(f"loopsubdiv triangle {bad} ({' '.join(map(str, triangles[bad]))}) uses a point twice")
    used, compact = np.unique(triangles, return_inverse=True)
    triangles = compact.reshape(-1, 3)
    topology = _topology(triangles, len(used))
    counts = np.bincount(topology.edge_of, minlength=len(topology.edges))
    if np.any(counts > 2):
        bad = int(np.argmax(counts))
        a, b = used[topology.edges[bad]]
        raise UserError(f"loopsubdiv is not manifold: the edge between points {a} and {b} is shared by "
                        f"{counts[bad]} triangles (at most 2)")
    starts = triangles.ravel()
    same_way = (topology.twin >= 0) & (starts == starts[np.maximum(topology.twin, 0)])
    if np.any(same_way):
        a, b = used[topology.edges[topology.edge_of[int(np.argmax(same_way))]]]
        raise UserError(f"loopsubdiv triangles are not wound consistently: both triangles on the edge between "
                        f"points {a} and {b} run it the same way")
    fans = _fans(triangles, topology, len(used))
    if fans.broken is not None:
        raise UserError(f"loopsubdiv is not manifold: the triangles around point {used[fans.broken]} do not "
                        f"form one fan")
    return points[used], triangles


def _topology(faces: np.ndarray, n_points: int) -> _Topology:
    """Edges, each half-edge's edge and twin, from the (F, 3) triangles of ``n_points`` points."""
    start = faces.ravel()
    end = np.roll(faces, -1, axis=1).ravel()
    key = np.minimum(start, end) * n_points + np.maximum(start, end)
    # half-edges sorted by edge: the two of an edge with two faces sit side by side
    order = np.argsort(key, kind="stable")
    ordered = key[order]
    first = np.flatnonzero(np.concatenate([[True], ordered[1:] != ordered[:-1]]))
    counts = np.diff(np.append(first, len(key)))
    edge_of = np.empty(len(key), dtype=np.int64)
    edge_of[order] = np.repeat(np.arange(len(first)), counts)
    edges = np.column_stack([ordered[first] // n_points, ordered[first] % n_points])
    paired = first[counts == 2]
    twin = np.full(len(start), -1, dtype=np.int64)
    twin[order[paired]], twin[order[paired + 1]] = order[paired + 1], order[paired]
    return _Topology(edges, edge_of, twin, counts == 1)


def _refine_once(points: np.ndarray, faces: np.ndarray, topology: _Topology) -> tuple[np.ndarray, np.ndarray]:
    """One level: the even points (moved), then one odd point per edge, and four triangles per
    triangle in pbrt's order (the corner children 0, 1, 2 and the middle one)."""
    a, b = topology.edges.T
    opposite = np.roll(faces, -2, axis=1).ravel()  # the third point of each half-edge's triangle
    across = _sum_by(topology.edge_of, points[opposite], len(a))
    odd = np.where(topology.boundary[:, None], 0.5 * (points[a] + points[b]),
                   0.375 * (points[a] + points[b]) + 0.125 * across)
    even = _even_or_limit(points, topology, boundary_weight=1 / 8, interior=_beta)
    v0, v1, v2 = faces.T
    e0, e1, e2 = (len(points) + topology.edge_of).reshape(-1, 3).T
    children = np.stack([np.column_stack([v0, e0, e2]), np.column_stack([e0, v1, e1]),
                         np.column_stack([e2, e1, v2]), np.column_stack([e0, e1, e2])], axis=1)
    return np.vstack([even, odd]), children.reshape(-1, 3)


def _beta(valence: np.ndarray) -> np.ndarray:
    """Warren's even-vertex weight (pbrt's ``beta``)."""
    return np.where(valence == 3, 3 / 16, 3 / (8 * np.maximum(valence, 1)))


def _chi(valence: np.ndarray) -> np.ndarray:
    """The limit weight for the same scheme (pbrt's ``loopGamma``)."""
    return 1 / (valence + 3 / (8 * _beta(valence)))


def _even_or_limit(points: np.ndarray, topology: _Topology, boundary_weight: float,
                   interior: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """(1 - n w) v + w * sum of neighbours inside (w = ``interior(n)``), (1 - 2 b) v + b (a + c)
    on the boundary (b = ``boundary_weight``, a and c the boundary neighbours)."""
    a, b = topology.edges.T
    ends = np.concatenate([a, b])
    others = points[np.concatenate([b, a])]
    valence = np.bincount(ends, minlength=len(points))
    around = _sum_by(ends, others, len(points))
    rim = np.concatenate([topology.boundary, topology.boundary])
    on_rim = np.bincount(ends[rim], minlength=len(points)) > 0
    along = _sum_by(ends[rim], others[rim], len(points))
    w = interior(valence)[:, None]
    return np.where(on_rim[:, None], (1 - 2 * boundary_weight) * points + boundary_weight * along,
                    (1 - valence[:, None] * w) * points + w * around)


def _limit_points(points: np.ndarray, topology: _Topology) -> np.ndarray:
    """pbrt's push of every point to the limit surface."""
    return _even_or_limit(points, topology, boundary_weight=1 / 5, interior=_chi)


def _sum_by(index: np.ndarray, values: np.ndarray, length: int) -> np.ndarray:
    """Rows of ``values`` (K, 3) summed into ``length`` rows by ``index`` (K,)."""
    return np.column_stack([np.bincount(index, weights=values[:, i], minlength=length) for i in range(3)])


@dataclass(frozen=True)
class _Fans:
    """The corners (3 f + k: corner k of face f) around each point in the order pbrt's one-ring
    walks them: ``corner`` (C,), its point ``owner`` and place ``step``; ``boundary`` (N,) points on
    the boundary, whose walk starts at the corner with no face across its outgoing edge and goes
    the other way; ``broken`` a point whose corners do not form one fan, or None."""

    corner: np.ndarray
    owner: np.ndarray
    step: np.ndarray
    boundary: np.ndarray
    broken: int | None


def _fans(faces: np.ndarray, topology: _Topology, n_points: int) -> _Fans:
    """Every point's fan walked at once, one step per numpy operation over the points still walking
    (as many steps as the largest number of triangles at a point)."""
    owner_of = faces.ravel()
    corners = np.arange(len(owner_of))
    twin = topology.twin
    # pbrt's nextFace: across the edge to the next point; prevFace: across the edge from the previous
    after = np.where(twin >= 0, 3 * (twin // 3) + (twin % 3 + 1) % 3, -1)
    before = twin[3 * (corners // 3) + (corners % 3 + 2) % 3]
    count = np.bincount(owner_of, minlength=n_points)
    ends = corners[after < 0]
    ends_at = np.bincount(owner_of[ends], minlength=n_points)
    if np.any(ends_at > 1):
        return _Fans(corners[:0], corners[:0], corners[:0], ends_at > 0, int(np.argmax(ends_at > 1)))
    boundary = ends_at == 1
    _, start = np.unique(owner_of, return_index=True)
    start[owner_of[ends]] = ends
    order = np.argsort(-count, kind="stable")
    descending = count[order]
    origin = start[order]
    current, walks_back = origin.copy(), boundary[order]
    pieces: list[tuple[np.ndarray, np.ndarray, int]] = []
    for step in range(int(descending[0]) if len(descending) else 0):
        m = int(np.searchsorted(-descending, -step, side="left"))  # the points with more than `step` corners
        here = current[:m].copy()
        pieces.append((here, order[:m], step))
        following = np.where(walks_back[:m], before[here], after[here])
        done = descending[:m] == step + 1
        closed = np.where(walks_back[:m], following < 0, following == origin[:m])
        wrong = np.where(done, ~closed, (following < 0) | (following == origin[:m]))
        if np.any(wrong):
            return _Fans(corners[:0], corners[:0], corners[:0], boundary, int(order[np.argmax(wrong)]))
        current[:m] = following
    return _Fans(np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces]),
                 np.concatenate([np.full(len(p[0]), p[2]) for p in pieces]), boundary, None)


def _limit_normals(limit: np.ndarray, faces: np.ndarray, topology: _Topology) -> np.ndarray:
    """pbrt's limit normals, S x T of its tangent masks on each point's ordered one-ring of limit
    points (``_tangent_masks``). A point where S x T vanishes (a degenerate ring) takes the sum of
    its triangles' area normals, oriented as pbrt's are (against the counter-clockwise winding), and
    +z where those cancel too. The points are scaled to at most 1 first: a direction does not
    depend on it, and products of large coordinates do not overflow."""
    n_points = len(limit)
    limit = limit / (np.abs(limit).max(initial=0.0) or 1.0)
    fans = _fans(faces, topology, n_points)
    next_point = np.roll(faces, -1, axis=1).ravel()
    previous_point = np.roll(faces, -2, axis=1).ravel()
    rim = fans.boundary[fans.owner]
    # the ring: inside, the next point of each corner in walk order; on the boundary, the next point
    # of the first corner, then the previous point of each corner
    opening = rim & (fans.step == 0)
    owner = np.concatenate([fans.owner, fans.owner[opening]])
    place = np.concatenate([fans.step + rim, np.zeros(int(np.count_nonzero(opening)), dtype=np.int64)])
    ring = np.concatenate([np.where(rim, previous_point[fans.corner], next_point[fans.corner]),
                           next_point[fans.corner[opening]]])
    valence = np.bincount(fans.owner, minlength=n_points) + fans.boundary
    s_mask, t_mask, own_mask = _tangent_masks(valence, fans.boundary)
    entry = own_mask.offset[owner] + place
    s = _sum_by(owner, s_mask[entry][:, None] * limit[ring], n_points)
    t = _sum_by(owner, t_mask[entry][:, None] * limit[ring], n_points) + own_mask.weight[:, None] * limit
    normals = np.cross(s, t)
    corners = limit[faces]
    area = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    around = -_sum_by(faces.ravel(), np.repeat(area, 3, axis=0), n_points)
    for fallback in (around, np.broadcast_to([0.0, 0.0, 1.0], normals.shape)):
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        usable = np.isfinite(length) & (length > 0)
        normals = np.where(usable, normals / np.where(usable, length, 1.0), fallback)
    return normals


@dataclass(frozen=True)
class _Masks:
    """Where each point's ring weights start in the flat mask tables (``offset``), and the weight of
    the point itself in T (``weight``)."""

    offset: np.ndarray
    weight: np.ndarray


def _tangent_masks(valence: np.ndarray, boundary: np.ndarray) -> tuple[np.ndarray, np.ndarray, _Masks]:
    """pbrt's tangent weights on a ring p_0 ... p_{n-1} (n the valence), tabulated once per distinct
    valence and side (inside or boundary), with each point's start in the tables:

    - inside: S = sum cos(2 pi j / n) p_j, T = sum sin(2 pi j / n) p_j, the ring in ``nextFace`` order;
    - on the boundary, the ring from one boundary neighbour (p_0) around to the other (p_{n-1}):
      S = p_{n-1} - p_0 and T = p_0 + p_1 - 2 v (n = 2), p_1 - v (n = 3), -p_0 + 2 p_1 + 2 p_2 - p_3
      - 2 v (n = 4), else -(sin t (p_0 + p_{n-1}) + sum_{k=1}^{n-2} (2 cos t - 2) sin(k t) p_k) with
      t = pi / (n - 1) (Hoppe et al.'s masks, as pbrt has them)."""
    width = int(valence.max(initial=0)) + 1
    kind = boundary * width + valence  # one number per (side, valence)
    first = np.zeros(2 * width, dtype=np.int64)
    own = np.zeros(2 * width)
    s_parts, t_parts, size = [np.zeros(0)], [np.zeros(0)], 0
    for k in np.unique(kind).tolist():
        n, j = k % width, np.arange(k % width)
        if k < width:
            s_parts.append(np.cos(2 * np.pi * j / n))
            t_parts.append(np.sin(2 * np.pi * j / n))
        else:
            s_parts.append((j == n - 1) - (j == 0).astype(np.float64))
            t_parts.append(_boundary_t(n))
            own[k] = {2: -2.0, 3: -1.0, 4: -2.0}.get(n, 0.0)
        first[k], size = size, size + n
    return np.concatenate(s_parts), np.concatenate(t_parts), _Masks(first[kind], own[kind])


def _boundary_t(n: int) -> np.ndarray:
    """pbrt's boundary T weights on the ring of a boundary point of valence ``n`` (the point's own
    weight is in ``_tangent_masks``)."""
    if n in (2, 3, 4):
        return np.array({2: [1.0, 1.0], 3: [0.0, 1.0, 0.0], 4: [-1.0, 2.0, 2.0, -1.0]}[n])
    t = np.pi / (n - 1)
    weights = -(2 * np.cos(t) - 2) * np.sin(np.arange(n) * t)
    weights[[0, -1]] = -np.sin(t)
    return weights
