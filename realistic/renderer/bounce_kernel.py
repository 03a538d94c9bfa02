"""OpenCL host of the path integrator's fused bounce: ``kernels/bounce.cl`` on a ``Device``.

``PathIntegrator`` (``renderer/path.py``) uses it on the "opencl" backend: one launch per bounce takes
the surface hits (embree's t, u, v, prim, geom, Ng) to every light sample's shadow ray and contribution
(MIS-weighted) and the BSDF sample's next ray, beta, pdf and flags; the host keeps embree and the
compaction of live paths. It covers scenes whose lights are area, point, spot, distant or
infinite lights, emitting meshes or spheres, or none, and every material ``bsdf_kernel.parameters``
covers, a mix whose second material is textured too. Constant parameters come from one row per
material (measured tables, named metals' tables and mixes' second lobes in the
BSDF kernel's ``TableStore``), and so does the diffuse-like colour (``diffuse_texture``: a ``Material``'s albedo,
a plastic's or substrate's Kd, a coated diffuse's reflectance, the latter three also as a ``ScaledTexture``)
also under a grid or checker texture (evaluated in the kernel) or an image texture (any filter:
``ewa_kernel.DEVICE_FILTERS``), a coated base remade from it per hit:
before each launch ``EwaKernel.at_hits`` turns those hits' records into their colour on the device, with
the footprint ``PathIntegrator._shade`` gives at that depth (the camera's pixel spread at depth 0, none
deeper: level 0 bilinear), and the kernel reads it per hit in place of the row's constant. Any
other textured parameter (roughness, a specular colour, a mirror's or glass's tints, a conductor's
scale, eta or k, a mix's amount or textured first material; ``MATERIALS``' ``per_hit``) makes each
hit's ``BSDF_PARAMS`` row on the host before the launch (``_hit_rows``: ``bsdf_kernel.parameters``
with ``PathIntegrator._hit_parameters``, the lookups ``_shade`` makes, footprints included), which the
kernel reads in place of the material's row; a mix's textured second material (``second_per_hit``)
likewise gives each hit its own second ``LOBE`` row (``bsdf_kernel.mix_rows``), read in place of the
tables' one; a mix holding a mix (``tree``) gives each hit its whole BSDF as a ``bsdf_kernel.TREE``
row, its lobes and amounts looked up likewise (``_hit_trees``; RGB rays' hits on a tree nothing in
which is textured take its one row, made with the kernel: ``constant_tree``). Everything else of the bounce stays
in the kernel. An
environment map's sampling tables (its ``Distribution2D``) and texels, and an emitting mesh's world
triangles and their area CDF (``light_sampler.Emitter``'s, which the scene's mesh-space device tables
cannot stand for: they lack the instance's transform and the CDF), share one device buffer; a light
sample's direction toward an emitting sphere meets its mesh on the host (embree).

Spectral rays (a dispersive camera's: one wavelength each, K per camera sample) take the program's
spectral build (``BOUNCE_SPECTRAL``) at the same hits: the kernel turns each material's RGB colours
into their spectral values at the ray's wavelength as ``bsdf_for`` builds its BSDF from
``SurfaceParameters``' spectral colours (each the dot with the ray's ``rgb_basis`` row, as
``light_sampler.colour`` turns RGB: albedos, tints, a conductor's eta and k; a named metal's and a
measured table's RGB through the basis row; a coated base remade from its albedo's spectral value; a
mix's both lobes), the diffuse-like colour's texture likewise (an image texture's bare RGB comes
from ``EwaKernel.at_hits`` with a factor of 1), every light's radiance likewise, and carries beta
and the contributions as one column, as the numpy bounce does; a hit's own row is looked up at its
ray's wavelength on the host (each colour's spectral value repeated, as ``bsdf_kernel.parameters``
says; a textured second material's row likewise), so only a mix's constant second lobe, RGB in the
tables, is turned in the kernel. Glass indices are constants (no
material's index varies with the wavelength in ``bsdf_for``). The host passes each camera ray's basis
row, the very rows ``PathIntegrator.radiance`` colours its emission with (``shade.cl`` interpolates
its basis from a table instead: its rays arrive as wavelengths alone).
The rest (a mix tree of more than ``bsdf_kernel.MAX_LOBES`` lobes) stays with
``PathIntegrator._shade``, the numpy reference
(``tests/test_bounce_kernel.py`` compares the two per hit with the same random numbers, RGB and
spectral). The program is the BSDF kernel's source with this one after it, so both share
``bsdf.cl``'s material functions; the scene's tables are device buffers made once per integrator,
each build is made at its first launch, and each thread has its own queue and kernel objects.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import TypeGuard, TypeVar

import numpy as np

from realistic.device.opencl import LOCAL_SIZE, Device, TypedKernel, cl, kernel_source, whole_groups
from realistic.device.tables import Table, constant_defines
from realistic.renderer import bsdf_kernel
from realistic.renderer.bsdf.base import HitParameters
from realistic.renderer.hit_rows import place_rows, rows_on_material
from realistic.renderer.light_sampler import (
    AREA,
    DISTANT,
    INFINITE,
    INSTANCE,
    POINT,
    SHADOW_DEFINES,
    SHADOW_LENGTH,
    SPOT,
    LightSampler,
)
from realistic.renderer.shade_kernel import GEOM_FLOATS, GEOM_INTS, rounded_up_cdf
from realistic.scene.ewa_kernel import DEVICE_FILTERS, EwaKernel, SurfaceTables, hit_mapping
from realistic.scene.intersect import Hits
from realistic.scene.lights import InfiniteLight, SpotLight
from realistic.scene.materials import CoatedDiffuse, Mix, Plastic, ScaledTexture, Substrate, SurfaceMaterial
from realistic.scene.mipmap import MipMap
from realistic.scene.model import RGB, CheckerTexture, GridTexture, ImageTexture, Material, Texture

KERNEL_FILE = "bounce.cl"
#: Per material, beside its ``BSDF_PARAMS`` row: its diffuse-like colour's texture (``TEXTURES``), a grid's or
#: checker's cells, line bounds (low, high: line_width / 2 and 1 - line_width / 2) and colours (a:
#: line or even, b: base or odd); an image texture's albedo comes per hit (``BounceKernel.__call__``).
#: ``per_hit`` 1: the material's parameters vary otherwise, and each hit's ``BSDF_PARAMS`` row comes from
#: the host (``BounceKernel._hit_rows``; the material's own row and texture are then unused);
#: ``second_per_hit`` 1 (a mix whose second material is textured, ``per_hit`` too): so does each hit's
#: second lobe, a ``bsdf_kernel.LOBE`` row (``BOUNCE_LOBE_WIDTH`` floats) in place of the tables' one.
#: ``tree`` 1 (a mix holding a mix): each hit's BSDF is its own ``bsdf_kernel.TREE`` row from the host
#: (``BounceKernel._hit_trees``); the material's ``BSDF_PARAMS`` row (zero) and texture are unused.
MATERIALS = Table("BOUNCE_MATERIAL", np.float32, (("texture", 1), ("cells", 1), ("low", 1), ("high", 1),
                                                  ("colour_a", 3), ("colour_b", 3), ("per_hit", 1),
                                                  ("second_per_hit", 1), ("tree", 1)))
TEXTURES = ("none", "grid", "checker", "image")
#: The textures the kernel evaluates (``diffuse_texture``).
DeviceTexture = GridTexture | CheckerTexture | ImageTexture
#: Per light (the sampler's order): its kind (``LIGHT_KINDS``); an area light's centre and half-axes
#: a, b (a point is centre + a x + b y), unit emitting normal, area, disk and two-sided (0, 1); a point
#: or spot light's position (``centre``); a distant light's unit direction toward it (``normal``);
#: ``radiance`` (a point or spot light's intensity); the pick probability; a spot light's world-to-light
#: rotation (``frame``, row-major), cos_total_width, cos_falloff_start - cos_total_width (``span``) and
#: whether its falloff is pbrt-v4's smoothstep (else pbrt-v3's quartic); an infinite light's mapping
#: (``MAPPINGS``), light-to-world rotation (``frame``) and, with a map, its width and height and the
#: starts (in ``bsdf_kernel.TABLE_ALIGN`` floats of the kernel's ``environment`` buffer) of its
#: ``Distribution2D``'s row CDF (H + 1), column CDFs (H, W + 1), density (H, W) and its texels (H, W, 3);
#: an emitting instance's radiance, total area, two-sided, its triangles (``triangles``: the starts,
#: in ``TABLE_ALIGN`` floats of ``environment``, of its area CDF (rounded up as ``rounded_up_cdf``
#: rounds) and its ``TRIANGLES`` rows, and their count) and, for an emitting sphere, its ``centre`` and
#: ``radius`` (0: none).
LIGHTS = Table("BOUNCE_LIGHT", np.float32, (("kind", 1), ("centre", 3), ("a", 3), ("b", 3), ("normal", 3),
                                            ("radiance", 3), ("area", 1), ("probability", 1), ("disk", 1),
                                            ("two_sided", 1), ("frame", 9), ("cos_total", 1), ("span", 1),
                                            ("smoothstep", 1), ("mapping", 1), ("map_size", 2),
                                            ("map_tables", 4), ("triangles", 3), ("radius", 1)))
#: An emitting instance's world triangle (``light_sampler.Emitter``'s rows): its first corner, its
#: edges to the other two and its unit normal (the world winding's side).
TRIANGLES = Table("BOUNCE_TRIANGLE", np.float32, (("origin", 3), ("e1", 3), ("e2", 3), ("normal", 3)))
#: The lights the kernel samples (``kind``): every kind ``LightSampler`` has.
LIGHT_KINDS = ("area", "point", "spot", "distant", "infinite", "instance")
#: An infinite light's map: none (constant radiance, sampled uniformly), or ``InfiniteLight.mapping``
#: (its "-" an "_" here).
MAPPINGS = ("none", "latlong", "equal_area")
#: ``LightSampler``'s kind -> ``LIGHT_KINDS``' index.
_KIND = {AREA: 0, POINT: 1, SPOT: 2, DISTANT: 3, INFINITE: 4, INSTANCE: 5}
#: ``mode_flags`` bits: MIS on, pbrt's "direct" mode, and (direct mode) whether non-specular BSDF
#: samples go on to find emission.
MODE_FLAGS = ("mis", "direct", "emission_after_diffuse")
MIS, DIRECT, EMISSION_AFTER_DIFFUSE = (1 << k for k in range(len(MODE_FLAGS)))
_M = TypeVar("_M", bound=SurfaceMaterial)  # a material kind, kept through ``BounceKernel._picks``
#: ``next_flags`` bits.
GOES_ON, SPECULAR, SHADES = 1, 2, 4


def header(dimension: int, roulette_after: int, spectral: bool) -> str:
    """The generated head of the program: ``bsdf.cl``'s defines, every table's here, the texture
    kinds, the mode flags, the integrator's first bounce dimension and roulette depth, and whether
    the rays are spectral (``BOUNCE_SPECTRAL``: the program's two builds)."""
    return (bsdf_kernel.HEADER + "".join(t.defines() for t in (GEOM_INTS, GEOM_FLOATS, MATERIALS, LIGHTS, TRIANGLES))
            + constant_defines("BOUNCE_TEXTURE", TEXTURES) + constant_defines("BOUNCE_KIND", LIGHT_KINDS)
            + constant_defines("BOUNCE_MAPPING", MAPPINGS)
            + "".join(f"#define BOUNCE_{name.upper()} {1 << k}\n" for k, name in enumerate(MODE_FLAGS))
            + f"#define BOUNCE_DIMENSION {dimension}\n#define BOUNCE_ROULETTE_AFTER {roulette_after}\n"
            + f"#define BOUNCE_SPECTRAL {int(spectral)}\n#define BOUNCE_LOBE_WIDTH {bsdf_kernel.LOBE.width}\n"
            + SHADOW_DEFINES)


class _Textured(Exception):
    """A parameter is a texture (``constant_rows``' probe)."""


class _Constants:
    """``HitParameters`` of one hit that refuse textures: what ``constant_rows`` packs with."""

    def colour(self, value: object) -> np.ndarray:
        if isinstance(value, tuple | list | np.ndarray | float | int):
            return np.broadcast_to(np.asarray(value, np.float32), (1, 3))
        raise _Textured

    def scalar(self, value: object) -> np.ndarray:
        if isinstance(value, float | int):
            return np.full(1, value, np.float32)
        raise _Textured


class _AnyTexture(_Constants):
    """``HitParameters`` of one hit that take any texture as 1: ``material_rows``' probe of whether
    ``bsdf_kernel.parameters`` covers a material at every hit (its kind; a mix's second material
    constant, which ``_Constants`` checks)."""

    def colour(self, value: object) -> np.ndarray:
        return np.ones((1, 3), np.float32) if isinstance(value, Texture) else super().colour(value)

    def scalar(self, value: object) -> np.ndarray:
        return np.ones(1, np.float32) if isinstance(value, Texture) else super().scalar(value)


def _device_texture(value: object) -> TypeGuard[DeviceTexture]:
    """Whether the kernel evaluates ``value``: a grid or checker texture, or an image texture filtered
    as ``DEVICE_FILTERS`` says."""
    return isinstance(value, GridTexture | CheckerTexture) or (isinstance(value, ImageTexture)
                                                              and value.filter in DEVICE_FILTERS)


def diffuse_texture(material: SurfaceMaterial) -> tuple[SurfaceMaterial, DeviceTexture, RGB] | None:
    """``material``'s diffuse-like colour split into a constant factor and a texture the kernel
    evaluates: a ``Material``'s diffuse and texture, or a plastic's or substrate's Kd or a coated
    diffuse's reflectance that is such a texture (factor 1) or a ``ScaledTexture`` of one (its scale).
    The material with that colour the factor alone, the texture and the factor; None where there is
    no such texture."""
    if isinstance(material, Material):
        texture = material.texture
        return (replace(material, texture=None), texture, material.diffuse) if _device_texture(texture) else None
    if not isinstance(material, Plastic | Substrate | CoatedDiffuse):
        return None
    value = material.reflectance if isinstance(material, CoatedDiffuse) else material.diffuse
    inner, factor = (value.texture, value.scale) if isinstance(value, ScaledTexture) else (value, (1.0, 1.0, 1.0))
    if not _device_texture(inner):
        return None
    plain = replace(material, reflectance=factor) if isinstance(material, CoatedDiffuse) \
        else replace(material, diffuse=factor)
    return plain, inner, factor


def material_rows(material: SurfaceMaterial, tables: bsdf_kernel.TableStore) -> tuple[np.ndarray, np.ndarray] | None:
    """``material``'s ``BSDF_PARAMS`` row and ``MATERIALS`` row, or None where the kernel does not cover
    it (a kind ``bsdf.cl`` lacks, or a mix tree of more than ``bsdf_kernel.MAX_LOBES`` lobes); measured
    tables, named metals' tables and mixes' constant second lobes go to ``tables``. Where the only
    texture is the diffuse-like colour's grid, checker or image texture (``diffuse_texture``), the row
    holds that colour's constant factor, which the kernel multiplies by the texture's colour per hit;
    where another parameter is textured, the ``MATERIALS`` row says ``per_hit`` and the ``BSDF_PARAMS``
    row is zero (each hit's comes from ``BounceKernel._hit_rows``), and where a mix's second material is
    textured it says ``second_per_hit`` too (each hit's second lobe comes from there as well). A mix
    holding a mix (of at most ``bsdf_kernel.MAX_LOBES`` covered lobes) says ``tree``, its row zero: each
    hit's ``TREE`` row comes from ``BounceKernel._hit_trees``, textured or not."""
    if bsdf_kernel.holds_mix(material):
        if bsdf_kernel.tree_rows(material, _AnyTexture(), 1, tables) is None:
            return None
        return np.zeros(bsdf_kernel.BSDF_PARAMS.width, np.float32), MATERIALS.pack(1, tree=1)[0]
    split = diffuse_texture(material)
    plain, texture = (material, None) if split is None else split[:2]
    try:
        row = bsdf_kernel.parameters(plain, _Constants(), 1, tables)
    except _Textured:
        try:
            covered, second = bsdf_kernel.parameters(material, _AnyTexture(), 1, tables, _Constants()) is not None, 0
        except _Textured:  # a mix's second material is textured: its lobe comes per hit too
            covered = isinstance(material, Mix) and bsdf_kernel.mix_rows(material, _AnyTexture(), 1, tables) is not None
            second = 1
        if not covered:
            return None
        return (np.zeros(bsdf_kernel.BSDF_PARAMS.width, np.float32),
                MATERIALS.pack(1, per_hit=1, second_per_hit=second)[0])
    if row is None:
        return None
    if isinstance(texture, GridTexture):
        half = texture.line_width / 2
        extra = MATERIALS.pack(1, texture=TEXTURES.index("grid"), cells=texture.cells, low=half, high=1 - half,
                               colour_a=texture.line, colour_b=texture.base)
    elif isinstance(texture, CheckerTexture):
        extra = MATERIALS.pack(1, texture=TEXTURES.index("checker"), cells=texture.cells, colour_a=texture.even,
                               colour_b=texture.odd)
    elif isinstance(texture, ImageTexture):
        extra = MATERIALS.pack(1, texture=TEXTURES.index("image"))
    else:
        extra = MATERIALS.pack(1)
    return row[0], extra[0]


def constant_tree(material: Mix, tables: bsdf_kernel.TableStore) -> np.ndarray | None:
    """The one ``TREE`` row (1, width) of a mix holding a mix (covered) where none of its lobes and
    amounts is textured: ``bsdf_kernel.tree_rows`` at any hit of RGB rays, made once per material
    rather than per hit; None where something in it is textured (its rows are made per hit)."""
    try:
        return bsdf_kernel.tree_rows(material, _Constants(), 1, tables)
    except _Textured:
        return None


def light_rows(lights: LightSampler) -> tuple[np.ndarray, np.ndarray]:
    """``LIGHTS`` rows of a sampler's lights, in its order, and the float32 ``environment`` buffer
    they point into: each map's sampling tables (its CDFs rounded up as ``rounded_up_cdf`` rounds, so
    the kernel's float32 searches pick numpy's cells) and texels, and each emitting instance's area
    CDF (rounded up likewise) and ``TRIANGLES`` rows, each at a multiple of ``bsdf_kernel.TABLE_ALIGN``
    floats."""
    n = len(lights.lights)
    spot = [(light.cos_total_width, light.cos_falloff_start - light.cos_total_width, light.falloff_kind != "quartic")
            if isinstance(light, SpotLight) else (0.0, 0.0, False) for light in lights.lights]
    radiance = np.array([light.radiance if isinstance(light, InfiniteLight) else lights.intensity[i]
                         for i, light in enumerate(lights.lights)], np.float64).reshape(n, 3)
    frame = lights.to_light_frame.reshape(n, 9).copy()
    mapping, map_size, map_tables = np.zeros(n), np.zeros((n, 2)), np.zeros((n, 4))
    triangles, emitter_area, two_sided, radius = np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros(n)
    centre = lights.position.copy()
    environment: list[np.ndarray] = []

    def append(part: np.ndarray) -> int:
        """Put ``part`` in ``environment`` at the next multiple of ``TABLE_ALIGN`` floats: its start in those."""
        start = sum(len(p) for p in environment) // bsdf_kernel.TABLE_ALIGN
        flat = np.asarray(part, np.float32).ravel()
        environment.extend((flat, np.zeros(-len(flat) % bsdf_kernel.TABLE_ALIGN, np.float32)))
        return start

    for i, env in lights.environments.items():
        frame[i] = np.asarray(env.light.light_to_world, np.float64)[:3, :3].ravel()
        if env.distribution is not None:  # a map
            row_cdf, col_cdf = env.distribution.cdfs
            mapping[i] = MAPPINGS.index(env.light.mapping.replace("-", "_"))
            map_size[i] = env.distribution.width, env.distribution.height
            map_tables[i] = [append(part) for part in (rounded_up_cdf(row_cdf), rounded_up_cdf(col_cdf),
                                                       env.distribution.density, np.asarray(env.light.image))]
    for i, emitter in lights.emitters.items():
        radiance[i], emitter_area[i], two_sided[i] = emitter.light.radiance, emitter.area, emitter.light.two_sided
        rows = TRIANGLES.pack(len(emitter.cdf), origin=emitter.origin, e1=emitter.e1, e2=emitter.e2,
                              normal=emitter.normal)
        triangles[i] = append(rounded_up_cdf(emitter.cdf)), append(rows), len(emitter.cdf)
        if emitter.light.sphere is not None:
            centre[i], radius[i] = emitter.light.sphere
    table = LIGHTS.pack(n, kind=[_KIND[int(k)] for k in lights.kind], centre=centre, normal=lights.position,
                        radiance=radiance, probability=lights.probability, frame=frame,
                        cos_total=[c for c, _, _ in spot], span=[s for _, s, _ in spot],
                        smoothstep=[k for _, _, k in spot], mapping=mapping, map_size=map_size,
                        map_tables=map_tables, area=emitter_area, two_sided=two_sided, triangles=triangles,
                        radius=radius)
    area = np.flatnonzero(lights.kind == AREA)
    if len(area):
        areas, slot = lights.area_lights, lights.area_slot[area]
        table[area] = LIGHTS.pack(len(area), kind=_KIND[AREA], centre=areas.centre[slot], a=areas.a[slot],
                                  b=areas.b[slot], normal=areas.normal[slot], radiance=areas.radiance[slot],
                                  area=areas.area[slot], probability=lights.probability[area],
                                  disk=areas.disk[slot], two_sided=areas.two_sided[slot])
    return table, np.concatenate(environment) if environment else np.zeros(1, np.float32)


@dataclass
class Bounce:
    """One launch's outputs for m surface hits and L light samples each: shadow rays at rows
    k * m + i (``length`` -1 and ``contribution`` 0 where dead), and each hit's next ray."""

    shadow_origin: np.ndarray  # (L m, 3) float32
    shadow_vector: np.ndarray  # (L m, 3) float32: to the light point, or its direction (distant, infinite)
    shadow_length: np.ndarray  # (L m,) float32: 1 - 1e-4 in units of the vector, FAR (a direction), or -1
    contribution: np.ndarray  # (L m, 3) float32
    origin: np.ndarray  # (m, 3) float32: the next ray's offset origin
    direction: np.ndarray  # (m, 3) float32
    beta: np.ndarray  # (m, 3) float32: after this bounce (and roulette)
    point: np.ndarray  # (m, 3) float32: the hit point
    pdf: np.ndarray  # (m,) float32: the BSDF sample's density
    flags: np.ndarray  # (m,) int32: GOES_ON, SPECULAR, SHADES

    def going_on(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The hits whose paths go on (their indices), and of those whether the BSDF sample was
        specular and whether their next hit is shaded."""
        keep = np.flatnonzero(self.flags & GOES_ON)
        flags = self.flags[keep]
        return keep, (flags & SPECULAR) != 0, (flags & SHADES) != 0


class BounceKernel:
    """``bounce.cl`` with one scene's tables on ``device``."""

    def __init__(self, device: Device, *, faces: np.ndarray, normals: np.ndarray, uv: np.ndarray,
                 geom_face_offset: np.ndarray, geom_material: np.ndarray, geom_smooth: np.ndarray,
                 geom_swaps: np.ndarray, geom_normal_matrix: np.ndarray, materials: list[SurfaceMaterial],
                 lights: LightSampler, extent: float, dimension: int, roulette_after: int,
                 tables: bsdf_kernel.TableStore, vertices: np.ndarray, geom_linear: np.ndarray,
                 pixel_spread_radians: float, ewa_kernel: Callable[[MipMap], EwaKernel]):
        """``dimension``: the random-number dimension of bounce 0's BSDF sample (bounce b's are 8 b
        on); ``roulette_after``: the bounces after which roulette may end a path. ``lights``: the scene's
        (its emitting spheres' meshes meet the kernel's cone samples here). ``tables``: the BSDF
        kernel's ``TableStore`` (shared, so a measured table is on the device once). ``vertices``
        (float64, mesh space), ``geom_linear`` (per instance, 3 x 3), ``pixel_spread_radians`` (the
        camera's) and ``ewa_kernel`` (a MIP map's ``EwaKernel``, the backend's) serve image textures."""
        self.device = device
        self.bsdf_tables = tables
        self._lights = lights
        rows = [material_rows(m, tables) for m in materials]
        #: per material: whether the kernel shades it (RGB and spectral rays alike)
        self.covered = np.array([r is not None for r in rows] or [False], bool)
        self._geom_material = np.asarray(geom_material)
        #: the materials whose hits take their own rows (``_hit_rows``): their indices and materials
        self._per_hit = [(k, m) for k, (m, r) in enumerate(zip(materials, rows))
                         if r is not None and r[1][MATERIALS.offset("per_hit")]]
        #: of those, the mixes whose second lobe comes per hit too (``second_per_hit``)
        self._second_per_hit = {k for k, r in enumerate(rows)
                                if r is not None and r[1][MATERIALS.offset("second_per_hit")]}
        #: the mixes holding a mix, whose hits take their own ``TREE`` rows (``_hit_trees``)
        self._trees = [(k, m) for k, (m, r) in enumerate(zip(materials, rows))
                       if r is not None and bsdf_kernel.holds_mix(m)]
        #: of those, the trees nothing in which is textured: their one ``TREE`` row (1, width), the
        #: row of every hit of RGB rays (spectral rays' colours vary with each hit's wavelength)
        self._constant_trees = {k: row for k, m in self._trees if (row := constant_tree(m, tables)) is not None}
        #: the floats of each hit's ``TREE`` row: as many lobes as the largest tree's
        self._tree_width = bsdf_kernel.tree_width(max((bsdf_kernel.leaf_count(m) for _, m in self._trees), default=0))
        #: per image-textured material covered: its index, EWA kernel, filter and ``hit_mapping`` rows
        #: at depth 0 (the pixel's footprint) and deeper (none: level 0 bilinear, as ``_shade``), each
        #: with the colour's constant factor (RGB rays: the albedo) and with 1 (spectral rays: the bare
        #: texture, whose spectral value the kernel multiplies by the factor's)
        self._images: list[tuple[int, EwaKernel, str, dict[tuple[bool, bool], np.ndarray]]] = []
        for k, (m, r) in enumerate(zip(materials, rows)):
            split = None if r is None or r[1][MATERIALS.offset("per_hit")] else diffuse_texture(m)
            if split is not None and isinstance(texture := split[1], ImageTexture):
                factor = split[2]
                self._images.append((k, ewa_kernel(texture.mipmap), texture.filter, {
                    (spectral, deeper): hit_mapping(texture, (1.0, 1.0, 1.0) if spectral else factor,
                                                    0.0 if deeper else pixel_spread_radians)
                    for spectral in (False, True) for deeper in (False, True)}))
        self._surfaces = SurfaceTables(device, faces, vertices, uv, geom_face_offset,
                                       np.asarray(geom_linear).reshape(-1, 9)) if self._images else None
        params = np.array([r[0] if r else np.zeros(bsdf_kernel.BSDF_PARAMS.width, np.float32) for r in rows]
                          or [np.zeros(bsdf_kernel.BSDF_PARAMS.width, np.float32)], np.float32)
        textures = np.array([r[1] if r else np.zeros(MATERIALS.width, np.float32) for r in rows]
                            or [np.zeros(MATERIALS.width, np.float32)], np.float32)
        count = len(geom_face_offset)
        geom = GEOM_INTS.pack(max(count, 1))
        geom[:count] = GEOM_INTS.pack(count, face_offset=geom_face_offset, material=geom_material,
                                      smooth=geom_smooth, swaps=geom_swaps)
        matrices = GEOM_FLOATS.pack(max(count, 1))
        matrices[:count] = GEOM_FLOATS.pack(
            count, normal_matrix=np.asarray(geom_normal_matrix, np.float32).reshape(-1, 9))
        self.light_count = len(lights.lights) if lights.has_lights else 0
        table, environment = light_rows(lights) if self.light_count else (LIGHTS.pack(1), np.zeros(1, np.float32))
        cdf = rounded_up_cdf(lights.cdf) if self.light_count else np.ones(1, np.float32)
        self.offset_base = np.float32(1e-2 * extent)
        self._dimension, self._roulette_after = dimension, roulette_after
        self._tables = [device.wrapped_buffer(array, dtype) for array, dtype in (
            (faces, np.int32), (normals, np.float32), (uv, np.float32), (geom, np.int32), (matrices, np.float32),
            (params, np.float32), (textures, np.float32), (table, np.float32), (cdf, np.float32),
            (environment, np.float32))]
        self._local = threading.local()

    def program(self, spectral: bool) -> cl.Program:
        """The RGB or the spectral build, built on its first launch (a render uses one of them;
        ``Device.build_program`` builds each once per process)."""
        return self.device.build_program(header(self._dimension, self._roulette_after, spectral)
                                         + kernel_source(bsdf_kernel.KERNEL_FILE) + kernel_source(KERNEL_FILE),
                                         KERNEL_FILE)

    def _queue_and_kernel(self, spectral: bool) -> tuple[cl.CommandQueue, TypedKernel]:
        """This thread's queue and its kernel object of the RGB or the spectral build."""
        state: tuple[cl.CommandQueue, dict[bool, TypedKernel]] | None = getattr(self._local, "state", None)
        if state is None:
            state = self._local.state = (self.device.queue(), {})
        queue, kernels = state
        if spectral not in kernels:
            kernels[spectral] = TypedKernel(self.program(spectral), "bounce")
        return queue, kernels[spectral]

    def __call__(self, rows: np.ndarray, path: np.ndarray, pixel: np.ndarray, sample: np.ndarray,
                 origin: np.ndarray, direction: np.ndarray, hits: Hits, beta: np.ndarray, *, depth: int,
                 light_samples: int, seed: int, mode_flags: int, max_depth: int, basis: np.ndarray | None = None,
                 hit_parameters: Callable[[np.ndarray], HitParameters] | None = None) -> Bounce:
        """The bounce at the hits ``rows`` (m,) of a batch of rays (``origin``, ``direction``,
        ``hits``, ``beta`` (B, C), ``path`` (B,): each ray's camera ray, whose ``pixel`` and
        ``sample`` key the random numbers) at ``depth``, with ``light_samples`` light samples per
        hit (0 without lights). ``basis``: for spectral rays (C = 1, the spectral build), each camera
        ray's ``rgb_basis`` row (float32, indexed by ``path``), and beta and the contributions come
        out one column wide; None for RGB rays (C = 3). ``hit_parameters``: the ``HitParameters`` at
        the hits rows[picked] (``PathIntegrator._hit_parameters``, spectral rays' with their basis
        rows), which the hits on ``per_hit`` materials need (``_hit_rows``)."""
        m = len(rows)
        lights = light_samples if self.light_count else 0
        shadows = lights * m
        spectral = basis is not None
        channels = 1 if spectral else 3
        out = Bounce(shadow_origin=np.empty((shadows, 3), np.float32), shadow_vector=np.empty((shadows, 3), np.float32),
                     shadow_length=np.empty(shadows, np.float32),
                     contribution=np.empty((shadows, channels), np.float32),
                     origin=np.empty((m, 3), np.float32), direction=np.empty((m, 3), np.float32),
                     beta=np.empty((m, channels), np.float32), point=np.empty((m, 3), np.float32),
                     pdf=np.empty(m, np.float32), flags=np.empty(m, np.int32))
        if m:
            cone_light = np.empty(shadows, np.int32)
            queue, kernel = self._queue_and_kernel(spectral)
            albedo = self._albedo(rows, direction, hits, depth, spectral)
            hit_rows, hit_seconds = self._hit_rows(rows, hits, hit_parameters)
            hit_trees = self._hit_trees(rows, hits, hit_parameters, spectral)
            inputs = [self.device.wrapped_buffer(a, dtype) for a, dtype in (
                (rows, np.int32), (path, np.int32), (pixel, np.uint32), (sample, np.uint32), (origin, np.float32),
                (direction, np.float32), (hits.t, np.float32), (hits.u, np.float32), (hits.v, np.float32),
                (hits.prim, np.int32), (hits.geom, np.int32), (hits.normal, np.float32), (beta, np.float32),
                (albedo, np.float32), (np.zeros(0) if basis is None else basis, np.float32),
                (hit_rows, np.float32), (hit_seconds, np.float32), (hit_trees, np.float32))]
            self.device.run_into(queue, kernel, (whole_groups(m),), (LOCAL_SIZE,),
                                 (np.uint32(m), np.uint32(lights), np.uint32(depth), np.uint32(seed & 0xFFFFFFFF),
                                  np.uint32(mode_flags), np.uint32(max_depth), self.offset_base,
                                  np.int32(max(self.light_count, 1)), *inputs, np.uint32(self._tree_width),
                                  *self._tables, self.bsdf_tables.buffer),
                                 (out.shadow_origin, out.shadow_vector, out.shadow_length, out.contribution,
                                  cone_light, out.origin, out.direction, out.beta, out.point, out.pdf, out.flags))
            self._meet_spheres(cone_light, out, m)
        return out

    def _meet_spheres(self, cone_light: np.ndarray, out: Bounce, m: int) -> None:
        """Finish the kernel's cone samples toward emitting spheres (``cone_light``: each shadow row's
        sphere light, or -1) as ``LightSampler._towards_sphere`` does: the direction from the hit point
        meets the sphere's mesh (``LightSampler.meets_sphere_mesh``), and the shadow ray goes to that
        point; where it misses the mesh or meets its back the sample is dead."""
        for light in np.unique(cone_light[cone_light >= 0]):
            rows = np.flatnonzero(cone_light == light)
            point, w = out.point[rows % m], out.shadow_vector[rows]
            ok, t = self._lights.meets_sphere_mesh(self._lights.emitters[int(light)], point, w)
            target = point + t[:, None] * w
            out.shadow_vector[rows] = np.where(ok[:, None], target - out.shadow_origin[rows], np.float32(0))
            out.shadow_origin[rows] = np.where(ok[:, None], out.shadow_origin[rows], np.float32(0))
            out.shadow_length[rows] = np.where(ok, SHADOW_LENGTH, np.float32(-1))
            out.contribution[rows] = np.where(ok[:, None], out.contribution[rows], np.float32(0))

    def _hit_rows(self, rows: np.ndarray, hits: Hits, hit_parameters: Callable[[np.ndarray], HitParameters] | None
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The ``BSDF_PARAMS`` rows (m, width) float32 of the hits ``rows`` on ``per_hit`` materials
        and the ``LOBE`` rows (m, ``LOBE.width``) of the second lobes of those on ``second_per_hit``
        mixes (zero elsewhere, unread; none without such hits): ``bsdf_kernel.parameters``, or
        ``bsdf_kernel.mix_rows`` for the latter, at ``hit_parameters(picked)``, which looks every
        texture up as ``PathIntegrator._shade`` does (spectral rays' at their wavelength, each
        colour's value repeated); a constant second lobe stays in the tables, RGB (the kernel turns it
        into spectral rays' channel)."""
        out = np.zeros((0, bsdf_kernel.BSDF_PARAMS.width), np.float32)
        seconds = np.zeros((0, bsdf_kernel.LOBE.width), np.float32)
        for index, material, picked in self._picks(self._per_hit, rows, hits):
            at = self._parameters(hit_parameters, index, picked)
            if not len(out):
                out = np.zeros((len(rows), bsdf_kernel.BSDF_PARAMS.width), np.float32)
            table: np.ndarray | None
            if isinstance(material, Mix) and index in self._second_per_hit:
                mixed = bsdf_kernel.mix_rows(material, at, len(picked), self.bsdf_tables)
                assert mixed is not None  # material_rows' probe: covered at every hit
                if not len(seconds):
                    seconds = np.zeros((len(rows), bsdf_kernel.LOBE.width), np.float32)
                table, seconds[picked] = mixed
            else:
                table = bsdf_kernel.parameters(material, at, len(picked), self.bsdf_tables, _Constants())
                assert table is not None  # material_rows' probe: covered at every hit
            out[picked] = table
        return out, seconds

    def _picks(self, materials: list[tuple[int, _M]], rows: np.ndarray, hits: Hits
                ) -> Iterator[tuple[int, _M, np.ndarray]]:
        """Each of ``materials`` (material index, material) that some of the hits ``rows`` are on,
        with the positions in ``rows`` of those hits."""
        geom, picks = hits.geom[rows], np.empty(len(rows), np.int32)
        for index, material in materials:
            picked = picks[:rows_on_material(geom, self._geom_material, index, picks)].copy()
            if len(picked):
                yield index, material, picked

    @staticmethod
    def _parameters(hit_parameters: Callable[[np.ndarray], HitParameters] | None, index: int, picked: np.ndarray
                    ) -> HitParameters:
        """``hit_parameters(picked)``, which hits on material ``index``, whose rows are made per hit, need."""
        if hit_parameters is None:
            raise ValueError(f"hits on material {index}, whose rows are made per hit, need hit_parameters")
        return hit_parameters(picked)

    def _hit_trees(self, rows: np.ndarray, hits: Hits, hit_parameters: Callable[[np.ndarray], HitParameters] | None,
                   spectral: bool = False) -> np.ndarray:
        """The ``TREE`` rows (m, ``_tree_width``) float32 of the hits ``rows`` on mixes holding a mix
        (zero elsewhere, unread; none without such hits): a constant tree's one row
        (``constant_tree``) for RGB rays, else ``bsdf_kernel.tree_rows`` at ``hit_parameters(picked)``,
        the lookups ``_shade`` makes (spectral rays' at their wavelength)."""
        out = np.zeros((0, self._tree_width), np.float32)
        for index, material, picked in self._picks(self._trees, rows, hits):
            constant = None if spectral else self._constant_trees.get(index)
            if constant is None:
                table = bsdf_kernel.tree_rows(material, self._parameters(hit_parameters, index, picked), len(picked),
                                              self.bsdf_tables)
                assert table is not None  # material_rows' probe: covered at every hit
                if len(picked) == len(rows) and table.shape[1] == self._tree_width:  # every hit, in order
                    return table
            else:
                table = constant
            if not len(out):
                out = np.zeros((len(rows), self._tree_width), np.float32)
            out[picked, :table.shape[1]] = table
        return out

    def _albedo(self, rows: np.ndarray, direction: np.ndarray, hits: Hits, depth: int, spectral: bool) -> np.ndarray:
        """The albedo (m, 3) float32 of the hits ``rows`` on image-textured materials (zero elsewhere,
        unread), or for ``spectral`` rays their texture's bare RGB: ``EwaKernel.at_hits`` with the
        pixel's footprint at depth 0 and none deeper, which is what ``PathIntegrator._shade`` filters
        with."""
        albedo = np.zeros((len(rows), 3), np.float32)
        if self._surfaces is None:  # no image-textured material
            return albedo
        geom, picks = hits.geom[rows], np.empty(len(rows), np.int32)
        for index, ewa, texture_filter, mappings in self._images:
            picked = picks[:rows_on_material(geom, self._geom_material, index, picks)]
            if len(picked):
                place_rows(ewa.at_hits(self._surfaces, rows[picked].astype(np.int32, copy=False),
                                       mappings[spectral, depth > 0], direction, hits, texture_filter),
                           picked, albedo)
        return albedo
