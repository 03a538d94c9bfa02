"""The "opencl" render backend: the camera, shading, BSDF and EWA kernels on one ``Device``.

Made by ``renderer.backends.backend_for`` (one per process and device spec). It keeps the per-device
state of what it is asked about: each MIP map's texels (an ``EwaKernel``) in a weak dictionary keyed
by the map, so a map is not held alive by the backend, and nothing is stored on the map.
"""

from __future__ import annotations

import threading
import weakref
from typing import Any

import numpy as np

from realistic.camera import opencl_host
from realistic.camera.base import Camera, RayGenerator
from realistic.camera.ghost_host import GhostKernel
from realistic.camera.lens_camera import LensCamera
from realistic.camera.opencl_host import LensKernel, build_ahead
from realistic.camera.thin_lens import ThinLensCamera
from realistic.camera.thin_lens_host import ThinLensKernel, thin_lens_program
from realistic.device.opencl import Device, keep_first_builds
from realistic.optics.ghosts import GhostTracer
from realistic.optics.lens import LensSystem
from realistic.renderer.bounce_kernel import BounceKernel
from realistic.renderer.bsdf_kernel import BsdfKernel
from realistic.renderer.shade_kernel import ShadeKernel
from realistic.scene.ewa_kernel import EwaKernel, FootprintKernel, SurfaceTables
from realistic.scene.mipmap import MipMap
from realistic.scene.textures import Footprint


class OpenCLBackend:
    """Kernels on ``device``: camera rays of a ``LensCamera`` or a ``ThinLensCamera``, image-texture lookups,
    and the shading kernel for ``DirectLighting``."""

    name = "opencl"

    def __init__(self, device: Device):
        self.device = device
        self._ewa_kernels: weakref.WeakKeyDictionary[MipMap, EwaKernel] = weakref.WeakKeyDictionary()
        self._lock = threading.Lock()
        self._bsdf_kernel: BsdfKernel | None = None
        self._footprint_kernel: FootprintKernel | None = None

    def ray_generator(self, camera: Camera, seed: int) -> RayGenerator:
        """``lens.cl``'s rays (float32) for a ``LensCamera``, ``thin_lens.cl``'s for a
        ``ThinLensCamera``, the numpy reference's for any other camera."""
        kernel: LensKernel | ThinLensKernel
        if isinstance(camera, LensCamera):
            kernel = LensKernel(camera, self.device)
        elif isinstance(camera, ThinLensCamera):
            kernel = ThinLensKernel(camera, self.device)
        else:
            return lambda block: camera.generate_rays(block, seed)
        return lambda block: kernel.generate(block, seed)

    def build_ahead(self, camera: Camera, time_choices: bool = True) -> None:
        """The programs ``ray_generator(camera, ...)`` will use, built now (``opencl_host.build_ahead``);
        ``time_choices``: ``opencl_host.time_choices``, for this process's lens kernels from now on,
        and ``opencl.keep_first_builds``, for every program built from now on."""
        opencl_host.time_choices(time_choices)
        keep_first_builds(time_choices)
        if isinstance(camera, LensCamera):
            build_ahead(camera, self.device)
        elif isinstance(camera, ThinLensCamera):
            self.device.build_program(*thin_lens_program(camera))

    def ewa_kernel(self, mipmap: MipMap) -> EwaKernel:
        """``mipmap``'s texels on this backend's device, made on first use."""
        with self._lock:
            kernel = self._ewa_kernels.get(mipmap)
            if kernel is None:
                kernel = self._ewa_kernels[mipmap] = EwaKernel(mipmap, self.device)
            return kernel

    def image_lookup(self, mipmap: MipMap, texture_filter: str, st: np.ndarray, axes: Footprint | None
                     ) -> np.ndarray:
        """``textures.numpy_lookup``'s lookups by ``kernels/ewa.cl`` (the same to float32 rounding:
        ``EwaKernel``), every filter of ``DEVICE_FILTERS`` and the lookups without a footprint."""
        return self.ewa_kernel(mipmap).lookup(texture_filter, st, axes)

    def triangle_footprint(self, vertices: np.ndarray, uv: np.ndarray, linear: np.ndarray, face: np.ndarray,
                           geom: np.ndarray, direction: np.ndarray, normal: np.ndarray, distance: np.ndarray,
                           spread_radians: float) -> Footprint:
        """``footprint.triangle_footprint`` over ``linear[geom]`` by ``kernels/ewa.cl`` (``FootprintKernel``,
        made on first use; the reference's to float64 rounding)."""
        with self._lock:
            if self._footprint_kernel is None:
                self._footprint_kernel = FootprintKernel(self.device)
        return self._footprint_kernel(vertices, uv, linear, face, geom, direction, normal, distance, spread_radians)

    def ghost_tracer(self, lens: LensSystem) -> GhostTracer:
        """``kernels/ghost.cl`` for ``lens`` on this device, float32 (its program is built once per
        process and lens by ``Device.build_program``; a kernel object holds its lens, so none is kept
        here, where it would keep the lens alive)."""
        return GhostKernel(lens, self.device).trace

    def bsdf_kernel(self) -> BsdfKernel:
        """``kernels/bsdf.cl`` on this device for ``PathIntegrator``, made on first use."""
        with self._lock:
            if self._bsdf_kernel is None:
                self._bsdf_kernel = BsdfKernel(self.device)
            return self._bsdf_kernel

    def bounce_kernel(self, **tables: Any) -> BounceKernel:
        """``BounceKernel`` (the path integrator's fused bounce) on this device with a scene's ``tables``
        and the BSDF kernel's ``TableStore``."""
        return BounceKernel(self.device, tables=self.bsdf_kernel().tables, **tables)

    def shade_kernel(self, **tables: Any) -> ShadeKernel:
        """``ShadeKernel`` on this device with a scene's ``tables`` (its keyword arguments)."""
        return ShadeKernel(device=self.device, **tables)

    def surface_tables(self, *arrays: np.ndarray) -> SurfaceTables:
        """``SurfaceTables`` on this device (its arrays, in its order)."""
        return SurfaceTables(self.device, *arrays)
