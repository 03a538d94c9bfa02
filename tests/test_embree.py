"""The ctypes binding of embree 4 (``realistic.scene.embree``) against analytic ray-plane hits.

A unit square in the plane z = 0 (two triangles) is hit by rays from z = h: t = h / |d_z|, and
the hit point gives the barycentrics. Batches of every size around the 16-ray packet check that
no lane is lost or mixed with another; an instance under a known affine map checks the
two-level build.
"""

import ctypes
import struct

import numpy as np
import pytest

from realistic.scene import embree, packet_loop
from realistic.scene.embree import EmbreeScene
from realistic.scene.packet_loop import PACKET

SQUARE_VERTICES = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
SQUARE_FACES = np.array([[0, 1, 2], [0, 2, 3]])


def square_scene(geom_id: int = 7) -> EmbreeScene:
    scene = EmbreeScene()
    scene.add_triangles(SQUARE_VERTICES, SQUARE_FACES, geom_id)
    scene.commit()
    return scene


def rays_at(points: np.ndarray, height: float = 2.0, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Rays from above the plane through ``points`` (N, 2) on z = 0, of varied lengths and slants."""
    rng = np.random.default_rng(seed)
    target = np.column_stack([points, np.zeros(len(points))])
    origin = target + np.column_stack([rng.uniform(-1, 1, (len(points), 2)), np.full(len(points), height)])
    direction = (target - origin) * rng.uniform(0.2, 3, (len(points), 1))
    return origin.astype(np.float32), direction.astype(np.float32)


def barycentrics(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangle (0 below the diagonal x = y, 1 above) and embree's u, v (weights of vertices 1, 2)."""
    x, y = points[:, 0], points[:, 1]
    upper = y > x
    # triangle 0: (0,0) (1,0) (1,1): p = u (1,0) + v (1,1) -> v = y, u = x - y
    # triangle 1: (0,0) (1,1) (0,1): p = u (1,1) + v (0,1) -> u = x, v = y - x
    return upper.astype(np.int32), np.where(upper, x, x - y), np.where(upper, y - x, y)


@pytest.mark.parametrize("n", [0, 1, PACKET - 1, PACKET, PACKET + 1, 3 * PACKET + 5, 1000])
def test_closest_hits_are_the_analytic_ones_in_batches_of_any_size(n):
    rng = np.random.default_rng(n)
    points = rng.uniform(-0.5, 1.5, (n, 2))
    points[::7] = rng.uniform(0.05, 0.95, (len(points[::7]), 2))
    origin, direction = rays_at(points)
    hits = square_scene().intersect(origin, direction)
    inside = np.all((points > 0) & (points < 1), axis=1)
    margin = np.min(np.abs(np.column_stack([points, points - 1, points[:, 0] - points[:, 1]])), axis=1) > 1e-4
    assert np.array_equal((hits.geom == 7)[margin], inside[margin])
    assert np.all(hits.geom[~inside & margin] == -1) and np.all(hits.t[hits.geom < 0] == np.float32(1e37))
    assert np.all(hits.instance == -1)
    hit = inside & margin
    np.testing.assert_allclose(hits.t[hit], (origin[hit, 2] / -direction[hit, 2]), rtol=1e-5)
    prim, u, v = barycentrics(points[hit])
    assert np.array_equal(hits.prim[hit], prim)
    np.testing.assert_allclose(hits.u[hit], u, atol=1e-5)
    np.testing.assert_allclose(hits.v[hit], v, atol=1e-5)
    normal = hits.normal[hit]  # the plane's normal, unnormalised (twice the triangle's area)
    np.testing.assert_allclose(np.abs(normal[:, 2]), 1.0, rtol=1e-6)
    np.testing.assert_allclose(normal[:, :2], 0, atol=1e-6)


def test_a_batch_answers_as_its_rays_one_at_a_time():
    rng = np.random.default_rng(3)
    origin, direction = rays_at(rng.uniform(-0.2, 1.2, (37, 2)))
    scene = square_scene()
    batch = scene.intersect(origin, direction)
    for i in range(len(origin)):
        one = scene.intersect(origin[i:i + 1], direction[i:i + 1])
        assert (one.geom[0], one.prim[0], one.t[0]) == (batch.geom[i], batch.prim[i], batch.t[i])


def test_occlusion_is_decided_by_the_distance():
    rng = np.random.default_rng(4)
    points = rng.uniform(0.05, 0.95, (100, 2))
    origin, direction = rays_at(points)
    t = origin[:, 2] / -direction[:, 2]
    scene = square_scene()
    assert scene.occluded(origin, direction, t * 1.001).all()
    assert not scene.occluded(origin, direction, t * 0.999).any()
    assert scene.occluded(origin, direction, np.full(len(t), -1, np.float32)).all()  # as embreex answered
    outside_origin, outside_direction = rays_at(points + 2)
    assert not scene.occluded(outside_origin, outside_direction, np.full(len(t), 1e30, np.float32)).any()


def test_an_instance_is_hit_where_its_transform_puts_the_mesh():
    # x scaled by 3, rotated 90 degrees about z (x -> y), moved up by 5: the square covers
    # x in [-1, 0], y in [0, 3] at z = 5; its normal (z) is unchanged by the map
    transform = np.array([[0, -1, 0, 0], [3, 0, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]], np.float64)
    top = EmbreeScene()
    top.add_instance(square_scene(geom_id=0), transform, 11)
    top.commit()
    rng = np.random.default_rng(5)
    world = np.column_stack([rng.uniform(-0.95, -0.05, 50), rng.uniform(0.05, 2.95, 50)])
    origin, direction = rays_at(world, height=3.0)
    origin[:, 2] += 5
    hits = top.intersect(origin, direction)
    assert np.all(hits.instance == 11) and np.all(hits.geom == 0)
    np.testing.assert_allclose(hits.t, 3.0 / -direction[:, 2], rtol=1e-5)
    # object-space hit point (x, y) = (y_w / 3, -x_w): the barycentrics are the object space's
    prim, u, v = barycentrics(np.column_stack([world[:, 1] / 3, -world[:, 0]]))
    assert np.array_equal(hits.prim, prim)
    np.testing.assert_allclose(hits.u, u, atol=1e-5)
    np.testing.assert_allclose(hits.v, v, atol=1e-5)


def test_bad_meshes_and_uncommitted_scenes_are_refused():
    scene = EmbreeScene()
    with pytest.raises(ValueError, match="vertex 4 of 4"):
        scene.add_triangles(SQUARE_VERTICES, [[0, 1, 4]], 0)
    with pytest.raises(RuntimeError, match="commit"):
        scene.intersect(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))


def test_the_library_is_the_one_embreex_ships():
    assert any("embree4" in path.name for path in embree.library_candidates())


def packet_view(address: int, rows: int, dtype) -> np.ndarray:
    """The packet at ``address`` as (rows, 16) of ``dtype``, shared with the caller's memory."""
    return np.ctypeslib.as_array(ctypes.cast(address, ctypes.POINTER(ctypes.c_int32)), (rows * PACKET,)).view(
        dtype).reshape(rows, PACKET)


@pytest.fixture(params=["shipped", "compiled here"])
def loops(request):
    """The closest and occluded loops as this machine runs them, or as llvmlite compiles them here."""
    if request.param == "shipped":
        yield packet_loop.closest_loop(), packet_loop.occluded_loop()
    else:
        owners = packet_loop.compiled_for_host("closest"), packet_loop.compiled_for_host("occluded")  # own the code
        yield owners[0][-1], owners[1][-1]


def fake_embree(check):
    """A ctypes function with rtcIntersect16's signature that hands each packet to ``check``."""
    function = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)(
        lambda valid, scene, packet, arguments: check(packet_view(valid, 1, np.int32)[0], scene, packet, arguments))
    return function, ctypes.cast(function, ctypes.c_void_p).value


@pytest.mark.parametrize("n", [0, 1, PACKET, 37])
def test_the_closest_loop_fills_and_reads_packets_as_embree_lays_them_out(loops, n):
    rng = np.random.default_rng(n)
    origin, direction = rng.normal(size=(2, n, 3)).astype(np.float32)
    seen = []

    def check(valid, scene, address, arguments):
        floats = packet_view(address, packet_loop.ROWS, np.float32)
        ints = packet_view(address, packet_loop.ROWS, np.int32)
        live = valid == -1
        seen.append(live.sum())
        assert scene == 99 and arguments is None
        assert np.all(valid[~live] == 0) and np.all(np.diff(live.astype(int)) <= 0)  # live lanes first
        first = sum(seen[:-1])
        np.testing.assert_array_equal(floats[0:3, live].T, origin[first:first + live.sum()])
        np.testing.assert_array_equal(floats[4:7, live].T, direction[first:first + live.sum()])
        assert np.all(floats[[3, 7, 12, 13, 14, 15, 16]][:, live] == 0) and np.all(floats[8, live] == np.float32(2.5))
        assert np.all(ints[[9, 17, 18, 19]][:, live] == -1) and np.all(ints[[10, 11]][:, live] == 0)
        # a hit that encodes the ray: t = 2 x, u = y, v = z, prim = lane, geom 5, instance 3, Ng = direction
        floats[8], floats[15], floats[16] = 2 * floats[0], floats[1], floats[2]
        ints[17], ints[18], ints[19] = np.arange(PACKET), 5, 3
        floats[12:15] = floats[4:7]

    function, address = fake_embree(check)
    closest, _ = loops
    out = [np.full(n, -7, np.float32) for _ in range(3)] + [np.full(n, -7, np.int32) for _ in range(3)]
    normal = np.zeros((n, 3), np.float32)
    closest(address, 99, origin.ctypes.data, direction.ctypes.data, n, 2.5, *(a.ctypes.data for a in out),
            normal.ctypes.data)
    assert sum(seen) == n and len(seen) == -(-n // PACKET)
    t, u, v, prim, geom, instance = out
    np.testing.assert_array_equal(t, 2 * origin[:, 0])
    np.testing.assert_array_equal(np.column_stack([u, v]), origin[:, 1:])
    np.testing.assert_array_equal(prim, np.arange(n) % PACKET)
    assert np.all(geom == 5) and np.all(instance == 3)
    np.testing.assert_array_equal(normal, direction)


def test_the_occluded_loop_traces_only_rays_with_a_distance_and_reports_negative_tfar(loops):
    n = 40
    rng = np.random.default_rng(7)
    origin, direction = rng.normal(size=(2, n, 3)).astype(np.float32)
    distance = rng.uniform(0.5, 2, n).astype(np.float32)
    distance[[3, 17]], distance[[5, 30]] = -1.0, np.nan
    traced = []

    def check(valid, scene, address, arguments):
        floats = packet_view(address, 12, np.float32)
        first = len(traced) * PACKET
        lanes = np.arange(PACKET)
        expected = (first + lanes < n) & (distance[np.minimum(first + lanes, n - 1)] >= 0)
        np.testing.assert_array_equal(valid == -1, expected)
        traced.append(valid)
        np.testing.assert_array_equal(floats[8, :min(PACKET, n - first)], distance[first:first + PACKET])
        floats[8, (valid == -1) & (floats[0] > 0)] = -np.inf  # "occluded" where x > 0

    function, address = fake_embree(check)
    _, occluded = loops
    blocked = np.zeros(n, np.bool_)
    occluded(address, 0, origin.ctypes.data, direction.ctypes.data, n, distance.ctypes.data, blocked.ctypes.data)
    assert len(traced) == 3
    np.testing.assert_array_equal(blocked, ((origin[:, 0] > 0) & (distance >= 0)) | (distance < 0))


def elf_text_section(elf: bytes) -> bytes:
    """The .text section of a little-endian ELF64 object, and a check that nothing relocates it."""
    section_headers, = struct.unpack_from("<Q", elf, 0x28)
    entry_size, count, names_index = struct.unpack_from("<HHH", elf, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", elf, section_headers + i * entry_size) for i in range(count)]
    names_offset = sections[names_index][4]
    names = [elf[names_offset + s[0]:elf.index(b"\0", names_offset + s[0])].decode() for s in sections]
    assert ".rela.text" not in names and ".rel.text" not in names
    text = sections[names.index(".text")]
    return elf[text[4]:text[4] + text[5]]


@pytest.mark.parametrize("name, ir", [("closest", packet_loop.closest_ir), ("occluded", packet_loop.occluded_ir)])
def test_the_shipped_machine_code_is_the_ir_compiled_by_llvmlite(name, ir):
    llvm = pytest.importorskip("llvmlite.binding")
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    machine = llvm.Target.from_triple("x86_64-unknown-linux-gnu").create_target_machine(
        cpu="x86-64", features="", opt=2, reloc="pic", codemodel="default")
    assert elf_text_section(machine.emit_object(llvm.parse_assembly(ir()))) == packet_loop.SHIPPED[name]
