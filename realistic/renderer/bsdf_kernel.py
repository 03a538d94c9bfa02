"""OpenCL host of the path integrator's BSDFs: ``kernels/bsdf.cl`` on a ``Device``.

``PathIntegrator`` (``renderer/path.py``) uses it on the "opencl" backend for RGB rays at hits whose
material the kernel covers (``parameters`` returns their rows) where the fused bounce
(``renderer/bounce_kernel``, whose program holds ``bsdf.cl``'s functions too) does not take
the whole bounce: textured parameters, lights other than area lights. Lambertian (``Material`` without
Oren-Nayar roughness), conductors given by eta and k, mirrors, smooth and thin dielectrics, and
plastic. Every other material, and spectral rays, stay with the numpy BSDFs of ``renderer.bsdf``,
which are the reference (``tests/test_bsdf_kernel.py`` compares the two). The host looks each
parameter up at the hits as ``bsdf.factory.bsdf_for`` does (textures included) and packs one
``BSDF_PARAMS`` row per hit; the kernel takes the integrator's own uniform numbers, so both draw the
same directions. One launch per bounce evaluates every light sample's direction and draws the
BSDF sample; each thread has its own queue, so the renderer's worker threads launch independently.
"""

from __future__ import annotations

import threading
from functools import cached_property

import numpy as np

from realistic.device.opencl import LOCAL_SIZE, Device, cl, kernel_source, whole_groups
from realistic.device.tables import Table, constant_defines
from realistic.renderer.bsdf.base import BSDFSample, HitParameters
from realistic.renderer.bsdf.factory import colour, scalar
from realistic.renderer.bsdf.microfacet import SMOOTH_ALPHA, alpha
from realistic.scene.materials import Conductor, Dielectric, Mirror, Plastic, SurfaceMaterial
from realistic.scene.model import Material

KERNEL_FILE = "bsdf.cl"
#: One hit's BSDF: its kind (``KINDS``); ``scale`` the Lambertian albedo, the conductor's or mirror's
#: scale, the glass's reflection tint or the plastic's diffuse colour; ``tint`` the glass's
#: transmission tint or the plastic's coat colour; ``eta`` the conductor's index per channel (a
#: dielectric's or coat's index in its first column); ``k`` the conductor's absorption; ``alpha``
#: the GGX widths along x and y.
BSDF_PARAMS = Table("BSDF_PARAM", np.float32, (("kind", 1), ("scale", 3), ("tint", 3), ("eta", 3), ("k", 3),
                                               ("alpha", 2)))
KINDS = ("lambertian", "conductor", "mirror", "dielectric", "thin_dielectric", "plastic")
KIND = {name: index for index, name in enumerate(KINDS)}
HEADER = BSDF_PARAMS.defines() + constant_defines("KIND", KINDS) + f"#define SMOOTH_ALPHA {SMOOTH_ALPHA!r}f\n"


def parameters(material: SurfaceMaterial, hits: HitParameters, count: int) -> np.ndarray | None:
    """``count`` ``BSDF_PARAMS`` rows of ``material`` at ``hits`` (RGB), or None where the kernel does
    not cover the material (the numpy BSDF then shades it). The same look-ups as ``bsdf_for``."""
    if isinstance(material, Material):
        if material.sigma != 0:
            return None
        albedo = hits.colour(material.diffuse)
        if material.texture is not None:
            albedo = albedo * hits.colour(material.texture)
        return BSDF_PARAMS.pack(count, kind=KIND["lambertian"], scale=albedo)
    if isinstance(material, Plastic):
        kd, ks = colour(hits, material.diffuse), colour(hits, material.specular)
        a = alpha(scalar(hits, material.roughness), material.rule)
        return BSDF_PARAMS.pack(count, kind=KIND["plastic"], scale=kd, tint=ks, eta=np.float32(material.eta),
                                alpha=np.column_stack([a, a]))
    if isinstance(material, Conductor):
        if material.spectra is not None:
            return None
        ax = alpha(scalar(hits, material.roughness_u), material.rule)
        ay = alpha(scalar(hits, material.roughness_v), material.rule)
        return BSDF_PARAMS.pack(count, kind=KIND["conductor"], scale=colour(hits, material.scale),
                                eta=colour(hits, material.eta), k=colour(hits, material.k),
                                alpha=np.column_stack([ax, ay]))
    if isinstance(material, Mirror):
        return BSDF_PARAMS.pack(count, kind=KIND["mirror"], scale=colour(hits, material.reflectance))
    if isinstance(material, Dielectric) and (material.thin or material.roughness_u == material.roughness_v == 0.0):
        return BSDF_PARAMS.pack(count, kind=KIND["thin_dielectric" if material.thin else "dielectric"],
                                scale=colour(hits, material.reflectance), tint=colour(hits, material.transmittance),
                                eta=np.float32(material.eta))
    return None


class BsdfKernel:
    """``kernels/bsdf.cl`` on ``device`` (its program built once per process)."""

    def __init__(self, device: Device):
        self.device = device
        self._local = threading.local()

    @cached_property
    def program(self) -> cl.Program:
        """The program, built on the first launch: a path tracer whose bounces all go through the
        fused bounce kernel (``renderer.bounce_kernel``) never launches this one."""
        return self.device.build_program(HEADER + kernel_source(KERNEL_FILE), KERNEL_FILE)

    def rows(self, material: SurfaceMaterial, hits: HitParameters, count: int) -> np.ndarray | None:
        """``parameters`` (the ``BsdfLauncher`` method)."""
        return parameters(material, hits, count)

    def _queue_and_kernel(self) -> tuple[cl.CommandQueue, cl.Kernel]:
        state = getattr(self._local, "state", None)
        if state is None:
            state = self._local.state = (self.device.queue(), cl.Kernel(self.program, "bsdf"))
        return state

    def __call__(self, params: np.ndarray, wo: np.ndarray, light_wi: np.ndarray, u: np.ndarray, u_lobe: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, BSDFSample]:
        """For N hits with ``params`` (N, ``BSDF_PARAMS.width``) and local outgoing directions ``wo``
        (N, 3): f (L, N, 3) and pdf (L, N) at the L light directions ``light_wi`` (L, N, 3), and the
        BSDF sample drawn with ``u`` (N, 2) and ``u_lobe`` (N,), as the numpy BSDF's
        ``evaluate``, ``pdf`` and ``sample`` give them (float32)."""
        n, lights = len(wo), len(light_wi)
        light_f = np.zeros((lights, n, 3), np.float32)
        light_pdf = np.zeros((lights, n), np.float32)
        wi, value = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32)
        pdf, flags = np.zeros(n, np.float32), np.zeros(n, np.int32)
        if n:
            queue, kernel = self._queue_and_kernel()
            inputs = [self.device.wrapped_buffer(a, np.float32) for a in (params, wo, light_wi, u, u_lobe)]
            self.device.run_into(queue, kernel, (whole_groups(n),), (LOCAL_SIZE,),
                                 (np.uint32(n), np.uint32(lights), *inputs),
                                 (light_f, light_pdf, wi, value, pdf, flags))
        specular = (flags & 1).astype(bool)
        return light_f, light_pdf, BSDFSample(wi, value, pdf, specular, (flags & 2).astype(bool))
