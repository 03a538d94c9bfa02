"""kernels/bounce.cl (the path integrator's fused bounce) against the numpy ``PathIntegrator._shade``
(the reference) per hit with the same random numbers, for every material and every kind of light the
kernel covers (emitting meshes and spheres among them, and textured parameters read from per-hit
rows); which materials and lights it covers; whole
paths equal to the numpy backend's; an area-light, a sky and an emitting-sphere furnace; and a plane's
closed-form radiance under point, spot and distant lights and under an emitting sphere. The spectral
build likewise: per hit, whole paths, a dispersive render against the numpy backend's, and the sky
and emitting-sphere furnaces read at each ray's wavelength."""

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from realistic import load_lens, render
from realistic.camera.lens_camera import LensCamera
from realistic.core.data_files import data_file
from realistic.core.spectrum import LAMBDA_MAX_NM, LAMBDA_MIN_NM, rgb_basis, rgb_response
from realistic.core.transforms import rotate, scale, translate
from realistic.optics.paraxial import film_distance_for_focus
from realistic.renderer.bsdf import fresnel
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import DistantLight, EmissiveInstance, InfiniteLight, PointLight, SpotLight
from realistic.scene.materials import (
    CoatedDiffuse,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Mirror,
    Mix,
    Plastic,
    ScaledTexture,
    Substrate,
)
from realistic.scene.model import AreaLight, CheckerTexture, GridTexture, ImageTexture, Material, Scene
from realistic.scene.shapes import quad, sphere
from test_bsdf_kernel import COVERED, three_samples  # noqa: F401 (a fixture)
from test_shading_reference import textured_scene

pytest.importorskip("realistic.camera.opencl_host")
pytestmark = pytest.mark.usefixtures("opencl_platform")

from realistic.device.opencl import Device  # noqa: E402
from realistic.renderer.bounce_kernel import (  # noqa: E402
    GOES_ON,
    MATERIALS,
    SHADES,
    SPECULAR,
    Bounce,
    BounceKernel,
    header,
    material_rows,
)
from realistic.renderer.bsdf_kernel import MAX_LOBES, TableStore  # noqa: E402

N = 6000


def _spot(falloff: str) -> SpotLight:
    """A spot light 3 above the floor pointing down, its cone 35 degrees wide, falling off from 25."""
    return SpotLight((40.0, 35.0, 30.0), translate(0.2, 3.0, 0.3) @ rotate(90, (1, 0, 0)), math.cos(math.radians(35)),
                     math.cos(math.radians(25)), falloff)


#: An environment map of 16 x 32 texels, bright toward one side, dark in a few texels.
SKY_IMAGE = (np.random.default_rng(12).random((16, 32, 3)) ** 3 + np.linspace(0.0, 1.0, 32)[None, :, None]
             ).astype(np.float32)
SKY_IMAGE[3:5, 7:9] = 0.0
#: Light sets beside ``textured_scene``'s two area lights (``None``: keep those): each kind the kernel
#: samples alone, and every kind together.
LIGHT_SETS = {
    "point": [PointLight((6.0, 5.0, 4.0), np.array([0.5, 2.5, 1.0]))],
    "spot, quartic": [_spot("quartic")],
    "spot, smoothstep": [_spot("smoothstep")],
    "distant": [DistantLight((2.0, 1.8, 1.5), np.array([0.3, 1.0, 0.4]) / np.linalg.norm([0.3, 1.0, 0.4]))],
    "infinite": [InfiniteLight((0.5, 0.6, 0.7))],
    "lat-long map": [InfiniteLight((0.8, 0.7, 0.6), 3 * SKY_IMAGE, "latlong", rotate(-90, (1, 0, 0)))],
    "equal-area map": [InfiniteLight((0.6, 0.7, 0.8), 3 * SKY_IMAGE[:, :16], "equal-area",
                                     rotate(30, (0, 1, 0)) @ rotate(-90, (1, 0, 0)))],
    "every kind": [None, PointLight((6.0, 5.0, 4.0), np.array([0.5, 2.5, 1.0])), _spot("smoothstep"),
                   DistantLight((0.5, 0.5, 0.5), np.array([0.0, 0.6, 0.8])), InfiniteLight((0.2, 0.3, 0.4)),
                   InfiniteLight((0.3, 0.3, 0.3), SKY_IMAGE, "latlong"), EmissiveInstance(2, (0.8, 1.0, 1.2))],
    # ``_scene``'s instances: 1 a sphere of radius 0.6 at (-0.8, 0.6, 0), 2 the gridded cone, 3 the
    # turned quad, 4 a mirrored sphere of radius 0.3 at (-0.2, 0.5, 1)
    "emitting mesh": [EmissiveInstance(3, (3.0, 2.0, 1.0))],
    "emitting sphere": [EmissiveInstance(1, (3.0, 2.0, 1.0), sphere=((-0.8, 0.6, 0.0), 0.6))],
    "emitting sphere, mirrored, two-sided": [None, EmissiveInstance(4, (1.0, 2.0, 3.0), two_sided=True,
                                                                    sphere=((-0.2, 0.5, 1.0), 0.3))],
    "emitting mesh, two-sided": [None, EmissiveInstance(2, (1.0, 2.0, 3.0), two_sided=True)],
    "emitting mesh, mirrored": [EmissiveInstance(4, (2.0, 2.5, 3.0)), EmissiveInstance(3, (1.0, 1.0, 1.0),
                                                                                         two_sided=True)]}


def _with_lights(scene: Scene, lights: list) -> Scene:
    """``scene`` with ``lights`` in place of its own (a ``None`` entry keeps its own there)."""
    own = scene.lights
    scene.lights = [light for entry in lights for light in (own if entry is None else [entry])]
    return scene


def _scene(material, lights: list | None = None) -> Scene:
    """``textured_scene`` with its sphere, cone and quad made of ``material`` and a mirrored copy of
    the sphere (a transform that swaps handedness) added; the floor keeps its EWA-filtered image;
    ``lights`` (``LIGHT_SETS``) in place of its area lights."""
    scene, _, _ = textured_scene()
    if lights is not None:
        _with_lights(scene, lights)
    scene.instances = scene.instances[:1] + [replace(inst, material=material) for inst in scene.instances[1:]]
    scene.add(scene.instances[1].mesh, translate(-0.2, 0.5, 1.0) @ scale(-0.5, 0.5, 0.5), material)
    return scene


def _rays(scene: Scene, n: int, seed: int):
    """Rays from around the eye toward the objects, and their closest hits."""
    rng = np.random.default_rng(seed)
    origin = (np.array([0.0, 1.0, 4.0]) + rng.uniform(-0.5, 0.5, (n, 3))).astype(np.float32)
    target = rng.uniform([-1.5, -0.2, -1.5], [1.5, 1.5, 1.5], (n, 3))
    direction = target - origin
    direction = (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)
    return origin, direction, Intersector(scene).closest(origin, direction)


def _pair(scene: Scene, mode: str = "path", mis: bool = True, light_samples: int = 3, spread: float = 0.0):
    """The numpy and the OpenCL backend's integrators (``spread``: the pixel spread, radians)."""
    numpy_one = PathIntegrator(scene, Intersector(scene), light_samples, 7, spread, 5, mode, mis, backend="numpy")
    device_one = PathIntegrator(scene, Intersector(scene), light_samples, 7, spread, 5, mode, mis, backend="opencl")
    assert device_one._bounce is not None
    return numpy_one, device_one


def _per_ray(rows: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Sums of ``values`` (k, C) by ray ``rows`` (k,), (n, C) float64."""
    return np.stack([np.bincount(rows, values[:, c], minlength=n) for c in range(values.shape[1])], axis=1)


def _mostly(close: np.ndarray) -> bool:
    """All but 0.2 % of the rows are close (a row may part where rounding crosses a threshold)."""
    return len(close) == 0 or float(close.mean()) > 0.998


def test_every_table_name_the_kernel_uses_is_declared_by_its_host():
    """As tests/test_tables.py checks the other kernels: the BOUNCE_ names come from the host's header."""
    code = re.sub(r"/\*.*?\*/", "", data_file("kernels/bounce.cl").read_text(encoding="utf-8"), flags=re.DOTALL)
    used = {name for name in re.findall(r"\b[A-Z][A-Z0-9_]*\b", code) if name.startswith("BOUNCE_")}
    declared = set(re.findall(r"^#define (\w+) ", header(1, 3, True), re.MULTILINE))
    assert used and used <= declared, used - declared
    assert not re.search(r"^#define BOUNCE_", code, re.MULTILINE)


def test_covered_materials():
    """Constant parameters of the materials bsdf.cl covers (named metals and mixes with their tables
    or second lobes in the BSDF kernel's tables), and the diffuse-like colour's grid or checker
    texture or its image texture (whatever its filter), a scaled one too: a ``Material``'s, a
    plastic's or substrate's Kd, a coated diffuse's reflectance, each in the material's row. Other
    textured parameters (roughness, a specular colour, a mirror's or glass's tints, a conductor's
    scale, a mix's amount) are covered by per-hit rows (``per_hit``), a mix's textured second material
    by per-hit second lobes too (``second_per_hit``); a mix holding a mix by per-hit trees (``tree``,
    ``tests/test_mix_trees.py``) up to ``MAX_LOBES`` lobes, not beyond."""
    tables = TableStore(Device.for_spec())
    for material in (*COVERED.values(), *TEXTURED.values()):
        assert material_rows(material, tables) is not None
    for sigma in (0.0, 20.0):
        assert material_rows(Material((1.0, 1.0, 1.0), GridTexture(cells=4.0), sigma=sigma), tables) is not None
        assert material_rows(Material((1.0, 1.0, 1.0), CheckerTexture(cells=4.0), sigma=sigma), tables) is not None
        for texture_filter in ("ewa", "bilinear", "point", "trilinear"):
            image = ImageTexture(np.ones((4, 4, 3), np.float32), filter=texture_filter)
            assert material_rows(Material((1.0, 1.0, 1.0), image, sigma=sigma), tables) is not None
    image = ImageTexture(np.ones((4, 4, 3), np.float32))
    for texture in (image, GridTexture(cells=4.0), CheckerTexture(cells=4.0), ScaledTexture(image, (0.5, 0.6, 0.7))):
        for material in (Plastic(texture), CoatedDiffuse(texture), Substrate(texture)):
            assert material_rows(material, tables)[1][MATERIALS.offset("per_hit")] == 0
    for per_hit in (Plastic((0.4, 0.4, 0.4), image), Plastic(image, image), Plastic(image, roughness=image),
                    CoatedDiffuse(image, roughness=image), CoatedDiffuse((0.5, 0.5, 0.5), image),
                    Substrate(image, image), Substrate(image, roughness_v=image), Mirror(image),
                    Dielectric(1.5, image), Conductor(scale=image), Mix(Plastic(image), Material(), 0.5),
                    Dielectric(1.5, roughness_u=image, roughness_v=0.2), Mix(Material(), Material(), image),
                    DiffuseTransmission(image), *(m for m, _ in PER_HIT.values())):
        rows = material_rows(per_hit, tables)
        assert rows is not None and rows[1][MATERIALS.offset("per_hit")] == 1, per_hit
        assert rows[1][MATERIALS.offset("second_per_hit")] == any(per_hit is m for m in SECOND_PER_HIT), per_hit
    for second in (Mix(Material(), Plastic(image), 0.5), Mix(Plastic(image), Material((1.0, 1.0, 1.0), image), image)):
        rows = material_rows(second, tables)
        assert rows is not None and rows[1][MATERIALS.offset("second_per_hit")] == 1, second
    for covered in (*COVERED.values(), *TEXTURED.values()):
        assert material_rows(covered, tables)[1][MATERIALS.offset("second_per_hit")] == 0
    for nested in (Mix(Material(), Mix(Material(), Plastic(image)), 0.5),
                   Mix(Mix(Material(), Plastic()), Material(), 0.5)):
        assert material_rows(nested, tables)[1][MATERIALS.offset("tree")] == 1
    assert material_rows(_beyond_max_lobes(Plastic(image)), tables) is None


def _beyond_max_lobes(material) -> Mix:
    """A mix tree of ``MAX_LOBES`` + 1 lobes, ``material`` the deepest: more than the kernel takes."""
    tree = material
    for k in range(MAX_LOBES):
        tree = Mix(Material((0.3 + 0.05 * k, 0.5, 0.4)), tree, 0.8)
    return tree


#: An image of 64 x 32 texels with little symmetry, for the image-textured materials.
IMAGE = np.random.default_rng(11).random((32, 64, 3)).astype(np.float32)
#: Textured materials the kernel covers, beside ``COVERED``.
TEXTURED = {"grid": Material((0.9, 0.8, 0.7), GridTexture(cells=5.0, line_width=0.2)),
            "checker": Material((0.7, 0.7, 0.7), CheckerTexture(cells=6.0)),
            "oren-nayar under a grid": Material((0.9, 0.8, 0.7), GridTexture(cells=5.0, line_width=0.2), sigma=15.0),
            "image, ewa": Material((0.9, 0.8, 0.7), ImageTexture(IMAGE, scale=(3.0, 2.0), max_anisotropy=4.0)),
            "image, bilinear": Material((0.6, 0.9, 0.8), ImageTexture(IMAGE, scale=(2.0, 5.0), v_origin="top",
                                                                      filter="bilinear", wrap="clamp",
                                                                      offset=(0.3, -0.2))),
            "image, point": Material((0.7, 0.8, 0.9), ImageTexture(IMAGE, scale=(3.0, 3.0), filter="point",
                                                                   wrap="black")),
            "image, trilinear": Material((0.8, 0.7, 0.9), ImageTexture(IMAGE, scale=(2.0, 3.0), filter="trilinear",
                                                                       offset=(0.1, 0.2))),
            "oren-nayar under an image": Material((0.8, 0.8, 0.9), ImageTexture(IMAGE, scale=(4.0, 4.0), wrap="black"),
                                                  sigma=20.0),
            # the diffuse-like colour of the other materials under each kind of texture, coloured
            # cells and scaled textures among them (a coated base is remade from the albedo per hit)
            "plastic under a grid": Plastic(GridTexture(base=(0.2, 0.7, 0.4), line=(0.7, 0.1, 0.3), cells=5.0,
                                                        line_width=0.2), (0.3, 0.2, 0.3), 0.15),
            "plastic under a checker": Plastic(ScaledTexture(CheckerTexture(even=(0.9, 0.3, 0.1), odd=(0.1, 0.4, 0.9),
                                                                            cells=6.0), (0.8, 0.6, 0.7)),
                                               (0.2, 0.2, 0.2), 0.0),
            "plastic under an image": Plastic(ImageTexture(IMAGE, scale=(3.0, 2.0), max_anisotropy=4.0),
                                              (0.25, 0.25, 0.25), 0.2),
            "coated diffuse under a grid": CoatedDiffuse(GridTexture(base=(0.2, 0.9, 0.4), line=(0.9, 0.1, 0.3),
                                                                     cells=5.0, line_width=0.2), 0.1),
            "coated diffuse under a checker": CoatedDiffuse(CheckerTexture(even=(0.9, 0.5, 0.1), odd=(0.1, 0.2, 0.8),
                                                                           cells=6.0), 0.0, eta=1.7),
            "coated diffuse under an image": CoatedDiffuse(ScaledTexture(
                ImageTexture(IMAGE, scale=(2.0, 5.0), filter="bilinear", wrap="clamp"), (0.9, 0.7, 1.0)), 0.2),
            "substrate under a grid": Substrate(GridTexture(cells=5.0, line_width=0.2), (0.1, 0.05, 0.1), 0.2, 0.1),
            "substrate under a checker": Substrate(CheckerTexture(even=(0.9, 0.3, 0.1), odd=(0.1, 0.4, 0.9), cells=6.0),
                                                   (0.05, 0.05, 0.05), 0.3, 0.3),
            "substrate under an image": Substrate(ImageTexture(IMAGE, scale=(3.0, 3.0), filter="trilinear",
                                                               offset=(0.1, 0.2)), (0.08, 0.1, 0.06), 0.1, 0.25)}
#: The pixel spread (radians) of the per-hit comparison: the image textures' footprints at depth 0.
SPREAD = 4e-3
#: Roughness in [0.02, 0.5] of little symmetry (an image's channels' mean).
ROUGH = (0.02 + 0.48 * IMAGE).astype(np.float32)
#: Materials with textured parameters beyond the diffuse-like colour, which the kernel reads from
#: per-hit rows (``per_hit``), each with the same material holding a constant in the texture's place
#: (about its mean): the kernel must shade the two differently.
PER_HIT = {
    "plastic, image roughness": (Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), ImageTexture(ROUGH, scale=(3.0, 2.0))),
                                 Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), 0.26)),
    "plastic, grid roughness, image kd": (
        Plastic(ImageTexture(IMAGE, scale=(2.0, 2.0)), (0.3, 0.3, 0.3),
                GridTexture(base=(0.05, 0.05, 0.05), line=(0.4, 0.5, 0.6), cells=5.0, line_width=0.3)),
        Plastic(ImageTexture(IMAGE, scale=(2.0, 2.0)), (0.3, 0.3, 0.3), 0.2)),
    "plastic, image ks": (Plastic((0.5, 0.3, 0.2), ScaledTexture(ImageTexture(IMAGE, scale=(3.0, 3.0)),
                                                                (0.6, 0.5, 0.4)), 0.15),
                          Plastic((0.5, 0.3, 0.2), (0.3, 0.25, 0.2), 0.15)),
    "conductor, checker roughness": (
        Conductor(roughness_u=CheckerTexture(even=(0.03, 0.03, 0.03), odd=(0.4, 0.4, 0.4), cells=6.0),
                  roughness_v=0.2),
        Conductor(roughness_u=0.2, roughness_v=0.2)),
    "conductor, image eta, k and scale": (
        Conductor(ImageTexture(0.2 + 2 * IMAGE, scale=(2.0, 3.0)), ImageTexture(1 + 3 * IMAGE[::-1]), 0.1, 0.1,
                  scale=CheckerTexture(even=(0.9, 0.7, 0.5), odd=(0.5, 0.8, 1.0), cells=6.0)),
        Conductor((1.2, 1.2, 1.2), (2.5, 2.5, 2.5), 0.1, 0.1, scale=(0.7, 0.75, 0.75))),
    "rough dielectric, image roughness": (
        Dielectric(1.5, roughness_u=ImageTexture(ROUGH, scale=(2.0, 2.0)), roughness_v=ImageTexture(ROUGH[:, ::-1])),
        Dielectric(1.5, roughness_u=0.26, roughness_v=0.26)),
    "dielectric, textured tints": (Dielectric(1.5, CheckerTexture(even=(1.0, 0.8, 0.6), odd=(0.5, 0.7, 1.0),
                                                                  cells=6.0), ImageTexture(IMAGE)),
                                   Dielectric(1.5, (0.75, 0.75, 0.8), (0.5, 0.5, 0.5))),
    "coated diffuse, image roughness": (CoatedDiffuse((0.8, 0.3, 0.2), ImageTexture(ROUGH, scale=(3.0, 3.0))),
                                        CoatedDiffuse((0.8, 0.3, 0.2), 0.26)),
    "substrate, grid roughness": (
        Substrate((0.6, 0.5, 0.3), (0.1, 0.1, 0.1), 0.1,
                  GridTexture(base=(0.03, 0.03, 0.03), line=(0.5, 0.5, 0.5), cells=5.0, line_width=0.3)),
        Substrate((0.6, 0.5, 0.3), (0.1, 0.1, 0.1), 0.1, 0.2)),
    "mix, checker amount": (Mix(Material((0.7, 0.6, 0.5)), Conductor(roughness_u=0.1, roughness_v=0.1),
                                CheckerTexture(even=(0.1, 0.1, 0.1), odd=(0.9, 0.9, 0.9), cells=6.0)),
                            Mix(Material((0.7, 0.6, 0.5)), Conductor(roughness_u=0.1, roughness_v=0.1), 0.5)),
    "mix, image amount, textured first": (
        Mix(Plastic((0.2, 0.5, 0.8), (0.3, 0.3, 0.3), ImageTexture(ROUGH)), CoatedDiffuse((0.9, 0.2, 0.4), 0.1),
            ImageTexture(IMAGE, scale=(2.0, 3.0))),
        Mix(Plastic((0.2, 0.5, 0.8), (0.3, 0.3, 0.3), 0.26), CoatedDiffuse((0.9, 0.2, 0.4), 0.1), 0.5)),
    # a mix's textured second material: each hit's second lobe from its own row (``second_per_hit``)
    "mix of two image-textured materials": (
        Mix(Material((0.9, 0.8, 0.7), ImageTexture(IMAGE, scale=(3.0, 2.0))),
            Plastic(ImageTexture(IMAGE[::-1, ::-1], scale=(2.0, 3.0)), (0.3, 0.3, 0.3), 0.1), 0.6),
        Mix(Material((0.9, 0.8, 0.7), ImageTexture(IMAGE, scale=(3.0, 2.0))),
            Plastic((0.5, 0.5, 0.5), (0.3, 0.3, 0.3), 0.1), 0.6)),
    "mix, second of image roughness": (
        Mix(Material((0.7, 0.6, 0.5)), Conductor(roughness_u=ImageTexture(ROUGH, scale=(3.0, 2.0)),
                                                 roughness_v=ImageTexture(ROUGH[:, ::-1], scale=(2.0, 2.0))), 0.7),
        Mix(Material((0.7, 0.6, 0.5)), Conductor(roughness_u=0.26, roughness_v=0.26), 0.7)),
    "mix, checker amount, textured coated second": (
        Mix(Plastic((0.2, 0.5, 0.8), (0.3, 0.3, 0.3), 0.1),
            CoatedDiffuse(ImageTexture(IMAGE, scale=(2.0, 2.0)),
                          GridTexture(base=(0.03, 0.03, 0.03), line=(0.4, 0.4, 0.4), cells=5.0, line_width=0.3)),
            CheckerTexture(even=(0.2, 0.2, 0.2), odd=(0.8, 0.8, 0.8), cells=6.0)),
        Mix(Plastic((0.2, 0.5, 0.8), (0.3, 0.3, 0.3), 0.1), CoatedDiffuse((0.5, 0.5, 0.5), 0.2), 0.5)),
    "mix, named metal second of checker roughness": (
        Mix(Material((0.3, 0.5, 0.7)), Conductor(roughness_u=CheckerTexture(even=(0.02, 0.02, 0.02),
                                                                            odd=(0.4, 0.4, 0.4), cells=6.0),
                                                 roughness_v=0.1, spectra=("Cu", "Cu")), 0.6),
        Mix(Material((0.3, 0.5, 0.7)), Conductor(roughness_u=0.2, roughness_v=0.1, spectra=("Cu", "Cu")), 0.6)),
}
#: The ``PER_HIT`` mixes whose second material is textured (``second_per_hit``).
SECOND_PER_HIT = [PER_HIT[name][0] for name in ("mix of two image-textured materials", "mix, second of image roughness",
                                               "mix, checker amount, textured coated second",
                                               "mix, named metal second of checker roughness")]


@pytest.mark.parametrize("name", sorted(PER_HIT))
@pytest.mark.parametrize("depth", [0, 2])
@pytest.mark.parametrize("mode, mis, spectral", [("path", True, False), ("direct", False, False),
                                                 ("path", True, True), ("direct", True, True)])
def test_bounce_kernel_shades_textured_parameters_per_hit_as_the_numpy_reference(name, depth, mode, mis,
                                                                                spectral):
    """Textured roughness (plastic, coated diffuse, substrate, conductor, rough glass; image, grid
    and checker textures), a textured specular colour, a conductor's textured eta, k and scale,
    glass's textured tints, a mix's textured amount (its first material textured too) and a mix's
    textured second material (two image-textured materials; a second of image or checker
    roughness, a named metal's among them; with a checker amount), RGB and spectral: per hit as the
    other materials, each hit's own rows looked up as ``_shade`` looks them up (image textures over
    the pixel footprint at depth 0); and the same material with a constant in the texture's place
    shades the hits differently, so a kernel that read the material's constant (or any one hit's
    row for all) would fail."""
    textured, constant = PER_HIT[name]
    seed = 300 + sorted(PER_HIT).index(name)
    got = _shades_as_numpy(textured, depth, mode, mis, seed, spectral=spectral)
    plain = _shades_as_numpy(constant, depth, mode, mis, seed, spectral=spectral)
    apart = ~np.all(np.isclose(got.beta, plain.beta, rtol=1e-3, atol=1e-6), axis=1) | (got.flags != plain.flags)
    assert apart.mean() > 0.05, apart.mean()


@pytest.mark.parametrize("name", sorted(COVERED) + sorted(TEXTURED))
@pytest.mark.parametrize("depth", [0, 1, 3])
@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", True), ("direct", False)])
def test_bounce_kernel_shades_each_hit_as_the_numpy_reference(name, depth, mode, mis):
    """Per hit, with the same random numbers: every light sample's shadow ray and contribution (summed
    per ray with several light samples at depth 0), and the next ray, beta, pdf and flags, to float32
    rounding (a decision may part only where rounding moves a number across its threshold); image
    textures filtered over the pixel's footprint at depth 0 (``SPREAD``) and at level 0 deeper, as
    ``_shade`` filters them."""
    names = sorted(COVERED) + sorted(TEXTURED)
    _shades_as_numpy(TEXTURED.get(name) or COVERED[name], depth, mode, mis, names.index(name))


@pytest.mark.parametrize("depth", [0, 2])
@pytest.mark.parametrize("spectral", [False, True])
def test_bounce_kernel_shades_measured_brdfs_as_the_numpy_reference(three_samples, depth, spectral):  # noqa: F811
    """A .brdf file's table and a mix holding it (both in the BSDF kernel's tables), per hit as above,
    for RGB rays and for spectral ones (the table's RGB at the ray's wavelength)."""
    for seed, material in enumerate((three_samples, Mix(Plastic(), three_samples, 0.7))):
        _shades_as_numpy(material, depth, "path", True, 40 + seed, spectral=spectral)


@pytest.mark.parametrize("lights", sorted(LIGHT_SETS))
@pytest.mark.parametrize("name", ["matte", "rough conductor", "plastic"])
@pytest.mark.parametrize("depth", [0, 2])
@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", False)])
def test_bounce_kernel_shades_each_hit_under_each_light_as_the_numpy_reference(lights, name, depth, mode, mis):
    """Point, spot (both falloffs), distant and infinite lights (constant, or a lat-long or
    equal-area map in a turned frame), alone and with area lights, per hit as above: the delta
    lights' samples unweighted, the sky's MIS-weighted, shadow rays to the light's position or along
    its direction to ``FAR``."""
    materials = {"matte": Material((0.7, 0.6, 0.5)), "rough conductor": Conductor(roughness_u=0.3, roughness_v=0.3),
                 "plastic": Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), 0.1)}
    _shades_as_numpy(materials[name], depth, mode, mis, 60 + sorted(LIGHT_SETS).index(lights), LIGHT_SETS[lights])


#: Materials the spectral build shades: every material the RGB build covers (each colour, a
#: conductor's eta and k, a named metal's or measured table's RGB, a coated base and both lobes of a
#: mix at the ray's wavelength), and ``Material``s under each texture, with grids and checkers of
#: coloured cells too (the texture's spectral value multiplies the diffuse colour's, which differs
#: from the spectral value of their product), and coloured eta and k.
SPECTRAL = {**COVERED,
            "coloured grid": Material((0.9, 0.8, 0.7), GridTexture(base=(0.2, 0.9, 0.4), line=(0.9, 0.1, 0.3),
                                                                   cells=5.0, line_width=0.2)),
            "coloured checker, oren-nayar": Material((0.6, 0.8, 0.9), CheckerTexture(
                even=(0.9, 0.3, 0.1), odd=(0.1, 0.4, 0.9), cells=6.0), sigma=15.0),
            "coloured conductor": Conductor((0.2, 0.9, 1.6), (3.9, 2.4, 2.0), 0.2, 0.1, scale=(0.9, 0.7, 1.0)),
            "coloured coated diffuse in a mix": Mix(Material((0.2, 0.5, 0.9)), CoatedDiffuse((0.9, 0.2, 0.4), 0.1),
                                                    0.6),
            **TEXTURED}


@pytest.mark.parametrize("name", sorted(SPECTRAL))
@pytest.mark.parametrize("depth", [0, 1, 3])
@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", True), ("direct", False)])
def test_spectral_bounce_kernel_shades_each_hit_as_the_numpy_reference(name, depth, mode, mis):
    """Rays of one wavelength each, per hit as the RGB comparison: the albedo's and the lights'
    spectral values at each ray's wavelength, beta and the contributions one column wide."""
    _shades_as_numpy(SPECTRAL[name], depth, mode, mis, 80 + sorted(SPECTRAL).index(name), spectral=True)


@pytest.mark.parametrize("lights", sorted(LIGHT_SETS))
@pytest.mark.parametrize("depth", [0, 2])
@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", False)])
def test_spectral_bounce_kernel_shades_each_hit_under_each_light_as_the_numpy_reference(lights, depth, mode, mis):
    """Spectral rays under every kind of light the kernel samples (point, spot, distant, infinite
    with and without a map, emitting meshes and spheres, area lights), per hit as above: each
    light's radiance, and an environment map's texel, at the ray's wavelength."""
    _shades_as_numpy(Material((0.7, 0.6, 0.5)), depth, mode, mis, 100 + sorted(LIGHT_SETS).index(lights),
                     LIGHT_SETS[lights], spectral=True)


def _shades_as_numpy(material, depth: int, mode: str, mis: bool, seed: int, lights: list | None = None,
                     spectral: bool = False) -> Bounce:
    """The per-hit comparison of the kernel and ``_shade`` on ``_scene(material, lights)`` (rays from
    ``seed``); ``spectral``: rays of one wavelength each (uniform over the visible), the kernel's
    spectral build against ``_shade`` given their ``rgb_basis`` rows, beta one column. The kernel's
    result."""
    scene = _scene(material, lights)
    numpy_one, device_one = _pair(scene, mode, mis, spread=SPREAD)
    origin, direction, hits = _rays(scene, N, seed)
    on_instance = (hits.geom >= 0) & (hits.geom < device_one.instance_count)
    covered = device_one._bounce.covered[device_one._geom_material[np.where(on_instance, hits.geom, 0)]]
    surface = np.flatnonzero(on_instance & covered)
    assert len(surface) > N // 4
    rng = np.random.default_rng(depth)
    path = rng.permutation(N)  # each ray its own camera ray, out of order
    beta = rng.uniform(0.2, 1.0, (N, 1 if spectral else 3)).astype(np.float32)
    pixel, sample = rng.integers(0, 1 << 20, N), rng.integers(0, 64, N)
    basis = rgb_basis(rng.uniform(LAMBDA_MIN_NM, LAMBDA_MAX_NM, N)) if spectral else None  # per camera ray
    expected = numpy_one._shade(hits, surface, path, origin, direction, beta, None if basis is None else basis[path],
                                pixel, sample, depth)
    got = device_one._bounce(surface, path, pixel.astype(np.uint32), sample.astype(np.uint32), origin, direction,
                             hits, beta, depth=depth, light_samples=3 if depth == 0 else 1, seed=7,
                             mode_flags=device_one._bounce_flags, max_depth=5, basis=basis,
                             hit_parameters=device_one._hit_parameters(hits, surface, direction,
                                                                       None if basis is None else basis[path], depth))
    assert got.contribution.shape[1] == got.beta.shape[1] == beta.shape[1]
    lights = 3 if depth == 0 else 1
    assert len(got.shadow_length) == lights * len(surface)
    # shadow rays: the same samples live, with the same contributions
    live = got.shadow_length > 0
    ray = np.tile(path[surface], lights)
    shadow = expected["shadow"]
    # a sample of a flat emitter from a point on the same facet lies in its plane (cos 0: dead) but
    # for rounding, which may leave it live on either side with a contribution of that rounding's size
    tiny = 1e-7 * max(float(np.abs(shadow["contribution"]).max(initial=0.0)), 1e-30)
    weighty = int(np.count_nonzero(np.abs(got.contribution).max(axis=1) > tiny))
    assert abs(weighty - int(np.count_nonzero(np.abs(shadow["contribution"]).max(axis=1, initial=0.0) > tiny))) \
        <= 1e-3 * len(live) + 1
    assert np.all(got.contribution[~live] == 0)
    sums = _per_ray(ray, got.contribution, N), _per_ray(shadow["rows"], shadow["contribution"], N)
    close = np.all(np.isclose(sums[0], sums[1], rtol=2e-3, atol=1e-6 * max(float(sums[1].max()), 1e-30)), axis=1)
    assert _mostly(close), close.mean()
    if lights == 1:  # one sample per ray: its ray, compared where both made it
        order = np.argsort(shadow["rows"])
        rows = shadow["rows"][order]
        mine = np.flatnonzero(live)
        both = np.intersect1d(ray[mine], rows)
        at_mine = mine[np.argsort(ray[mine])][np.searchsorted(np.sort(ray[mine]), both)]
        at_ref = order[np.searchsorted(rows, both)]
        assert np.allclose(got.shadow_origin[at_mine], shadow["start"][at_ref], atol=1e-4)
        assert np.allclose(got.shadow_vector[at_mine], shadow["vector"][at_ref], atol=2e-4, rtol=1e-4)
        assert np.array_equal(got.shadow_length[at_mine], shadow["length"][at_ref])
    # the next rays
    goes = (got.flags & GOES_ON) != 0
    next_path = path[surface][goes]
    assert len(np.setxor1d(next_path, expected["path"])) <= 2e-3 * len(surface) + 1
    both, mine, ref = np.intersect1d(next_path, expected["path"], return_indices=True)
    rows = np.flatnonzero(goes)[mine]
    assert np.array_equal((got.flags[rows] & SPECULAR) != 0, expected["specular"][ref])
    assert np.array_equal((got.flags[rows] & SHADES) != 0, expected["shade"][ref])
    assert np.allclose(got.point[rows], expected["point"][ref], atol=1e-5)
    assert np.allclose(got.origin[rows], expected["origin"][ref], atol=1e-4)
    direction_close = np.all(np.isclose(got.direction[rows], expected["direction"][ref], atol=2e-4), axis=1)
    assert _mostly(direction_close)
    beta_close = np.all(np.isclose(got.beta[rows], expected["beta"][ref], rtol=2e-3, atol=1e-7), axis=1)
    assert _mostly(beta_close)
    pdf_close = np.isclose(got.pdf[rows], expected["pdf"][ref], rtol=2e-3)
    assert _mostly(pdf_close)
    return got


def _paths_agree(scene: Scene, numpy_one: PathIntegrator, device_one: PathIntegrator, seed: int,
                 spectral: bool = False) -> None:
    """Whole paths of N rays into ``scene`` (``_rays``' seed ``seed``; ``spectral``: each of one
    wavelength, uniform over the visible): each ray's radiance the numpy backend's to float32
    rounding (99 % of rays), the mean to 2e-3, the shadow rays to 1 %."""
    origin, direction, _ = _rays(scene, N, seed)
    rng = np.random.default_rng(seed + 1)
    pixel, sample = rng.integers(0, 1 << 20, N), rng.integers(0, 64, N)
    wavelength = rng.uniform(LAMBDA_MIN_NM, LAMBDA_MAX_NM, N) if spectral else None
    expected, expected_shadows = numpy_one.radiance(origin, direction, pixel, sample, None, wavelength)
    got, shadows = device_one.radiance(origin, direction, pixel, sample, None, wavelength)
    top = float(np.abs(expected).max())
    close = np.all(np.isclose(got, expected, rtol=1e-3, atol=1e-5 * top), axis=1)
    assert close.mean() > 0.99, close.mean()
    assert abs(float(got.mean()) / float(expected.mean()) - 1) < 2e-3
    assert abs(shadows - expected_shadows) <= 0.01 * expected_shadows


def _kernel_paths_agree(scene: Scene, mode: str, seed: int, spectral: bool, monkeypatch) -> BounceKernel:
    """``_paths_agree`` on whole paths (two light samples, a pixel spread) over ``scene``, every one of
    whose materials the fused bounce covers, with ``_shade`` never called (every hit is the kernel's);
    the device integrator's bounce kernel, for the caller's own checks of how it covered them."""
    numpy_one, device_one = _pair(scene, mode, light_samples=2, spread=SPREAD)
    assert device_one._bounce is not None and device_one._bounce.covered.all()
    monkeypatch.setattr(device_one, "_shade", None)  # never called: every hit is the kernel's
    _paths_agree(scene, numpy_one, device_one, seed, spectral=spectral)
    return device_one._bounce


@pytest.mark.parametrize("mode, mis", [("path", True), ("path", False), ("direct", True), ("direct", False)])
def test_paths_through_the_bounce_kernel_carry_the_numpy_radiance(mode, mis):
    """Whole paths (depth 5, two light samples), glass, a rough conductor, an Oren-Nayar quad,
    plastic and diffuse transmission in the kernel and the floor, a mix tree of more lobes than
    ``MAX_LOBES`` (the one material the kernel lacks) holding a plastic whose Ks is an image texture,
    in numpy: each ray's radiance is the numpy backend's to float32 rounding (a path may only part
    where rounding moves a sample across a threshold)."""
    scene, _, _ = textured_scene()
    floor = scene.instances[0].material
    specular = ScaledTexture(floor.texture, (0.3, 0.3, 0.3))
    scene.instances[0] = replace(scene.instances[0],
                                 material=_beyond_max_lobes(Plastic((0.5, 0.4, 0.3), specular, 0.2)))
    materials = [None, Dielectric(1.5), Conductor(roughness_u=0.2, roughness_v=0.05), Material((0.3, 0.6, 0.9),
                                                                                             sigma=20.0)]
    scene.instances = [inst if m is None else replace(inst, material=m) for inst, m in zip(scene.instances, materials)]
    scene.add(sphere(0.3, 16), translate(0.2, 0.3, 0.8), Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), 0.2))
    scene.add(sphere(0.25, 16), translate(-0.6, 0.3, 0.9), COVERED["diffuse transmission"])
    numpy_one, device_one = _pair(scene, mode, mis, light_samples=2)
    assert not device_one._bounce.covered[device_one._geom_material[0]]
    _paths_agree(scene, numpy_one, device_one, 3)


@pytest.mark.parametrize("mode, spectral", [("path", False), ("direct", False), ("path", True), ("direct", True)])
def test_paths_over_textured_parameters_carry_the_numpy_radiance(mode, spectral, monkeypatch):
    """Whole paths, RGB and spectral, over ``textured_scene`` with a plastic floor whose Kd is its
    EWA image and whose roughness an image, a mix of a Lambertian and a rough conductor under a
    checkered amount, glass of image-textured roughness and a conductor of checkered roughness,
    seen with a pixel spread: every hit is the kernel's, the textured ones from per-hit rows
    (``_shade`` is never called), and each ray's radiance is the numpy backend's to float32 rounding."""
    scene, _, _ = textured_scene()
    floor = Plastic(scene.instances[0].material.texture, (0.3, 0.3, 0.3), ImageTexture(ROUGH, scale=(4.0, 4.0)))
    materials = [floor, PER_HIT["mix, checker amount"][0], PER_HIT["rough dielectric, image roughness"][0],
                 PER_HIT["conductor, checker roughness"][0]]
    scene.instances[:4] = [replace(inst, material=m) for inst, m in zip(scene.instances, materials)]
    assert len(_kernel_paths_agree(scene, mode, 17, spectral, monkeypatch)._per_hit) == 4


@pytest.mark.parametrize("mode, spectral", [("path", False), ("direct", False), ("path", True), ("direct", True)])
def test_paths_over_mixes_of_textured_second_materials_carry_the_numpy_radiance(mode, spectral, monkeypatch):
    """Whole paths, RGB and spectral, over ``textured_scene`` whose floor, sphere, cone and quad are
    mixes whose second material is textured (two image-textured materials, a second of image
    roughness, a textured coated second under a checker amount, a named metal's second of checker
    roughness), seen with a pixel spread: every hit is the kernel's, second lobes from per-hit rows
    (``_shade`` is never called), and each ray's radiance is the numpy backend's to float32 rounding."""
    scene, _, _ = textured_scene()
    scene.instances[:4] = [replace(inst, material=m) for inst, m in zip(scene.instances, SECOND_PER_HIT)]
    assert len(_kernel_paths_agree(scene, mode, 19, spectral, monkeypatch)._second_per_hit) == 4


@pytest.mark.parametrize("mode", ["path", "direct"])
def test_paths_over_image_textures_carry_the_numpy_radiance(mode):
    """Whole paths over image textures in the kernel: ``textured_scene``'s EWA floor, a bilinear
    Oren-Nayar sphere and a Lambertian quad under an image, seen with a pixel spread (footprints at
    the first hit, level 0 deeper): each ray's radiance is the numpy backend's to float32 rounding."""
    scene, _, _ = textured_scene()
    scene.instances[3] = replace(scene.instances[3], material=TEXTURED["image, ewa"])
    scene.instances[1] = replace(scene.instances[1], material=replace(TEXTURED["image, bilinear"], sigma=10.0))
    numpy_one, device_one = _pair(scene, mode, light_samples=2, spread=SPREAD)
    assert device_one._bounce is not None and device_one._bounce.covered.all()
    _paths_agree(scene, numpy_one, device_one, 5)


@pytest.mark.parametrize("mode, spectral", [("path", False), ("direct", False), ("path", True)])
def test_paths_over_textured_coated_diffuse_plastic_and_substrate_carry_the_numpy_radiance(mode, spectral,
                                                                                           monkeypatch):
    """Whole paths, RGB and spectral, over ``textured_scene`` with a coated diffuse floor under its
    EWA image texture (a scaled one), a plastic sphere under a checker and a substrate cone under a
    grid, seen with a pixel spread: every hit is the kernel's (``_shade`` is never called) and each
    ray's radiance is the numpy backend's to float32 rounding."""
    scene, _, _ = textured_scene()
    floor, ball, cone = (scene.instances[k].material for k in range(3))
    materials = [CoatedDiffuse(ScaledTexture(floor.texture, (0.9, 0.8, 0.7)), 0.1),
                 Plastic(ball.texture, (0.3, 0.3, 0.3), 0.1), Substrate(cone.texture, (0.1, 0.1, 0.1), 0.2, 0.2)]
    scene.instances[:3] = [replace(inst, material=m) for inst, m in zip(scene.instances, materials)]
    _kernel_paths_agree(scene, mode, 13, spectral, monkeypatch)


def _spectral_launches(integrator: PathIntegrator, monkeypatch) -> list[np.ndarray]:
    """The material of each hit ``integrator``'s bounce kernel shades for spectral rays, one array
    per launch, as its renders launch it."""
    kernel, launches = integrator._bounce, []

    def spy(rows, path, pixel, sample, origin, direction, hits, beta, **options):
        if options["basis"] is not None:
            launches.append(integrator._geom_material[hits.geom[rows]])
        return kernel(rows, path, pixel, sample, origin, direction, hits, beta, **options)

    monkeypatch.setattr(integrator, "_bounce", spy)
    return launches


@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", True), ("direct", False)])
def test_spectral_paths_through_the_bounce_kernel_carry_the_numpy_radiance(mode, mis, monkeypatch):
    """Whole spectral paths (depth 5, two light samples) under every kind of light, over glass, a
    rough conductor, a named metal, plastic, diffuse transmission, coated diffuse in a mix and
    Lambertian and Oren-Nayar materials under image, grid and checker textures: each ray's radiance
    is the numpy backend's to float32 rounding, and the kernel's spectral build shades every hit, on
    every material, in every bounce's launch."""
    scene = _with_lights(textured_scene()[0], LIGHT_SETS["every kind"])
    materials = [None, Dielectric(1.5, (0.9, 1.0, 0.8), (1.0, 0.7, 0.9)), SPECTRAL["coloured grid"],
                 SPECTRAL["coloured coated diffuse in a mix"]]
    scene.instances = [inst if m is None else replace(inst, material=m) for inst, m in zip(scene.instances, materials)]
    scene.add(sphere(0.3, 16), translate(0.2, 0.3, 0.8), Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), 0.2))
    scene.add(sphere(0.3, 16), translate(-0.6, 0.3, 0.9), SPECTRAL["coloured conductor"])
    scene.add(sphere(0.25, 16), translate(0.7, 0.8, 0.6), SPECTRAL["coloured checker, oren-nayar"])
    scene.add(sphere(0.2, 16), translate(-0.1, 0.9, 0.5), COVERED["named metal"])
    scene.add(sphere(0.2, 16), translate(0.5, 0.2, 1.1), COVERED["diffuse transmission"])
    numpy_one, device_one = _pair(scene, mode, mis, light_samples=2, spread=SPREAD)
    assert device_one._bounce.covered[device_one._geom_material].all()
    launches = _spectral_launches(device_one, monkeypatch)
    monkeypatch.setattr(device_one, "_shade", None)  # never called: every hit is the kernel's
    _paths_agree(scene, numpy_one, device_one, 11, spectral=True)
    assert len(launches) >= 2 and all(len(materials) for materials in launches)
    instances = device_one._geom_material[:device_one.instance_count]
    assert set(np.unique(np.concatenate(launches))) == set(instances)


def test_a_dispersive_path_traced_render_on_opencl_is_the_numpy_backends(monkeypatch):
    """A path-traced render through the dgauss lens with dispersion (three wavelengths per sample) of
    a checkered floor, an Oren-Nayar sphere, a plastic one, a copper one and a glass one, on the
    OpenCL backend (its spectral bounces in the kernel) and on the numpy one with the same seed:
    every pixel agrees to float32 rounding, far inside the noise between two seeds, and so does the
    mean."""
    launches = []
    launch = BounceKernel.__call__

    def counted(self, *args, **options):
        launches.append(options["basis"] is not None)
        return launch(self, *args, **options)

    monkeypatch.setattr(BounceKernel, "__call__", counted)
    lens = load_lens("dgauss")
    camera = LensCamera(lens, film_distance_for_focus(lens, 1000.0), 43.27, 32, 32, 16,
                        translate(0, 0, 1.0) @ rotate(180, (1, 0, 0)) @ scale(1e-3), spectral=True)
    scene = Scene(integrator="path", max_depth=4)
    scene.add(quad(4.0, 4.0), material=SPECTRAL["coloured checker, oren-nayar"])
    scene.add(sphere(0.1, 24), translate(0.0, 0.0, 0.1), Material((0.3, 0.6, 0.9), sigma=20.0))
    scene.add(sphere(0.06, 24), translate(0.12, 0.05, 0.06), Plastic((0.5, 0.3, 0.2), (0.2, 0.4, 0.6), 0.2))
    scene.add(sphere(0.05, 24), translate(-0.12, -0.04, 0.05), Conductor(roughness_u=0.1, roughness_v=0.1,
                                                                         spectra=("Cu", "Cu")))
    scene.add(sphere(0.05, 24), translate(0.02, -0.14, 0.05), Dielectric(1.5))
    scene.lights.append(AreaLight("disk", (0.4, 0.4), (20.0, 30.0, 40.0), translate(-0.3, 0.2, 1.2)
                                  @ rotate(180, (1, 0, 0))))
    device = render(scene, camera, "opencl", seed=1)
    assert launches and all(launches)  # every launch spectral
    reference, other_seed = (render(scene, camera, "numpy", seed=seed) for seed in (1, 2))
    top = float(np.abs(reference).max())
    assert np.all(np.isclose(device, reference, rtol=1e-3, atol=1e-5 * top))
    assert np.abs(device - reference).max() < 0.01 * np.abs(other_seed - reference).max()
    np.testing.assert_allclose(device.mean(axis=(0, 1)), reference.mean(axis=(0, 1)), rtol=1e-4)


def _spectral_values(radiance: np.ndarray, wavelength: np.ndarray) -> np.ndarray:
    """The spectral value each ray carried: ``radiance`` is it times the film's weight
    ``rgb_response`` at the ray's wavelength (their quotient in the channel of the largest weight)."""
    response = rgb_response(wavelength)
    column = np.abs(response).argmax(axis=1)
    rows = np.arange(len(radiance))
    return radiance[rows, column].astype(np.float64) / response[rows, column]


def _down_rays(height: float, half: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """N unit rays from (0, 0, height) toward points uniform in [-half, half]^2 on the plane z = 0."""
    origin = np.tile(np.float32([[0.0, 0.0, height]]), (N, 1))
    target = rng.uniform(-half, half, (N, 3)) * np.array([1.0, 1.0, 0.0])
    direction = target - origin
    return origin, (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)


def _inside_rays(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """N rays from points uniform in [-0.3, 0.3]^3 (inside the unit sphere) along uniform unit directions."""
    origin = rng.uniform(-0.3, 0.3, (N, 3)).astype(np.float32)
    direction = rng.normal(size=(N, 3))
    return origin, (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)


def _covering_integrator(scene: Scene, mode: str) -> PathIntegrator:
    """The path integrator (depth 5, one light sample) on the opencl backend, its bounce kernel covering
    every material of ``scene``."""
    integrator = PathIntegrator(scene, Intersector(scene), 1, 3, 0.0, 5, mode, backend="opencl")
    assert integrator._bounce is not None and integrator._bounce.covered.all()
    return integrator


def _spectral_reading(integrator: PathIntegrator, origin: np.ndarray, direction: np.ndarray,
                      rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The radiance of spectral rays (wavelengths uniform over the visible range), their
    wavelengths and their ``rgb_basis`` rows (float64)."""
    wavelength = rng.uniform(LAMBDA_MIN_NM, LAMBDA_MAX_NM, N)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int), None, wavelength)
    return radiance, wavelength, rgb_basis(wavelength).astype(np.float64)


def _assert_mean_reads(radiance: np.ndarray, expected: float) -> None:
    """The rays' first channel reads ``expected`` on average, within 4 standard errors (and 2e-3)."""
    value = radiance[:, 0].astype(np.float64)
    error = value.std() / np.sqrt(N)
    assert abs(value.mean() - expected) < 4 * error + 2e-3, (value.mean(), error)


def _reads_per_wavelength(value: np.ndarray, expected: np.ndarray, wavelength: np.ndarray) -> None:
    """``value`` / ``expected`` (per ray) has mean 1 within 4 standard errors in each quarter of the
    visible."""
    ratio = value / expected
    for quarter in np.array_split(np.argsort(wavelength), 4):
        mean, error = ratio[quarter].mean(), ratio[quarter].std() / np.sqrt(len(quarter))
        assert abs(mean - 1) < 4 * error + 2e-3, (wavelength[quarter].mean(), mean, error)


@pytest.mark.parametrize("mode", ["direct", "path"])
@pytest.mark.parametrize("albedo, sky", [((0.7, 0.7, 0.7), (0.8, 0.8, 0.8)), ((0.8, 0.5, 0.2), (0.4, 0.7, 1.0))])
@pytest.mark.parametrize("image, mapping", [(None, "latlong"), (np.ones((8, 16, 3), np.float32), "latlong"),
                                            (np.ones((8, 8, 3), np.float32), "equal-area")])
def test_spectral_rays_on_a_convex_lambertian_under_a_uniform_sky_read_albedo_times_sky(mode, albedo, sky, image,
                                                                                       mapping):
    """Under a uniform infinite light of radiance L (constant, or a map of ones sampled by its
    tables) every point of a convex Lambertian of albedo a sees the whole sky once, so a ray of
    wavelength w reads a(w) L(w), the spectral values of the RGB a and L there (the dot with the
    ``rgb_basis`` row; grey a and L: a L at every wavelength, the RGB reading), in the kernel's
    spectral build."""
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), Material(albedo))
    scene.lights.append(InfiniteLight(sky, image, mapping, rotate(40, (1, 1, 0))))
    integrator = _covering_integrator(scene, mode)
    rng = np.random.default_rng(1)
    radiance, wavelength, basis = _spectral_reading(integrator, *_down_rays(3.0, 0.5, rng), rng)
    _reads_per_wavelength(_spectral_values(radiance, wavelength), basis @ albedo * (basis @ sky), wavelength)


@pytest.mark.parametrize("mode", ["path", "direct"])
@pytest.mark.parametrize("albedo", [(0.6, 0.6, 0.6), (0.9, 0.5, 0.2)])
def test_spectral_rays_inside_an_emitting_sphere_read_the_series_at_their_wavelength(mode, albedo):
    """Inside a closed sphere of Lambertian albedo a emitting Le (as the RGB test), a ray of
    wavelength w reads Le(w) (1 - a(w)^6) / (1 - a(w)) in "path" mode and Le(w) (1 + a(w)) in
    "direct" mode, a(w) and Le(w) the spectral values there: the series in the albedo's spectral
    value, bounce after bounce, not in any RGB colour's."""
    le = np.array([2.0, 1.5, 1.0])
    scene = Scene()
    scene.add(sphere(1.0, 24), np.eye(4), Material(albedo))
    scene.lights.append(EmissiveInstance(0, tuple(le), two_sided=True))
    integrator = _covering_integrator(scene, mode)
    rng = np.random.default_rng(2)
    radiance, wavelength, basis = _spectral_reading(integrator, *_inside_rays(rng), rng)
    a, emitted = basis @ albedo, basis @ le
    expected = emitted * (1 - a ** 6) / (1 - a) if mode == "path" else emitted * (1 + a)
    _reads_per_wavelength(_spectral_values(radiance, wavelength), expected, wavelength)


@pytest.mark.parametrize("mode", ["path", "direct"])
@pytest.mark.parametrize("material", ["coloured conductor", "coloured mirror"])
def test_spectral_rays_off_a_smooth_conductor_under_a_uniform_sky_read_its_fresnel_times_sky(mode, material):
    """A ray of wavelength w mirrored by a smooth flat conductor of scale s and index eta + i k into
    a uniform sky of radiance L reads s(w) F(cos; eta(w), k(w)) L(w), each the spectral value of its
    RGB there, F the conductor Fresnel at the ray's cosine (a mirror: s(w) L(w)): per ray, to float32
    rounding (the one path is deterministic: a smooth lobe takes no light sample)."""
    conductor = Conductor((0.2, 0.9, 1.6), (3.9, 2.4, 2.0), 0.0, 0.0, scale=(0.9, 0.7, 1.0))
    chosen = conductor if material == "coloured conductor" else Mirror((0.9, 0.4, 0.7))
    sky = np.array([0.4, 0.7, 1.0])
    scene = Scene()
    scene.add(quad(4.0, 4.0), np.eye(4), chosen)
    scene.lights.append(InfiniteLight(tuple(sky)))
    integrator = _covering_integrator(scene, mode)
    rng = np.random.default_rng(3)
    origin, direction = _down_rays(3.0, 1.5, rng)
    radiance, wavelength, basis = _spectral_reading(integrator, origin, direction, rng)
    if chosen is conductor:
        reflectance = basis @ conductor.scale * fresnel.conductor(
            -direction[:, 2], (basis @ conductor.eta)[:, None], (basis @ conductor.k)[:, None])[:, 0]
    else:
        reflectance = basis @ chosen.reflectance
    np.testing.assert_allclose(_spectral_values(radiance, wavelength), reflectance * (basis @ sky), rtol=2e-3)


def _area_light_furnace(material) -> Scene:
    """A unit sphere of ``material`` inside a cube of six two-sided quad lights of radiance 1 (each a
    little larger than its face, so no ray leaves through an edge)."""
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), material)
    faces = [rotate(0, (1, 0, 0)), rotate(180, (1, 0, 0)), rotate(90, (1, 0, 0)), rotate(-90, (1, 0, 0)),
             rotate(90, (0, 1, 0)), rotate(-90, (0, 1, 0))]
    for face in faces:
        scene.lights.append(AreaLight("quad", (4.05, 4.05), (1.0, 1.0, 1.0), face @ translate(0, 0, 2.0),
                                      two_sided=True))
    return scene


@pytest.mark.parametrize("mode", ["direct", "path"])
@pytest.mark.parametrize("material, albedo", [
    (Material((0.7, 0.7, 0.7)), 0.7), (Conductor((1.0,) * 3, (1e4,) * 3, 0.0, 0.0), 1.0),
    (Mix(Material((0.7, 0.7, 0.7)), Conductor((1.0,) * 3, (1e4,) * 3, 0.0, 0.0), 0.25), 0.775),
    (Dielectric(1.0, roughness_u=0.3, roughness_v=0.3), 1.0)])
def test_convex_object_inside_area_lights_reads_its_albedo(mode, material, albedo):
    """Inside a closed box of lights of radiance 1, a convex Lambertian of albedo a reads a, a
    smooth perfect conductor 1, a mix of the two 0.75 a + 0.25, and rough glass of index 1 (which
    lets light straight through) 1 (light sampling and BSDF sampling weighted by MIS, on the kernel)."""
    scene = _area_light_furnace(material)
    integrator = _covering_integrator(scene, mode)
    rng = np.random.default_rng(0)
    origin, direction = _down_rays(1.8, 0.4, rng)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    _assert_mean_reads(radiance, albedo)


def test_the_kernel_takes_scenes_without_lights_and_with_every_kind_of_light():
    """No light (nothing to sample: the camera rays' misses see the background, the rest is black,
    as on the numpy backend); point, spot, distant and infinite lights, emitting meshes and spheres."""
    scene = _scene(Material((0.5, 0.5, 0.5)))
    scene.lights = []
    integrator = PathIntegrator(scene, Intersector(scene), 1, 3, 0.0, 5, "path", backend="opencl")
    assert integrator._bounce is not None
    origin, direction, hits = _rays(scene, 500, 1)
    radiance, shadows = integrator.radiance(origin, direction, np.arange(500), np.zeros(500, int))
    assert shadows == 0 and np.any(hits.geom >= 0)
    assert np.array_equal(radiance, np.where((hits.geom < 0)[:, None], np.float32(scene.background), 0))
    _with_lights(scene, LIGHT_SETS["every kind"][1:])
    assert PathIntegrator(scene, Intersector(scene), backend="opencl")._bounce is not None
    scene.lights += [EmissiveInstance(1, (1.0, 1.0, 1.0)), EmissiveInstance(2, (1.0, 1.0, 1.0),
                                                                            sphere=((0.0, 0.0, 0.0), 1.0))]
    assert PathIntegrator(scene, Intersector(scene), backend="opencl")._bounce is not None


@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", True), ("direct", False)])
def test_paths_under_every_kind_of_light_carry_the_numpy_radiance(mode, mis):
    """Whole paths (depth 5, two light samples) under area, point, spot, distant and constant
    infinite lights together, over glass, a rough conductor, plastic and textured Lambertians: each
    ray's radiance is the numpy backend's to float32 rounding, escaping rays seeing the sky weighted
    by MIS against its light samples as in numpy."""
    scene = _with_lights(textured_scene()[0], LIGHT_SETS["every kind"])
    materials = [None, Dielectric(1.5), Conductor(roughness_u=0.2, roughness_v=0.05), Material((0.3, 0.6, 0.9),
                                                                                             sigma=20.0)]
    scene.instances = [inst if m is None else replace(inst, material=m) for inst, m in zip(scene.instances, materials)]
    scene.add(sphere(0.3, 16), translate(0.2, 0.3, 0.8), Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), 0.2))
    numpy_one, device_one = _pair(scene, mode, mis, light_samples=2)
    assert device_one._bounce.covered.all()
    _paths_agree(scene, numpy_one, device_one, 7)


@pytest.mark.parametrize("mode", ["path", "direct"])
def test_a_lambertian_plane_reads_the_closed_form_under_point_spot_and_distant_lights(mode):
    """A Lambertian floor of albedo a, each light alone, on the kernel (no noise: delta lights, and
    nothing else to reach): under a point light of intensity I at height h, at distance x from its
    foot, radiance a I h / (pi d^3) with d^2 = h^2 + x^2 (a I / (pi h^2) at the foot); a spot light
    there pointing down the same times pbrt-v3's quartic falloff of the angle from its axis; a
    distant light of radiance E at 30 degrees from the zenith a E cos 30 / pi everywhere."""
    a, intensity, h = 0.6, 5.0, 2.0
    x = np.array([0.0, 0.5, 1.0, 1.5, 2.0])  # 0, 14, 27, 37 and 45 degrees from the spot's axis
    d = np.hypot(h, x)
    point = a * intensity * h / (math.pi * d ** 3)
    cos_total, cos_start = math.cos(math.radians(40)), math.cos(math.radians(20))
    falloff = np.clip((h / d - cos_total) / (cos_start - cos_total), 0.0, 1.0) ** 4
    assert falloff[0] == 1 and 0 < falloff[2] < 1 and falloff[-1] == 0
    tilt = math.radians(30)
    cases = [(PointLight((intensity,) * 3, np.array([0.0, h, 0.0])), point),
             (SpotLight((intensity,) * 3, translate(0.0, h, 0.0) @ rotate(90, (1, 0, 0)), cos_total, cos_start),
              point * falloff),
             (DistantLight((intensity,) * 3, np.array([math.sin(tilt), math.cos(tilt), 0.0])),
              np.full(len(x), a * intensity * math.cos(tilt) / math.pi))]
    target = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    origin = (target + np.array([-0.3, 3.0, 2.0])).astype(np.float32)
    direction = (target - origin) / np.linalg.norm(target - origin, axis=1, keepdims=True)
    for light, expected in cases:
        scene = Scene()
        scene.add(quad(40.0, 40.0), rotate(-90, (1, 0, 0)), Material((a, a, a)))
        scene.lights = [light]
        integrator = _covering_integrator(scene, mode)
        radiance, _ = integrator.radiance(origin, direction.astype(np.float32), np.arange(len(x)),
                                          np.zeros(len(x), int))
        assert np.allclose(radiance, expected[:, None], rtol=1e-4, atol=1e-7), (light, radiance[:, 0], expected)


@pytest.mark.parametrize("mode", ["direct", "path"])
@pytest.mark.parametrize("material, albedo", [
    (Material((0.7, 0.7, 0.7)), 0.7), (Conductor((1.0,) * 3, (1e4,) * 3, 0.0, 0.0), 1.0),
    (Mix(Material((0.7, 0.7, 0.7)), Conductor((1.0,) * 3, (1e4,) * 3, 0.0, 0.0), 0.25), 0.775)])
@pytest.mark.parametrize("image, mapping", [(None, "latlong"), (np.ones((8, 16, 3), np.float32), "latlong"),
                                            (np.ones((8, 8, 3), np.float32), "equal-area")])
def test_convex_object_under_a_uniform_sky_reads_its_albedo_times_the_sky(mode, material, albedo, image, mapping):
    """Under a uniform infinite light of radiance L (constant, or a map of ones sampled by its
    tables: by sin(theta) over a lat-long map's rows), every point of a convex object sees the
    whole sky: a Lambertian of albedo a reads a L, a smooth perfect conductor L, a mix of the two
    (0.75 a + 0.25) L (the sky's light samples and the BSDF samples that escape to it weighted by
    MIS, on the kernel)."""
    sky = 0.8
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), material)
    scene.lights.append(InfiniteLight((sky, sky, sky), image, mapping, rotate(40, (1, 1, 0))))
    integrator = _covering_integrator(scene, mode)
    rng = np.random.default_rng(1)
    origin, direction = _down_rays(3.0, 0.5, rng)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    _assert_mean_reads(radiance, albedo * sky)


@pytest.mark.parametrize("mode", ["direct", "path"])
@pytest.mark.parametrize("reflectance", [0.0, 0.3, 1.0])
def test_white_diffuse_transmission_under_a_uniform_sky_reads_the_sky(mode, reflectance):
    """A plane of diffuse transmission with R + T = 1 under a uniform infinite light of radiance L:
    both its sides see the whole sky, so the reflected R L and the transmitted T L sum to L."""
    sky = 0.8
    scene = Scene()
    scene.add(quad(40.0, 40.0), np.eye(4), DiffuseTransmission((reflectance,) * 3, (1.0 - reflectance,) * 3))
    scene.lights.append(InfiniteLight((sky, sky, sky)))
    integrator = _covering_integrator(scene, mode)
    origin, direction = _down_rays(3.0, 0.5, np.random.default_rng(2))
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    _assert_mean_reads(radiance, sky)


@pytest.mark.parametrize("lights", ["emitting mesh", "emitting mesh, two-sided", "emitting mesh, mirrored",
                                    "emitting sphere", "emitting sphere, mirrored, two-sided"])
@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", True), ("direct", False)])
def test_paths_under_emitting_instances_carry_the_numpy_radiance(lights, mode, mis):
    """Whole paths (depth 5, two light samples) lit by emitting meshes and spheres (one- and
    two-sided, under a mirroring transform, beside area lights), over glass, a rough conductor and textured
    Lambertians: each ray's radiance is the numpy backend's to float32 rounding, BSDF samples that
    reach an emitting mesh weighted by MIS against its light samples as in numpy."""
    scene = _scene(Material((0.5, 0.5, 0.5)), LIGHT_SETS[lights])
    materials = [None, Dielectric(1.5), Conductor(roughness_u=0.2, roughness_v=0.05), None, Material((0.3, 0.6, 0.9),
                                                                                                   sigma=20.0)]
    scene.instances = [inst if m is None else replace(inst, material=m) for inst, m in zip(scene.instances, materials)]
    numpy_one, device_one = _pair(scene, mode, mis, light_samples=2)
    assert device_one._bounce.covered.all()
    _paths_agree(scene, numpy_one, device_one, 9)


@pytest.mark.parametrize("mode", ["path", "direct"])
@pytest.mark.parametrize("mirrored", [False, True])
@pytest.mark.parametrize("as_sphere", [False, True])
def test_inside_an_emitting_sphere_of_albedo_a_reads_the_closed_form(mode, mirrored, as_sphere):
    """Inside a closed sphere of Lambertian albedo a emitting Le on its inside (a mesh, sampled by
    its triangles), radiance is uniform and L = Le + a L, cut at the path's depth D = 5:
    Le (1 - a^(D + 1)) / (1 - a) in "path" mode (roulette keeps the mean), Le (1 + a) in "direct"
    mode (emission seen, and the first hit's direct light). The inside is the emitting side either
    by a mirroring transform (the world winding turns inward: one-sided) or by two-sidedness. Given as
    an emitting sphere (``EmissiveInstance.sphere``), points inside it sample it by area too."""
    a, le = 0.6, 2.0
    scene = Scene()
    scene.add(sphere(1.0, 24), scale(-1.0, 1.0, 1.0) if mirrored else np.eye(4), Material((a, a, a)))
    scene.lights.append(EmissiveInstance(0, (le, le, le), two_sided=not mirrored,
                                         sphere=((0.0, 0.0, 0.0), 1.0) if as_sphere else None))
    integrator = _covering_integrator(scene, mode)
    rng = np.random.default_rng(2)
    origin, direction = _inside_rays(rng)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    value = radiance[:, 0].astype(np.float64)
    expected = le * (1 - a ** 6) / (1 - a) if mode == "path" else le * (1 + a)
    error = value.std() / np.sqrt(N)
    assert abs(value.mean() - expected) < 4 * error + 1e-3 * expected, (value.mean(), expected, error)


@pytest.mark.parametrize("mode", ["path", "direct"])
def test_a_lambertian_plane_under_an_emitting_sphere_reads_the_closed_form(mode):
    """A black sphere of radius r emitting Le at height h above a Lambertian floor of albedo a (the
    sphere sampled by the cone it subtends, its mesh met on the host): a uniform sphere above the
    horizon lights a point at distance D from its centre as a point light of intensity pi r^2 Le, so
    the floor reads a Le (r / D)^2 cos(theta), cos(theta) = h / D. The mesh inscribed in the sphere
    (64 segments) subtends a little less: under 1 % here, so the reading lies in [0.99, 1] of it,
    within the noise of N samples."""
    a, le, r, h = 0.6, 5.0, 0.25, 2.0
    scene = Scene()
    scene.add(quad(40.0, 40.0), rotate(-90, (1, 0, 0)), Material((a, a, a)))
    scene.add(sphere(r, 64), translate(0.0, h, 0.0), Material((0.0, 0.0, 0.0)))
    scene.lights.append(EmissiveInstance(1, (le, le, le), sphere=((0.0, h, 0.0), r)))
    integrator = _covering_integrator(scene, mode)
    x = np.array([0.0, 0.7, 1.5, 3.0])
    d2 = h * h + x * x
    expected = a * le * r * r / d2 * h / np.sqrt(d2)
    target = np.repeat(np.column_stack([x, np.zeros_like(x), np.zeros_like(x)]), N, axis=0)
    origin = (target + np.array([-0.3, 3.0, 2.0])).astype(np.float32)
    direction = ((target - origin) / np.linalg.norm(target - origin, axis=1, keepdims=True)).astype(np.float32)
    radiance, _ = integrator.radiance(origin, direction, np.arange(len(target)), np.zeros(len(target), int))
    value = radiance[:, 0].astype(np.float64).reshape(len(x), N)
    mean, error = value.mean(axis=1), value.std(axis=1) / np.sqrt(N)
    assert np.all(mean > 0.99 * expected - 4 * error) and np.all(mean < expected + 4 * error), (mean / expected, error)
