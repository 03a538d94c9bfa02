"""Mixes holding mixes on the device: the fused bounce (``kernels/bounce.cl`` with ``bsdf.cl``'s
``tree_eval`` and ``tree_sample``) against the numpy ``PathIntegrator._shade``, whose nested
``WeightedSum``s (``bsdf_for``) are the reference: per hit with the same random numbers and whole
paths that never reach ``_shade``, RGB and spectral, path and direct modes; constant and textured
amounts and lobes at both levels, three levels deep. Each tree also shades apart from the same tree
with its innermost mix's second lobe dropped, so a kernel that dropped a nested lobe (or weighed it
wrongly) fails the comparison. A tree of more lobes than ``MAX_LOBES`` stays numpy, and a mix made of
itself is a one-line ``UserError`` naming the material when the scene is read."""

from dataclasses import replace

import numpy as np
import pytest

import realistic
from bsdf_helpers import ConstantHits
from realistic.errors import UserError
from realistic.renderer.bsdf import bsdf_for
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.materials import (
    CoatedDiffuse,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Mirror,
    Mix,
    Plastic,
    Substrate,
)
from realistic.scene.model import CheckerTexture, GridTexture, ImageTexture, Material
from test_bounce_kernel import IMAGE, ROUGH, _kernel_paths_agree, _shades_as_numpy
from test_bsdf_kernel import _matches_numpy
from test_shading_reference import textured_scene

pytest.importorskip("realistic.camera.opencl_host")
pytestmark = pytest.mark.usefixtures("opencl_platform")

from realistic.device.opencl import Device  # noqa: E402
from realistic.renderer import bsdf_kernel  # noqa: E402
from realistic.renderer.bounce_kernel import MATERIALS, constant_tree, material_rows  # noqa: E402
from realistic.renderer.bsdf_kernel import MAX_LOBES, BsdfKernel, TableStore  # noqa: E402
from realistic.renderer.surface_parameters import SurfaceParameters  # noqa: E402

#: A checkerboard amount (pbrt's "float" checkerboard: its channels' mean).
CHECKER_AMOUNT = CheckerTexture(even=(0.15, 0.15, 0.15), odd=(0.85, 0.85, 0.85), cells=6.0)


def _trees(inner_second: bool) -> dict[str, Mix]:
    """The mixes holding mixes the tests shade; ``inner_second`` False: each with its innermost mix's
    second material dropped (that mix replaced by its first), which must shade differently."""

    def inner(first, second, amount) -> object:
        return Mix(first, second, amount) if inner_second else first

    return {
        # pbrt-v4's nesting: a mix of (a mix of diffuse and a rough conductor) and glass
        "mix of (diffuse + conductor) and glass": Mix(
            inner(Material((0.7, 0.5, 0.3)), Conductor(roughness_u=0.1, roughness_v=0.2), 0.3), Dielectric(1.5), 0.4),
        "textured amounts at both levels": Mix(
            inner(Plastic((0.2, 0.5, 0.8), (0.3, 0.3, 0.3), 0.1), Conductor(roughness_u=0.05, roughness_v=0.05),
                  CHECKER_AMOUNT),
            CoatedDiffuse((0.9, 0.2, 0.4), 0.1), ImageTexture(IMAGE, scale=(2.0, 3.0))),
        # the mix second, its lobes textured, under an image-textured Lambertian
        "textured lobes in a second mix": Mix(
            Material((0.9, 0.8, 0.7), ImageTexture(IMAGE, scale=(3.0, 2.0))),
            inner(Conductor(roughness_u=ImageTexture(ROUGH, scale=(3.0, 2.0)), roughness_v=0.1),
                  Dielectric(1.5, roughness_u=0.2, roughness_v=0.2), 0.5), 0.6),
        # three levels: ((diffuse + substrate) + named metal) + (diffuse transmission + mirror), a grid amount
        "three levels deep": Mix(
            Mix(inner(Material((0.8, 0.3, 0.2)), Substrate((0.3, 0.5, 0.6), (0.1, 0.1, 0.1), 0.1, 0.2),
                      GridTexture(base=(0.8, 0.8, 0.8), line=(0.2, 0.2, 0.2), cells=5.0, line_width=0.3)),
                Conductor(roughness_u=0.2, roughness_v=0.2, spectra=("Cu", "Cu")), 0.35),
            Mix(DiffuseTransmission((0.4, 0.5, 0.3), (0.3, 0.2, 0.4)), Mirror((0.8, 0.8, 0.9)), 0.3), 0.55)}


TREES = _trees(True)
DROPPED = _trees(False)


def _chain(leaves: int) -> Mix:
    """A mix of ``leaves`` Lambertian lobes, each mix holding the next."""
    tree: object = Material((0.5, 0.5, 0.5))
    for k in range(leaves - 1):
        tree = Mix(Material((0.2 + 0.1 * (k % 7), 0.5, 0.4)), tree, 0.6)
    assert isinstance(tree, Mix)
    return tree


def test_mixes_holding_mixes_are_the_kernels_with_per_hit_trees():
    """Every tree above is the fused bounce's, each hit's tree from the host (``tree``, no other
    per-hit row); so is a chain of ``MAX_LOBES`` lobes, while one more lobe stays numpy."""
    tables = TableStore(Device.for_spec())
    for tree in (*TREES.values(), _chain(MAX_LOBES)):
        rows = material_rows(tree, tables)
        assert rows is not None
        assert rows[1][MATERIALS.offset("tree")] == 1
        assert rows[1][MATERIALS.offset("per_hit")] == rows[1][MATERIALS.offset("second_per_hit")] == 0
    assert material_rows(_chain(MAX_LOBES + 1), tables) is None
    for plain in (Mix(Material(), Plastic(), 0.5), Plastic(), Mix(Material(), Plastic(), CHECKER_AMOUNT)):
        assert material_rows(plain, tables)[1][MATERIALS.offset("tree")] == 0


@pytest.mark.parametrize("name", sorted(TREES))
@pytest.mark.parametrize("depth", [0, 2])
@pytest.mark.parametrize("mode, mis, spectral", [("path", True, False), ("direct", False, False),
                                                 ("path", True, True), ("direct", True, True)])
def test_mix_trees_shade_each_hit_as_the_numpy_reference(name, depth, mode, mis, spectral):
    """Per hit, with the same random numbers, RGB and spectral: light samples, next rays, beta, pdf
    and flags as ``_shade``'s (``test_bounce_kernel._shades_as_numpy``); and the same tree with its
    innermost mix's second lobe dropped shades the hits differently."""
    seed = 500 + sorted(TREES).index(name)
    got = _shades_as_numpy(TREES[name], depth, mode, mis, seed, spectral=spectral)
    dropped = _shades_as_numpy(DROPPED[name], depth, mode, mis, seed, spectral=spectral)
    apart = ~np.all(np.isclose(got.beta, dropped.beta, rtol=1e-3, atol=1e-6), axis=1) | (got.flags != dropped.flags)
    assert apart.mean() > 0.05, apart.mean()


@pytest.mark.parametrize("mode, spectral", [("path", False), ("direct", False), ("path", True), ("direct", True)])
def test_paths_over_mix_trees_never_reach_numpy_and_carry_its_radiance(mode, spectral, monkeypatch):
    """Whole paths (depth 5, two light samples), RGB and spectral, over ``textured_scene`` whose floor,
    sphere, cone and quad are the four trees, seen with a pixel spread: every hit is the kernel's
    (``_shade`` is never called) and each ray's radiance is the numpy backend's to float32 rounding."""
    scene, _, _ = textured_scene()
    scene.instances[:4] = [replace(inst, material=m) for inst, m in zip(scene.instances, TREES.values())]
    assert len(_kernel_paths_agree(scene, mode, 23, spectral, monkeypatch)._trees) == 4


#: Trees nothing in which is textured (``constant_tree``): two of ``TREES``' trees as they are or
#: with a constant amount in place of the grid, a mix of two mixes, and a chain of ``MAX_LOBES`` lobes.
CONSTANT_TREES = [TREES["mix of (diffuse + conductor) and glass"],
                  Mix(Mix(Plastic((0.2, 0.5, 0.8), (0.3, 0.3, 0.3), 0.1), CoatedDiffuse((0.9, 0.2, 0.4), 0.1), 0.3),
                      Mix(Mirror((0.8, 0.8, 0.9)), DiffuseTransmission((0.4, 0.5, 0.3), (0.3, 0.2, 0.4)), 0.7), 0.45),
                  replace(TREES["three levels deep"], first=replace(TREES["three levels deep"].first,
                                                                  first=replace(TREES["three levels deep"].first.first,
                                                                                amount=0.6))),
                  _chain(MAX_LOBES)]


def test_constant_trees_have_one_row_each_hits_row():
    """A tree nothing in which is textured has one ``TREE`` row, bit for bit the row ``tree_rows``
    makes at each of its RGB hits; a textured tree has none (its rows are made per hit)."""
    tables = TableStore(Device.for_spec())
    count = 7
    at_hits = SurfaceParameters(count, lambda: np.zeros((count, 2), np.float32), lambda: None, None)
    for tree in CONSTANT_TREES:
        row = constant_tree(tree, tables)
        assert row is not None and row.shape == (1, bsdf_kernel.tree_width(bsdf_kernel.leaf_count(tree)))
        np.testing.assert_array_equal(bsdf_kernel.tree_rows(tree, at_hits, count, tables),
                                      np.repeat(row, count, axis=0), strict=True)
    for name in ("textured amounts at both levels", "textured lobes in a second mix", "three levels deep"):
        assert constant_tree(TREES[name], tables) is None


@pytest.mark.parametrize("mode, spectral", [("path", False), ("direct", False), ("path", True)])
def test_paths_over_constant_trees_make_no_row_per_hit_for_rgb_rays(mode, spectral, monkeypatch):
    """Whole paths over ``textured_scene`` whose floor, sphere, cone and quad are ``CONSTANT_TREES``
    carry the numpy backend's radiance; RGB rays' bounces ask ``tree_rows`` for no hit's row (the
    trees' one rows are made with the kernel), spectral rays' for each hit's (their colours vary
    with each hit's wavelength)."""
    counts: list[int] = []
    made = bsdf_kernel.tree_rows

    def counted(material, hits, count, tables):
        counts.append(count)
        return made(material, hits, count, tables)

    monkeypatch.setattr(bsdf_kernel, "tree_rows", counted)
    scene, _, _ = textured_scene()
    scene.instances[:4] = [replace(inst, material=m) for inst, m in zip(scene.instances, CONSTANT_TREES)]
    bounce = _kernel_paths_agree(scene, mode, 29, spectral, monkeypatch)
    assert len(bounce._trees) == len(bounce._constant_trees) == 4
    assert (max(counts) > 1) == spectral


@pytest.mark.parametrize("spectral", [False, True])
@pytest.mark.parametrize("index", range(len(CONSTANT_TREES)))
def test_the_bsdf_kernel_evaluates_and_samples_trees_as_the_numpy_bsdf(index, spectral):
    """The standalone BSDF kernel (``_shade``'s) given a tree's rows (``BsdfKernel.rows``: a "tree"
    row and its ``TREE`` row) evaluates and samples it as ``bsdf_for``'s nested ``WeightedSum``s,
    RGB and spectral (``test_bsdf_kernel._matches_numpy``); a tree of more than ``MAX_LOBES`` lobes
    has no rows."""
    kernel = BsdfKernel(Device.for_spec())
    _matches_numpy(kernel, CONSTANT_TREES[index], 700 + index, spectral=spectral)
    assert kernel.rows(_chain(MAX_LOBES + 1), ConstantHits(3), 3) is None


@pytest.mark.parametrize("spectral", [False, True])
def test_paths_through_the_bsdf_kernel_over_mix_trees_carry_the_numpy_radiance(spectral, monkeypatch):
    """Whole paths (depth 5, two light samples) over ``textured_scene`` whose sphere, cone and quad
    are trees of three to five lobes, textured and not, with the fused bounce off: ``_shade`` launches
    every hit's BSDF on the standalone kernel (the floor's rows and the trees' wider ones padded to
    one width), none in numpy, and each ray's radiance is the numpy backend's to float32 rounding."""
    scene, eye, target = textured_scene()
    trees = [TREES["textured lobes in a second mix"], TREES["three levels deep"], CONSTANT_TREES[1]]
    scene.instances[1:4] = [replace(inst, material=m) for inst, m in zip(scene.instances[1:4], trees)]
    rng = np.random.default_rng(31)
    n = 4000
    origin = np.tile(np.asarray(eye, np.float32), (n, 1))
    aim = np.asarray(target, np.float32) + rng.uniform(-1.2, 1.2, (n, 3)).astype(np.float32)
    direction = ((aim - origin) / np.linalg.norm(aim - origin, axis=1, keepdims=True)).astype(np.float32)
    args = (origin, direction, np.arange(n), np.zeros(n, np.int64), None,
            rng.uniform(400, 700, n) if spectral else None)
    images, numpy_bsdfs = [], []
    for backend in ("numpy", "opencl"):
        integrator = PathIntegrator(scene, Intersector(scene), 2, 3, 1e-3, 5, "path", backend=backend)
        if backend == "opencl":
            integrator._bounce = integrator._bounce_covers = None  # every hit through ``_shade``
            monkeypatch.setattr(integrator, "bsdf_factory",
                                lambda material, hits: numpy_bsdfs.append(material) or bsdf_for(material, hits))
        images.append(integrator.radiance(*args)[0])
    assert numpy_bsdfs == []
    expected, got = images
    scale = float(np.abs(expected).max())
    close = np.all(np.isclose(got, expected, rtol=1e-4, atol=1e-5 * scale), axis=1)
    assert close.mean() > 0.99, close.mean()
    assert abs(float(got.mean()) / float(expected.mean()) - 1) < 1e-3


def test_a_mix_made_of_itself_is_one_line_naming_it():
    """A mix naming itself never reaches the renderer: reading the scene says which material."""
    description = {"shapes": [{"type": "sphere", "radius": 1.0, "material": "loop"}],
                   "materials": {"loop": {"type": "mix", "materials": ["loop", "grey"]},
                                 "grey": {"type": "diffuse"}}}
    with pytest.raises(UserError) as error:
        realistic.load_dict(description)
    message = str(error.value)
    assert "\n" not in message and message.startswith("materials.loop:") and "made of itself" in message
