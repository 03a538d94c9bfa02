"""OpenCL host of the path integrator's BSDFs: ``kernels/bsdf.cl`` on a ``Device``.

``PathIntegrator`` (``renderer/path.py``) uses it on the "opencl" backend for RGB and spectral rays
at hits whose material the kernel covers (``parameters`` returns their rows) where the fused bounce
(``renderer/bounce_kernel``, whose program holds ``bsdf.cl``'s functions too) does not take the
whole bounce: Lambertian and
Oren-Nayar (``Material``), conductors (eta and k, or a named metal's tabulated Fresnel), mirrors,
smooth, thin and rough dielectrics, plastic, coated diffuse, substrate, measured ``.brdf`` files
(their 128^3 table), MERL half-angle tables (their 90 x 90 x 180 RGB bins as read), diffuse
transmission, a mix of two of those whose second is the same at every hit, and a mix holding a mix
of up to ``MAX_LOBES`` of those lobes (a ``TREE`` row per hit, ``tree_rows``, which ``bsdf.cl``'s
``tree_eval`` and ``tree_sample`` read as ``bsdf_for``'s nested ``WeightedSum``s are evaluated and
sampled; here each hit's row is a ``BSDF_PARAMS`` row of kind "tree" followed by its ``TREE`` row:
``BsdfKernel.rows``); the tables and the mixes' second lobes live in the kernel's ``TableStore``.
Here, mixes of a textured second material (or seen by spectral rays, whose second lobe varies with
the wavelength) stay with the numpy BSDFs of ``renderer.bsdf``, which are the reference; the fused
bounce takes them (a textured second material's lobe from per-hit rows, ``mix_rows``) and trees as
this kernel does. Only a larger tree stays numpy (``tests/test_bsdf_kernel.py``,
``tests/test_mix_trees.py`` and, for MERL tables, ``tests/test_merl_kernel.py`` compare the two).
The host looks each parameter up at the hits as ``bsdf.factory.bsdf_for`` does (textures included)
and packs one row per hit; the kernel takes the integrator's own uniform numbers, so both draw the same directions.
One launch per bounce evaluates every light sample's direction and draws the BSDF sample; each
thread has its own queue, so the renderer's worker threads launch independently.
"""

from __future__ import annotations

import threading
from functools import cached_property
from typing import TypeGuard

import numpy as np
from numpy.typing import ArrayLike

from realistic.device.opencl import LOCAL_SIZE, Device, TypedKernel, cl, kernel_source, whole_groups
from realistic.device.tables import Table, constant_defines
from realistic.renderer.bsdf.base import BSDFSample, HitParameters
from realistic.renderer.bsdf.coated_diffuse import CoatedLambertian
from realistic.renderer.bsdf.factory import colour, scalar
from realistic.renderer.bsdf.measured import irregular_table
from realistic.renderer.bsdf.microfacet import SMOOTH_ALPHA, alpha
from realistic.renderer.bsdf.oren_nayar import OrenNayar
from realistic.scene.materials import (
    CoatedDiffuse,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Measured,
    Mirror,
    Mix,
    Plastic,
    Substrate,
    SurfaceMaterial,
)
from realistic.scene.measured import MERL_SHAPE, IrregularSamples, load_measured
from realistic.scene.metals import reflectance_table
from realistic.scene.model import Material

KERNEL_FILE = "bsdf.cl"
#: One lobe (a material that is not a mix): its kind (``KINDS``); ``scale`` the Lambertian,
#: Oren-Nayar, plastic or coated base's albedo, the conductor's or mirror's scale, the glass's
#: reflection tint, the substrate's diffuse colour or diffuse transmission's reflectance; ``tint`` the
#: diffuse transmission's transmittance, the glass's transmission tint, the plastic's coat colour
#: (1 for coated diffuse) or the substrate's specular reflectance; ``eta`` the
#: conductor's index per channel (a dielectric's or coat's index in its first column; a coat's then
#: ``CoatedLambertian.internal`` and pi eta^2, from which spectral rays' base is made, as ``k`` and the
#: estimate are from the albedo); ``k`` the conductor's absorption or the coated base's scale
#: (``CoatedLambertian.scale``); ``alpha`` the GGX widths along x and y; ``extra`` Oren-Nayar's A and
#: B, the coated base's albedo estimate and 1 - ``internal``, or a
#: table's start (in ``TABLE_ALIGN`` floats) and size (a measured table's nodes per axis, a named
#: metal's reflectance rows; a MERL table's shape is ``MERL_SHAPE``, in the header). A measured or
#: MERL lobe's ``scale``, ``tint`` and ``eta``, and a tabulated
#: conductor's ``tint``, ``eta`` and ``k``, are the rows of the matrix turning RGB into the rays'
#: channels (``rgb_channels``).
LOBE = Table("BSDF_PARAM", np.float32, (("kind", 1), ("scale", 3), ("tint", 3), ("eta", 3), ("k", 3), ("alpha", 2),
                                        ("extra", 2)))
#: One hit's BSDF: its first lobe, then ``amount`` (0: that lobe alone; else a mix of it, weighted
#: 1 - amount, and a second lobe, weighted amount, the same at every hit: a ``LOBE`` row in the
#: kernel's tables at ``second``, in ``TABLE_ALIGN`` floats; the fused bounce reads a textured second
#: material's ``LOBE`` row per hit from its own buffer instead). Mixes put their second lobe there so
#: that every other row stays one lobe wide.
BSDF_PARAMS = Table("BSDF_PARAM", np.float32, (*LOBE.fields, ("amount", 1), ("second", 1)))
#: The most lobes (leaves) of a mix holding a mix that the fused bounce takes (``TREE``); a larger one
#: stays with the numpy BSDFs.
MAX_LOBES = 8
#: One hit's mix holding a mix (the fused bounce's, ``tree_rows``): ``nodes`` mixes, root first and
#: each mix before the mixes it holds (pre-order), each with its ``amount`` (clipped to [0, 1] as
#: ``bsdf_for`` clips it) and its ``first`` and ``second`` material: a mix's index, or -1 - k for
#: leaf k, whose ``LOBE`` row is the k-th of the tail's ``lobes`` (one per leaf, at most
#: ``MAX_LOBES``; a row is ``TREE.width`` + leaves x ``LOBE.width`` floats, ``tree_width``).
TREE = Table("BSDF_TREE", np.float32, (("nodes", 1), ("amount", MAX_LOBES - 1), ("first", MAX_LOBES - 1),
                                       ("second", MAX_LOBES - 1)), tail="lobes")
#: Lobe kinds; "tree" is no lobe: the ``BsdfKernel`` row of a mix holding a mix (``BsdfKernel.rows``).
KINDS = ("lambertian", "conductor", "mirror", "dielectric", "thin_dielectric", "plastic", "oren_nayar",
         "rough_dielectric", "substrate", "coated_diffuse", "measured", "tabulated_conductor", "diffuse_transmission",
         "merl", "tree")
KIND = {name: index for index, name in enumerate(KINDS)}
#: Measured tables start at multiples of this many floats in ``TableStore``'s buffer, so a row holds a
#: start divided by it, a whole number float32 keeps exactly.
TABLE_ALIGN = 1024
HEADER = (BSDF_PARAMS.defines() + TREE.defines() + f"#define BSDF_LOBE_WIDTH {LOBE.width}\n"
          + f"#define BSDF_MAX_LOBES {MAX_LOBES}\n" + constant_defines("KIND", KINDS)
          + f"#define SMOOTH_ALPHA {SMOOTH_ALPHA!r}f\n"
          + f"#define BSDF_TABLE_ALIGN {TABLE_ALIGN}\n"
          + "".join(f"#define MERL_{axis} {count}\n"
                    for axis, count in zip(("THETA_H", "THETA_D", "PHI_D"), MERL_SHAPE)))
#: One lobe's ``LOBE`` fields by name: constants or per-hit (count,) or (count, width) arrays.
Columns = dict[str, ArrayLike]


def rgb_channels(hits: HitParameters) -> np.ndarray:
    """(N, 3, 3): how an RGB value becomes the rays' channels at ``hits``, as ``bsdf_for`` turns a
    measured or tabulated RGB into them; a spectral ray's one channel is repeated (``parameters``)."""
    channels = np.stack([hits.colour(c) for c in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))], axis=-1)
    return np.broadcast_to(channels, (len(channels), 3, 3))


def _lobe(material: SurfaceMaterial, hits: HitParameters, count: int, tables: TableStore | None
          ) -> Columns | None:
    """``LOBE`` columns of ``material`` (not a mix) at ``count`` ``hits``, or None where the kernel does
    not cover it (a measured BRDF or named metal without ``tables``). The same look-ups as ``bsdf_for``; the
    Oren-Nayar and coated-diffuse constants come from their numpy BSDFs' own constructors."""
    if isinstance(material, Material):
        albedo = hits.colour(material.diffuse)
        if material.texture is not None:
            albedo = albedo * hits.colour(material.texture)
        if material.sigma == 0:
            return dict(kind=KIND["lambertian"], scale=albedo)
        rough = OrenNayar(albedo, material.sigma)
        return dict(kind=KIND["oren_nayar"], scale=albedo, extra=np.column_stack([rough.a, rough.b]))
    if isinstance(material, Plastic):
        kd, ks = colour(hits, material.diffuse), colour(hits, material.specular)
        a = alpha(scalar(hits, material.roughness), material.rule)
        return dict(kind=KIND["plastic"], scale=kd, tint=ks, eta=np.float32(material.eta),
                    alpha=np.column_stack([a, a]))
    if isinstance(material, CoatedDiffuse):
        base = CoatedLambertian(colour(hits, material.reflectance), material.eta)
        a = alpha(scalar(hits, material.roughness), material.rule)
        return dict(kind=KIND["coated_diffuse"], scale=base.albedo, tint=np.float32(1.0),
                    eta=np.array([material.eta, base.internal, np.pi * base.eta ** 2], np.float32), k=base.scale,
                    alpha=np.column_stack([a, a]),
                    extra=np.column_stack([base.albedo_estimate, np.full(count, 1.0 - base.internal)]))
    if isinstance(material, Conductor):
        ax = alpha(scalar(hits, material.roughness_u), material.rule)
        ay = alpha(scalar(hits, material.roughness_v), material.rule)
        if material.spectra is not None:
            if tables is None:
                return None
            table, channels = reflectance_table(*material.spectra), rgb_channels(hits)
            return dict(kind=KIND["tabulated_conductor"], scale=colour(hits, material.scale),
                        tint=channels[:, 0], eta=channels[:, 1], k=channels[:, 2],
                        alpha=np.column_stack([ax, ay]), extra=np.array([tables.place(table), len(table)], np.float32))
        return dict(kind=KIND["conductor"], scale=colour(hits, material.scale),
                    eta=colour(hits, material.eta), k=colour(hits, material.k), alpha=np.column_stack([ax, ay]))
    if isinstance(material, Mirror):
        return dict(kind=KIND["mirror"], scale=colour(hits, material.reflectance))
    if isinstance(material, Dielectric):
        kr, kt = colour(hits, material.reflectance), colour(hits, material.transmittance)
        if material.thin or material.roughness_u == material.roughness_v == 0.0:
            return dict(kind=KIND["thin_dielectric" if material.thin else "dielectric"], scale=kr,
                        tint=kt, eta=np.float32(material.eta))
        ru, rv = scalar(hits, material.roughness_u), scalar(hits, material.roughness_v)
        smooth = (ru == 0) & (rv == 0)  # as bsdf_for: smooth where both are 0 before the remapping
        ax, ay = (np.where(smooth, 0.0, alpha(r, material.rule)) for r in (ru, rv))
        return dict(kind=KIND["rough_dielectric"], scale=kr, tint=kt, eta=np.float32(material.eta),
                    alpha=np.column_stack([ax, ay]))
    if isinstance(material, Substrate):
        ax = alpha(scalar(hits, material.roughness_u), material.rule)
        ay = alpha(scalar(hits, material.roughness_v), material.rule)
        return dict(kind=KIND["substrate"], scale=colour(hits, material.diffuse),
                    tint=colour(hits, material.specular), alpha=np.column_stack([ax, ay]))
    if isinstance(material, DiffuseTransmission):
        return dict(kind=KIND["diffuse_transmission"], scale=colour(hits, material.reflectance),
                    tint=colour(hits, material.transmittance))
    if isinstance(material, Measured) and tables is not None:
        data, channels = load_measured(material.path), rgb_channels(hits)
        if isinstance(data, IrregularSamples):
            table = irregular_table(data)
            kind, extra = KIND["measured"], [tables.place(table), table.shape[0]]
        else:  # a MERL table: its bins as read, their shape the header's MERL_*
            kind, extra = KIND["merl"], [tables.place(data.rgb), 0]
        return dict(kind=kind, scale=channels[:, 0], tint=channels[:, 1], eta=channels[:, 2],
                    extra=np.array(extra, np.float32))
    return None


def parameters(material: SurfaceMaterial, hits: HitParameters, count: int, tables: TableStore | None = None,
               second_hits: HitParameters | None = None) -> np.ndarray | None:
    """``count`` ``BSDF_PARAMS`` rows of ``material`` at ``hits``, or None where the kernel does not
    cover the material (the numpy BSDF then shades it); ``tables`` holds measured tables, named
    metals' Fresnel tables and mixes' second lobes (without it those stay in numpy). A mix is covered
    where its second material's lobe is the same at every hit (no textures; RGB rays), with its
    amount clipped to [0, 1] as ``bsdf_for`` clips it; a row of amount 0 is its first lobe alone,
    which is what the numpy mix gives there. For spectral rays (colours of one channel) each colour
    fills all three of the kernel's channels, which then agree, and any one of them is the ray's
    (the lobe choices use channel means, unchanged by the repetition). ``second_hits``: one hit a
    mix's second material is looked up at instead of ``hits`` (the fused bounce's RGB constants: it
    turns that lobe into spectral rays' channels itself, so a spectral ray's mix is covered there)."""
    if not isinstance(material, Mix):
        lobe = _lobe(material, hits, count, tables)
        return None if lobe is None else _rows(count, lobe, BSDF_PARAMS.width)
    if tables is None:
        return None
    mixed = mix_rows(material, hits, count, tables, second_hits)
    if mixed is None:
        return None
    rows, second_rows = mixed
    if len(second_rows) and not np.all(second_rows == second_rows[:1]):
        return None
    rows[:, BSDF_PARAMS.offset("second")] = tables.place_lobe(second_rows[0]) if count else 0
    return rows


def mix_rows(material: Mix, hits: HitParameters, count: int, tables: TableStore,
             second_hits: HitParameters | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """A mix's ``count`` ``BSDF_PARAMS`` rows at ``hits`` (its first lobe and its amount, clipped to
    [0, 1] as ``bsdf_for`` clips it; ``second`` 0) and its second material's ``LOBE`` rows at ``hits``
    (``count`` of them) or at ``second_hits`` (one), or None where the kernel does not cover either
    material. ``parameters`` places a second lobe that is the same at every hit in ``tables``; the
    fused bounce passes a textured second material's rows per hit (``BounceKernel._hit_rows``)."""
    second_at, second_count = (hits, count) if second_hits is None else (second_hits, 1)
    first, second = _lobe(material.first, hits, count, tables), _lobe(material.second, second_at, second_count, tables)
    if first is None or second is None:
        return None
    rows = _rows(count, first, BSDF_PARAMS.width)
    rows[:, BSDF_PARAMS.offset("amount")] = np.clip(scalar(hits, material.amount), 0.0, 1.0)
    return rows, _rows(second_count, second, LOBE.width)


def holds_mix(material: SurfaceMaterial) -> TypeGuard[Mix]:
    """Whether ``material`` is a mix one of whose materials is a mix (``tree_rows``' kind)."""
    return isinstance(material, Mix) and (isinstance(material.first, Mix) or isinstance(material.second, Mix))


def leaf_count(material: SurfaceMaterial) -> int:
    """The materials that are not mixes in ``material``'s mix tree (1 for a material not a mix)."""
    return leaf_count(material.first) + leaf_count(material.second) if isinstance(material, Mix) else 1


def tree_width(leaves: int) -> int:
    """Floats in a ``TREE`` row of ``leaves`` lobes."""
    return TREE.width + leaves * LOBE.width


def tree_rows(material: Mix, hits: HitParameters, count: int, tables: TableStore) -> np.ndarray | None:
    """``count`` ``TREE`` rows (``tree_width`` of its leaves wide) of a mix holding a mix at ``hits``
    (the fused bounce reads one per hit: ``BounceKernel._hit_trees``), or None where it has more than
    ``MAX_LOBES`` leaves or the kernel does not cover one of them. Each leaf's lobe is looked up at
    ``hits`` as ``parameters`` looks a material up (spectral rays' colours repeated); each mix's amount
    is clipped as ``bsdf_for`` clips it. The kernel then evaluates and samples the tree as
    ``bsdf_for``'s nested ``WeightedSum``s do."""
    leaves = leaf_count(material)
    if leaves > MAX_LOBES:
        return None
    rows = np.zeros((count, tree_width(leaves)), np.float32)
    lobes: list[Columns] = []
    mixes: list[Mix] = []

    def place(part: SurfaceMaterial) -> int | None:
        """``part``'s code (a mix's index, or -1 - k for leaf k), its columns filled in; None where not covered."""
        if not isinstance(part, Mix):
            lobe = _lobe(part, hits, count, tables)
            if lobe is None:
                return None
            lobes.append(lobe)
            return -len(lobes)
        index = len(mixes)
        mixes.append(part)
        first, second = place(part.first), place(part.second)
        if first is None or second is None:
            return None
        rows[:, TREE.offset("amount") + index] = np.clip(scalar(hits, part.amount), 0.0, 1.0)
        rows[:, TREE.offset("first") + index] = first
        rows[:, TREE.offset("second") + index] = second
        return index

    if place(material) is None:
        return None
    rows[:, TREE.offset("nodes")] = len(mixes)
    for k, lobe in enumerate(lobes):
        rows[:, tree_width(k):tree_width(k + 1)] = _rows(count, lobe, LOBE.width)
    return rows


def _rows(count: int, lobe: Columns, width: int) -> np.ndarray:
    """``count`` rows of ``width`` float32 with ``lobe``'s ``LOBE`` columns first (``LOBE`` and
    ``BSDF_PARAMS`` share their names and offsets) and zero elsewhere."""
    rows = np.zeros((count, width), np.float32)
    for name, value in lobe.items():
        column, size = LOBE.offset(name), LOBE.dtype[name].shape[0]
        array = np.asarray(value, np.float32)  # (count, 1) colours of spectral rays broadcast
        rows[:, column:column + size] = array[:, None] if size == 1 and array.ndim == 1 else array
    return rows


class TableStore:
    """What the kernel reads beside its rows, back to back in one read-only buffer, each at a multiple
    of ``TABLE_ALIGN`` floats: measured and MERL tables and named metals' Fresnel tables (``place``, once per
    table), and mixes' second lobes (``place_lobe``, once per distinct lobe). Starts never move, so
    rows made before a later addition stay right."""

    def __init__(self, device: Device):
        self.device = device
        self._lock = threading.Lock()
        self._starts: dict[int | bytes, int] = {}
        self._tables: list[np.ndarray] = []  # held, so their ids stay theirs
        self._data = np.zeros(TABLE_ALIGN, np.float32)
        self.buffer = device.wrapped_buffer(self._data, np.float32)

    def place(self, table: np.ndarray) -> int:
        """``table``'s start in the buffer, in ``TABLE_ALIGN`` floats."""
        with self._lock:
            start = self._starts.get(id(table))
            if start is None:
                start = self._starts[id(table)] = self._append(table)
                self._tables.append(table)
            return start

    def place_lobe(self, lobe: np.ndarray) -> int:
        """A ``LOBE`` row's start in the buffer, in ``TABLE_ALIGN`` floats (one copy per distinct row)."""
        key = np.ascontiguousarray(lobe, np.float32).tobytes()
        with self._lock:
            start = self._starts.get(key)
            if start is None:
                start = self._starts[key] = self._append(lobe)
            return start

    def _append(self, array: np.ndarray) -> int:
        """Append ``array``'s floats, padded to ``TABLE_ALIGN``; its start (the caller holds the lock)."""
        start = len(self._data) // TABLE_ALIGN
        flat = np.ascontiguousarray(array, np.float32).ravel()
        self._data = np.concatenate([self._data, flat, np.zeros(-len(flat) % TABLE_ALIGN, np.float32)])
        self.buffer = self.device.wrapped_buffer(self._data, np.float32)
        return start


class BsdfKernel:
    """``kernels/bsdf.cl`` on ``device`` (its program built once per process)."""

    def __init__(self, device: Device):
        self.device = device
        self.tables = TableStore(device)
        self._local = threading.local()

    @cached_property
    def program(self) -> cl.Program:
        """The program, built on the first launch: a path tracer whose bounces all go through the
        fused bounce kernel (``renderer.bounce_kernel``) never launches this one."""
        return self.device.build_program(HEADER + kernel_source(KERNEL_FILE), KERNEL_FILE)

    def rows(self, material: SurfaceMaterial, hits: HitParameters, count: int) -> np.ndarray | None:
        """``parameters`` with this kernel's tables (the ``BsdfLauncher`` method); for a mix holding a
        mix, a ``BSDF_PARAMS`` row of kind "tree" followed by its ``tree_rows`` row (``tree_width`` of
        its leaves wider), or None where ``tree_rows`` does not cover it. Rows of several materials
        launched together are padded with zeros to the widest (``PathIntegrator._shade``)."""
        if not holds_mix(material):
            return parameters(material, hits, count, self.tables)
        tree = tree_rows(material, hits, count, self.tables)
        if tree is None:
            return None
        rows = np.zeros((count, BSDF_PARAMS.width + tree.shape[1]), np.float32)
        rows[:, BSDF_PARAMS.offset("kind")] = KIND["tree"]
        rows[:, BSDF_PARAMS.width:] = tree
        return rows

    def _queue_and_kernel(self) -> tuple[cl.CommandQueue, TypedKernel]:
        state = getattr(self._local, "state", None)
        if state is None:
            state = self._local.state = (self.device.queue(), TypedKernel(self.program, "bsdf"))
        return state

    def __call__(self, params: np.ndarray, wo: np.ndarray, light_wi: np.ndarray, u: np.ndarray, u_lobe: np.ndarray,
                 channels: int = 3) -> tuple[np.ndarray, np.ndarray, BSDFSample]:
        """For N hits with ``params`` (N, W: ``rows``' rows, W at least ``BSDF_PARAMS.width``) and local outgoing
        directions ``wo`` (N, 3): f (L, N, C) and pdf (L, N) at the L light directions ``light_wi``
        (L, N, 3), and the BSDF sample drawn with ``u`` (N, 2) and ``u_lobe`` (N,), as the numpy
        BSDF's ``evaluate``, ``pdf`` and ``sample`` give them (float32); C = ``channels``, 3 for RGB
        rays, 1 for spectral ones (whose rows repeat their channel)."""
        n, lights = len(wo), len(light_wi)
        light_f = np.zeros((lights, n, 3), np.float32)
        light_pdf = np.zeros((lights, n), np.float32)
        wi, value = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32)
        pdf, flags = np.zeros(n, np.float32), np.zeros(n, np.int32)
        if n:
            queue, kernel = self._queue_and_kernel()
            rows = self.device.wrapped_buffer(params, np.float32)
            inputs = [self.device.wrapped_buffer(a, np.float32) for a in (wo, light_wi, u, u_lobe)]
            self.device.run_into(queue, kernel, (whole_groups(n),), (LOCAL_SIZE,),
                                 (np.uint32(n), np.uint32(lights), rows, np.uint32(params.shape[1]),
                                  self.tables.buffer, *inputs),
                                 (light_f, light_pdf, wi, value, pdf, flags))
        specular = (flags & 1).astype(bool)
        return light_f[:, :, :channels], light_pdf, BSDFSample(wi, value[:, :channels], pdf, specular,
                                                               (flags & 2).astype(bool))
