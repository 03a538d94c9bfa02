"""pbrt's loopsubdiv subdivided as pbrt does (issue 34): Loop's rules checked against closed forms
(linear precision on a regular planar grid, the limit mask of a vertex of valence n, the cubic
B-spline rules on boundaries), convergence with levels, pbrt's limit normals against a plain
one-vertex-at-a-time implementation of its rules, and the shape through the pbrt importer."""

import itertools
import math
from collections import defaultdict

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.scene import loop_subdivision
from realistic.scene.loop_subdivision import MAX_TRIANGLES, loop_subdivide, refine
from realistic.scene.pbrt.importer import import_pbrt

# ---------------------------------------------------------------------------------------------------
# meshes


def outward(vertices: np.ndarray, faces) -> np.ndarray:
    """Faces of a convex solid turned counter-clockwise seen from outside."""
    faces = np.array(faces, dtype=np.int64)
    corners = vertices[faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    inward = np.einsum("ij,ij->i", normal, corners.mean(axis=1) - vertices.mean(axis=0)) < 0
    faces[inward] = faces[inward][:, ::-1]
    return faces


def platonic(vertices) -> tuple[np.ndarray, np.ndarray]:
    """A solid with equilateral faces: every triple of points at the shortest distance from each other."""
    vertices = np.array(vertices, dtype=np.float64)
    gap = np.linalg.norm(vertices[:, None] - vertices[None], axis=2)
    edge = gap[gap > 0].min()
    faces = [t for t in itertools.combinations(range(len(vertices)), 3)
             if all(abs(gap[i, j] - edge) < 1e-9 for i, j in itertools.combinations(t, 2))]
    return vertices, outward(vertices, faces)


GOLDEN = (1 + math.sqrt(5)) / 2
TETRAHEDRON = platonic([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])
OCTAHEDRON = platonic([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
ICOSAHEDRON = platonic([p for a, b in itertools.product((-1, 1), (-GOLDEN, GOLDEN))
                        for p in ([0, a, b], [a, b, 0], [b, 0, a])])


def bipyramid(k: int, squash: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Two apexes of valence ``k`` over a ring of ``k`` points of valence 4."""
    angle = 2 * np.pi * np.arange(k) / k
    ring = np.column_stack([np.cos(angle), np.sin(angle), 0.1 * np.sin(3 * angle)])
    vertices = np.vstack([ring, [[0, 0, squash], [0, 0, -squash]]])
    faces = [[i, (i + 1) % k, k] for i in range(k)] + [[(i + 1) % k, i, k + 1] for i in range(k)]
    return vertices, outward(vertices, faces)


def grid(rows: int, cols: int, height=None) -> tuple[np.ndarray, np.ndarray]:
    """A (rows+1) x (cols+1) grid of points (x = column, y = row) cut along the same diagonal in every
    cell, so that every inner point has valence 6, wound counter-clockwise seen from +z."""
    r, c = np.meshgrid(np.arange(rows + 1), np.arange(cols + 1), indexing="ij")
    z = np.zeros(r.shape) if height is None else height(c, r)
    vertices = np.column_stack([c.ravel(), r.ravel(), z.ravel()]).astype(np.float64)
    a = (r[:-1, :-1] * (cols + 1) + c[:-1, :-1]).ravel()
    d = a + cols + 1  # the point above a
    faces = np.concatenate([np.column_stack([a, a + 1, d + 1]), np.column_stack([a, d + 1, d])])
    return vertices, faces


def half_fan(k: int) -> tuple[np.ndarray, np.ndarray]:
    """``k`` triangles around a boundary point (valence k + 1) over a wavy half circle."""
    angle = np.pi * np.arange(k + 1) / k
    rim = np.column_stack([np.cos(angle), np.sin(angle), 0.3 * np.cos(2 * angle)])
    return np.vstack([[[0.0, 0.0, 0.2]], rim]), np.array([[0, i + 1, i + 2] for i in range(k)])


CLOSED = {"tetrahedron": TETRAHEDRON, "octahedron": OCTAHEDRON, "icosahedron": ICOSAHEDRON,
          "bipyramid7": bipyramid(7), "bipyramid3": bipyramid(3, 0.5)}
OPEN = {"wavy grid": grid(4, 5, lambda x, y: 0.3 * np.sin(x) * np.cos(1.3 * y)), "half fan": half_fan(6),
        "triangle": (np.eye(3), np.array([[0, 1, 2]])), "open cap": (OCTAHEDRON[0], OCTAHEDRON[1][:-1])}

# ---------------------------------------------------------------------------------------------------
# a plain implementation of the rules, one point and one face at a time, for small meshes


def neighbours(faces) -> tuple[dict, dict, dict]:
    """Each point's neighbours, its neighbours along boundary edges, and each edge's opposite points."""
    opposite = defaultdict(list)
    for a, b, c in faces:
        for u, v, w in ((a, b, c), (b, c, a), (c, a, b)):
            opposite[frozenset((u, v))].append(w)
    around, rim = defaultdict(set), defaultdict(set)
    for edge, thirds in opposite.items():
        u, v = tuple(edge)
        around[u].add(v)
        around[v].add(u)
        if len(thirds) == 1:
            rim[u].add(v)
            rim[v].add(u)
    return around, rim, opposite


def reference(points, faces, levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Subdivision, limit points and limit normals written from the rules (module docstring of
    ``realistic.scene.loop_subdivision``) with dicts and loops."""
    points = [np.asarray(p, dtype=np.float64) for p in points]
    faces = [tuple(int(i) for i in f) for f in faces]
    for _ in range(levels):
        around, rim, opposite = neighbours(faces)
        moved = []
        for i, p in enumerate(points):
            if rim[i]:
                moved.append(0.75 * p + 0.125 * sum(points[j] for j in rim[i]))
            else:
                n = len(around[i])
                beta = 3 / 16 if n == 3 else 3 / (8 * n)
                moved.append((1 - n * beta) * p + beta * sum(points[j] for j in around[i]))
        middle = {}
        for edge, thirds in opposite.items():
            u, v = tuple(edge)
            middle[edge] = len(moved)
            if len(thirds) == 1:
                moved.append(0.5 * (points[u] + points[v]))
            else:
                moved.append(0.375 * (points[u] + points[v]) + 0.125 * (points[thirds[0]] + points[thirds[1]]))
        children = []
        for a, b, c in faces:
            ab, bc, ca = middle[frozenset((a, b))], middle[frozenset((b, c))], middle[frozenset((c, a))]
            children += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        points, faces = moved, children
    around, rim, _ = neighbours(faces)
    limit = []
    for i, p in enumerate(points):
        if rim[i]:
            limit.append(0.6 * p + 0.2 * sum(points[j] for j in rim[i]))
        else:
            n = len(around[i])
            beta = 3 / 16 if n == 3 else 3 / (8 * n)
            chi = 1 / (n + 3 / (8 * beta))
            limit.append((1 - n * chi) * p + chi * sum(points[j] for j in around[i]))
    normals = [reference_normal(i, limit, faces, bool(rim[i])) for i in range(len(limit))]
    return np.array(limit), np.array(faces), np.array(normals)


def reference_normal(i: int, p: list, faces: list, on_rim: bool) -> np.ndarray:
    """pbrt's tangents on point i's one-ring: rotating each face so that i comes first, (i, a, b),
    the ring goes from a to the face holding (i, x, a); on the boundary it starts at the face
    with no face across its edge (i, a) and goes the other way, through b."""
    turned = [f[f.index(i):] + f[:f.index(i)] for f in faces if i in f]
    by_last = {f[2]: f for f in turned}
    by_next = {f[1]: f for f in turned}
    if not on_rim:
        ring, face = [], turned[0]
        while True:
            ring.append(face[1])
            face = by_last[face[1]]
            if face == turned[0]:
                break
        n = len(ring)
        s = sum(math.cos(2 * math.pi * j / n) * p[v] for j, v in enumerate(ring))
        t = sum(math.sin(2 * math.pi * j / n) * p[v] for j, v in enumerate(ring))
    else:
        (face,) = [f for f in turned if f[1] not in by_last]
        ring = [face[1]]
        while face is not None:
            ring.append(face[2])
            face = by_next.get(face[2])
        n = len(ring)
        q = [p[v] for v in ring]
        s = q[-1] - q[0]
        if n == 2:
            t = q[0] + q[1] - 2 * p[i]
        elif n == 3:
            t = q[1] - p[i]
        elif n == 4:
            t = -q[0] + 2 * q[1] + 2 * q[2] - q[3] - 2 * p[i]
        else:
            theta = math.pi / (n - 1)
            t = -(math.sin(theta) * (q[0] + q[-1])
                  + sum((2 * math.cos(theta) - 2) * math.sin(k * theta) * q[k] for k in range(1, n - 1)))
    normal = np.cross(s, t)
    return normal / np.linalg.norm(normal)


# ---------------------------------------------------------------------------------------------------
# closed forms


def limit_by_mask(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The closed-form limit of each point of a closed mesh: (1 - n chi) v + chi * sum of its n
    neighbours, chi = 1 / (3 / (8 beta) + n)."""
    around, _, _ = neighbours(faces.tolist())
    limit = []
    for i, v in enumerate(vertices):
        n = len(around[i])
        beta = 3 / 16 if n == 3 else 3 / (8 * n)
        chi = 1 / (3 / (8 * beta) + n)
        limit.append((1 - n * chi) * v + chi * vertices[sorted(around[i])].sum(axis=0))
    return np.array(limit)


def point_to_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each point's distance to the nearest point of the triangles (brute force)."""
    a, b, c = (vertices[faces[:, k]][None] for k in range(3))
    x = points[:, None]
    normal = np.cross(b - a, c - a)
    normal = normal / np.linalg.norm(normal, axis=2, keepdims=True)
    height = np.einsum("ijk,ijk->ij", x - a, normal)
    foot = x - height[..., None] * normal
    inside = np.ones(height.shape, dtype=bool)
    for p, q in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ijk,ijk->ij", np.cross(q - p, foot - p), normal) >= 0

    def to_segment(p, q):
        t = np.clip(np.einsum("ijk,ijk->ij", x - p, q - p) / np.einsum("ijk,ijk->ij", q - p, q - p), 0, 1)
        return np.linalg.norm(x - (p + t[..., None] * (q - p)), axis=2)

    edges = np.minimum(np.minimum(to_segment(a, b), to_segment(b, c)), to_segment(c, a))
    return np.where(inside, np.abs(height), edges).min(axis=1)


def boundary_loop(faces: np.ndarray) -> list[int]:
    """The points of a mesh's one boundary in order."""
    _, rim, _ = neighbours(faces.tolist())
    start = min(rim)
    loop, previous = [start], None
    while True:
        here = loop[-1]
        step = [v for v in rim[here] if v != previous][0]
        if step == start:
            return loop
        previous = here
        loop.append(step)


def bspline_refine(polygon: np.ndarray) -> np.ndarray:
    """One step of the closed cubic B-spline's subdivision: (p_{i-1} + 6 p_i + p_{i+1}) / 8 and
    (p_i + p_{i+1}) / 2, interleaved."""
    before, after = np.roll(polygon, 1, axis=0), np.roll(polygon, -1, axis=0)
    out = np.empty((2 * len(polygon), polygon.shape[1]))
    out[0::2] = (before + 6 * polygon + after) / 8
    out[1::2] = (polygon + after) / 2
    return out


def rim_points(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    _, rim, _ = neighbours(faces.tolist())
    return vertices[sorted(rim)]


def nearest(points: np.ndarray, others: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points[:, None] - others[None], axis=2).min(axis=1)


# ---------------------------------------------------------------------------------------------------
# the subdivision


@pytest.mark.parametrize("name", [*CLOSED, *OPEN])
@pytest.mark.parametrize("levels", [0, 1, 2, 3])
def test_each_level_splits_every_triangle_in_four(name, levels):
    vertices, faces = {**CLOSED, **OPEN}[name]
    subdivided = loop_subdivide(vertices, faces, levels)
    assert len(subdivided.faces) == 4 ** levels * len(faces)
    edges = {frozenset(e) for f in subdivided.faces.tolist() for e in itertools.combinations(f, 2)}
    # Euler: V - E + F is kept (2 for a closed surface, 1 for a disk)
    assert len(subdivided.vertices) - len(edges) + len(subdivided.faces) == (2 if name in CLOSED else 1)
    assert np.allclose(np.linalg.norm(subdivided.normals, axis=1), 1)


@pytest.mark.parametrize("name", [*CLOSED, *OPEN])
def test_points_and_normals_are_those_of_the_rules_applied_one_point_at_a_time(name):
    vertices, faces = {**CLOSED, **OPEN}[name]
    for levels in (0, 1, 2):
        subdivided = loop_subdivide(vertices, faces, levels)
        limit, children, normals = reference(vertices, faces, levels)
        # the same triangles in the same order (pbrt's), whatever the numbering of the new points
        assert np.allclose(subdivided.vertices[subdivided.faces], limit[children], atol=1e-12)
        assert np.allclose(subdivided.normals[subdivided.faces], normals[children], atol=1e-12)


def test_a_flat_regular_grid_stays_flat_and_on_the_refined_lattice():
    """Loop's rules reproduce linear functions on a regular (valence 6) mesh, and the boundary rules
    on a straight boundary: away from the 4 corners (which the boundary rule rounds off) every point
    lies on the lattice refined 2^levels times, in the plane."""
    plane = np.array([[1.0, 0.4, 0.0], [0.3, 1.0, 0.0], [0.2, -0.5, 1.0]])  # a sheared, tilted plane
    vertices, faces = grid(12, 12)
    levels = 3
    subdivided = loop_subdivide(vertices @ plane, faces, levels)
    flat = subdivided.vertices @ np.linalg.inv(plane)  # back to lattice coordinates
    assert np.allclose(flat[:, 2], 0, atol=1e-12)
    corners = np.array([[0, 0], [12, 0], [0, 12], [12, 12]])
    far = nearest(flat[:, :2], corners) > 3 + 1e-6
    lattice = flat[far, :2] * 2 ** levels
    assert np.allclose(lattice, np.round(lattice), atol=1e-9)
    assert len(np.unique(np.round(lattice), axis=0)) == far.sum()  # one point per lattice site
    # every lattice site of that region is there: 97 x 97 sites less the four corner regions
    sites = np.stack(np.meshgrid(np.arange(97), np.arange(97)), axis=-1).reshape(-1, 2) / 8
    assert far.sum() == (nearest(sites, corners) > 3 + 1e-6).sum()
    # the normals are the plane's, against the counter-clockwise winding (+z in lattice coordinates)
    up = np.cross(plane[0], plane[1])
    assert np.allclose(subdivided.normals, -up / np.linalg.norm(up), atol=1e-9)


@pytest.mark.parametrize("name", list(CLOSED))
def test_limit_points_are_the_closed_form_mask_and_refinement_converges_to_them(name):
    vertices, faces = CLOSED[name]
    expected = limit_by_mask(vertices, faces)
    size = np.ptp(vertices, axis=0).max()
    for levels in (0, 1, 2):  # the limit point of a control point does not move with levels
        assert np.allclose(loop_subdivide(vertices, faces, levels).vertices[:len(vertices)], expected, atol=1e-12)
    errors = [np.abs(refine(vertices, faces, k)[0][:len(vertices)] - expected).max() / size for k in range(7)]
    assert all(b < 0.7 * a for a, b in itertools.pairwise(errors))
    assert errors[-1] < 2e-3


@pytest.mark.parametrize("name", ["tetrahedron", "octahedron", "icosahedron"])
def test_the_platonic_solids_surfaces_converge_with_levels(name):
    """The Hausdorff distance from the limit surface (densely sampled: points pushed to the limit
    lie on it) to the subdivided mesh falls with levels, about fourfold once the mesh is fine (it is
    piecewise linear)."""
    vertices, faces = CLOSED[name]
    dense = loop_subdivide(vertices, faces, 4).vertices
    distances = []
    for levels in range(3):
        subdivided = loop_subdivide(vertices, faces, levels)
        distances.append(point_to_mesh(dense, subdivided.vertices, subdivided.faces).max())
    assert distances[0] > 0.02 * np.ptp(vertices, axis=0).max()
    assert distances[2] < distances[1] / 2.5 < distances[0] / 2.5, distances


@pytest.mark.parametrize("name", ["wavy grid", "half fan", "open cap"])
def test_boundaries_follow_the_cubic_bspline_rules(name):
    """The refined boundary is the boundary polygon refined by the cubic B-spline's rules, whatever
    the interior; pbrt pushes it with (1/5, 3/5, 1/5) where the B-spline's limit is (1/6, 2/3, 1/6),
    off by a fraction of the level's second difference, which falls fourfold a level."""
    vertices, faces = OPEN[name]
    polygon = vertices[boundary_loop(faces)]
    bumped = vertices + 0.3 * np.sin(7 * vertices[:, ::-1])  # the interior moves; the rule must not see it
    on_rim = np.isin(np.arange(len(vertices)), boundary_loop(faces))
    bumped[on_rim] = vertices[on_rim]
    gaps = []
    for levels in range(1, 5):
        polygon = bspline_refine(polygon)
        points, children = refine(bumped, faces, levels)
        rim = rim_points(points, children)
        assert len(rim) == len(polygon) and nearest(rim, polygon).max() < 1e-12
        spline_limit = (np.roll(polygon, 1, axis=0) + 4 * polygon + np.roll(polygon, -1, axis=0)) / 6
        pbrt_limit = (np.roll(polygon, 1, axis=0) + 3 * polygon + np.roll(polygon, -1, axis=0)) / 5
        pushed = rim_points(loop_subdivide(bumped, faces, levels).vertices, children)
        assert nearest(pushed, pbrt_limit).max() < 1e-12
        gaps.append(nearest(pushed, spline_limit).max())
    assert all(3 * b < a for a, b in itertools.pairwise(gaps)), gaps


@pytest.mark.parametrize("name", list(CLOSED))
def test_normals_point_out_of_a_mesh_wound_clockwise_seen_from_outside(name):
    """pbrt's limit normals point against the faces' counter-clockwise normal, so out of a mesh
    whose faces run clockwise seen from outside, and agree with the subdivided mesh's faces."""
    vertices, faces = CLOSED[name]
    subdivided = loop_subdivide(vertices, faces[:, ::-1], 3)
    out = subdivided.vertices - subdivided.vertices.mean(axis=0)
    assert np.all(np.einsum("ij,ij->i", subdivided.normals, out) > 0)
    corners = subdivided.vertices[subdivided.faces]
    face_normal = np.cross(corners[:, 2] - corners[:, 0], corners[:, 1] - corners[:, 0])  # clockwise
    face_normal /= np.linalg.norm(face_normal, axis=1, keepdims=True)
    agreement = np.einsum("ijk,ik->ij", subdivided.normals[subdivided.faces], face_normal)
    assert agreement.min() > 0 and agreement.mean() > 0.95
    inward = loop_subdivide(vertices, faces, 3).normals
    assert np.allclose(inward, -subdivided.normals)


# ---------------------------------------------------------------------------------------------------
# meshes Loop's rules do not apply to


@pytest.mark.parametrize("faces,fragment", [
    ([[0, 1, 2], [0, 1, 3], [1, 0, 4]], "edge between points 0 and 1 is shared by 3 triangles"),
    ([[0, 1, 2], [0, 1, 3]], "both triangles on the edge between points 0 and 1 run it the same way"),
    ([[0, 1, 2], [0, 3, 4]], "triangles around point 0 do not form one fan"),
    ([[0, 1, 2], [0, 2, 3], [0, 3, 1], [0, 4, 5], [0, 5, 6], [0, 6, 4]], "triangles around point 0 do not form"),
    ([[0, 1, 2], [0, 2, 3], [0, 3, 1], [0, 4, 5], [0, 5, 6]], "triangles around point 0 do not form one fan"),
    ([[0, 1, 1]], r"triangle 0 \(0 1 1\) uses a point twice")])
def test_a_mesh_that_is_not_a_consistently_wound_manifold_is_one_line_error(faces, fragment):
    points = np.random.default_rng(1).normal(size=(10, 3))
    with pytest.raises(UserError, match=fragment) as err:
        loop_subdivide(points, np.array(faces), 1)
    assert "\n" not in str(err.value)


def test_points_no_triangle_uses_are_dropped():
    vertices, faces = OCTAHEDRON
    padded = np.vstack([[[9.0, 9, 9]], vertices])
    subdivided = loop_subdivide(padded, faces + 1, 1)
    assert np.allclose(subdivided.vertices, loop_subdivide(vertices, faces, 1).vertices)


@given(st.integers(3, 7), st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6), st.integers(0, 6)),
                                   min_size=1, max_size=10), st.integers(0, 2), st.integers(0, 2 ** 32 - 1))
def test_random_small_meshes_subdivide_or_are_refused_in_one_line(points, triangles, levels, seed):
    vertices = np.random.default_rng(seed).normal(size=(points, 3))
    faces = np.array(triangles) % points
    try:
        subdivided = loop_subdivide(vertices, faces, levels)
    except UserError as err:
        assert str(err).startswith("loopsubdiv") and "\n" not in str(err)
        return
    assert len(subdivided.faces) == 4 ** levels * len(faces)
    assert np.all(np.isfinite(subdivided.vertices))
    assert np.allclose(np.linalg.norm(subdivided.normals, axis=1), 1)


@given(st.sets(st.integers(0, 19), min_size=1), st.integers(0, 2))
def test_any_piece_of_an_icosahedron_subdivides_unless_a_point_joins_two_fans(kept, levels):
    vertices, faces = ICOSAHEDRON
    piece = faces[sorted(kept)]
    try:
        subdivided = loop_subdivide(vertices, piece, levels)
    except UserError as err:
        assert "do not form one fan" in str(err)
        return
    used, renumbered = np.unique(piece, return_inverse=True)
    limit, children, normals = reference(vertices[used], renumbered.reshape(-1, 3), levels)
    assert np.allclose(subdivided.vertices[subdivided.faces], limit[children], atol=1e-12)
    assert np.allclose(subdivided.normals[subdivided.faces], normals[children], atol=1e-12)


# ---------------------------------------------------------------------------------------------------
# through the pbrt importer

CAMERA = 'LookAt 0 0 -5  0 0 0  0 1 0\nCamera "perspective" "float fov" 30\n'


def pbrt_file(tmp_path, shape: str, film: str = 'Film "rgb"', extra: str = ""):
    vertices, faces = OCTAHEDRON
    points = " ".join(f"{x:g}" for x in vertices.ravel())
    indices = " ".join(str(i) for i in faces[:, ::-1].ravel())  # clockwise from outside: normals out
    path = tmp_path / "s.pbrt"
    path.write_text(f'{film} "integer xresolution" 9 "integer yresolution" 9\n{CAMERA}WorldBegin\n{extra}'
                    f'Shape "loopsubdiv" {shape} "point3 P" [{points}] "integer indices" [{indices}]\n')
    return path


def the_mesh(imported):
    (mesh,) = [m for m in imported.scene.meshes if m.name == "loopsubdiv"]
    return mesh


def test_a_loopsubdiv_imports_subdivided_with_no_warning(tmp_path):
    imported = import_pbrt(pbrt_file(tmp_path, '"integer levels" 2'))
    mesh = the_mesh(imported)
    assert imported.warnings == []
    assert len(mesh.faces) == 8 * 16 and mesh.normals is not None
    expected = loop_subdivide(OCTAHEDRON[0], OCTAHEDRON[1][:, ::-1], 2)
    assert np.array_equal(mesh.vertices, expected.vertices) and np.array_equal(mesh.normals, expected.normals)
    assert np.allclose(np.linalg.norm(mesh.vertices[:6], axis=1), 0.5)  # the control points' limits


@pytest.mark.parametrize("dialect,shape,faces,unused", [
    ("v4", "", 8 * 64, None),  # default 3 levels in every version
    ("v4", '"integer levels" 1', 32, None),
    ("v4", '"integer nlevels" 1', 8 * 64, "nlevels"),  # pbrt-v4 reads "levels" only
    ("v3", '"integer nlevels" 1', 32, None),  # pbrt-v3 reads "levels", else "nlevels"
    ("v3", '"integer levels" 0 "integer nlevels" 1', 8, None),
    ("v2", '"integer nlevels" 1', 32, None),
    ("v2", '"integer levels" 1', 8 * 64, "levels")])  # pbrt-v2 reads "nlevels" only
def test_each_version_reads_its_own_name_for_the_levels(tmp_path, dialect, shape, faces, unused):
    path = pbrt_file(tmp_path, shape)
    imported = import_pbrt(path, dialect=dialect)
    assert len(the_mesh(imported).faces) == faces
    unused_warnings = [w for w in imported.warnings if "parameter not used here" in w]
    assert unused_warnings == ([f'{path}:5: unsupported: "{unused}": parameter not used here (ignored)']
                               if unused else [])


def test_levels_that_would_exhaust_memory_are_lowered_with_a_warning(tmp_path, monkeypatch):
    assert MAX_TRIANGLES >= 8 * 4 ** 8  # the killeroo scenes' meshes at pbrt's 3 levels, and more
    monkeypatch.setattr(loop_subdivision, "MAX_TRIANGLES", 8 * 4 ** 2 + 5)
    path = pbrt_file(tmp_path, '"integer levels" 40')
    imported = import_pbrt(path)
    assert len(the_mesh(imported).faces) == 8 * 4 ** 2
    assert imported.warnings == [f'{path}:5: unsupported: loopsubdiv "levels" 40 would make 4^40 x 8 triangles '
                                 f"(subdivided 2 times)"]


@pytest.mark.parametrize("levels", ["2.5", "-0.5"])
def test_levels_that_are_not_a_whole_number_are_an_error_at_the_line(tmp_path, levels):
    path = pbrt_file(tmp_path, f'"integer levels" {levels}')
    with pytest.raises(UserError) as err:
        import_pbrt(path)
    assert str(err.value) == f'{path}:5: loopsubdiv "levels" must be a whole number, got {float(levels):g}'


def test_negative_levels_subdivide_none_as_pbrt_does(tmp_path):
    assert len(the_mesh(import_pbrt(pbrt_file(tmp_path, '"integer levels" -2'))).faces) == 8


def test_a_non_manifold_loopsubdiv_is_an_error_at_its_line(tmp_path):
    path = tmp_path / "s.pbrt"
    path.write_text(f'Film "rgb"\n{CAMERA}WorldBegin\nShape "loopsubdiv" "point3 P" [0 0 0 1 0 0 0 1 0 0 0 1 1 1 1] '
                    '"integer indices" [0 1 2 0 1 3 1 0 4]\n')
    with pytest.raises(UserError) as err:
        import_pbrt(path)
    assert str(err.value) == (f"{path}:5: loopsubdiv is not manifold: the edge between points 0 and 1 is shared by "
                              f"3 triangles (at most 2)")


@pytest.mark.parametrize("wound_out,expected", [(True, 2.0), (False, 0.0)])
def test_a_glowing_loopsubdiv_renders_on_the_side_its_pbrt_normals_face(tmp_path, wound_out, expected):
    """An area light on the subdivided octahedron: the camera looking at it sees its radiance where
    pbrt's normals face the camera (one-sided emitter), nothing on the other side."""
    import realistic

    vertices, faces = OCTAHEDRON
    if not wound_out:
        faces = faces[:, ::-1]
    points = " ".join(f"{x:g}" for x in vertices.ravel())
    indices = " ".join(str(i) for i in faces[:, ::-1].ravel())
    path = tmp_path / "s.pbrt"
    path.write_text(f'Film "rgb" "integer xresolution" 9 "integer yresolution" 9\n{CAMERA}WorldBegin\n'
                    'AreaLightSource "diffuse" "rgb L" [2 2 2]\nMaterial "diffuse" "rgb reflectance" [0 0 0]\n'
                    f'Shape "loopsubdiv" "integer levels" 2 "point3 P" [{points}] "integer indices" [{indices}]\n')
    scene = realistic.load_scene(str(path), spp=4)
    image = np.asarray(realistic.render(scene, backend="numpy", threads=1))
    assert image[4, 4] == pytest.approx([expected] * 3, abs=1e-3)
