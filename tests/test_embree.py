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

from realistic.scene import embree
from realistic.scene import packet_loop as packet_loop_module
from realistic.scene.embree import PACKET, EmbreeScene
from realistic.scene.packet_loop import packet_loop

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


@pytest.mark.parametrize("loop", ["shipped", "compiled here"])
def test_the_packet_loop_calls_the_function_once_per_packet_with_the_right_addresses(loop):
    owner = None if loop == "shipped" else packet_loop_module.compiled_for_host()  # owns the code
    trace = packet_loop() if owner is None else owner[-1]
    calls = []
    record = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)(
        lambda valid, scene, packet, arguments: calls.append((valid, scene, packet, arguments)))
    address = ctypes.cast(record, ctypes.c_void_p).value
    trace(address, 1000, 77, 5000, 1344, 3)
    assert calls == [(1000, 77, 5000, None), (1064, 77, 6344, None), (1128, 77, 7688, None)]
    trace(address, 1000, 77, 5000, 1344, 0)
    assert len(calls) == 3
    del owner


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


def test_the_shipped_machine_code_is_the_ir_compiled_by_llvmlite():
    llvm = pytest.importorskip("llvmlite.binding")
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    machine = llvm.Target.from_triple("x86_64-unknown-linux-gnu").create_target_machine(
        cpu="x86-64", features="", opt=2, reloc="pic", codemodel="default")
    module = llvm.parse_assembly(packet_loop_module._IR)
    assert elf_text_section(machine.emit_object(module)) == packet_loop_module.X86_64_SYSV_CODE
