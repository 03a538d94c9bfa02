"""Render backends: what runs the kernels, picked from the options' strings ``backend`` and ``cl_device``.

The options keep the strings (a job stays picklable for Dask: each worker process makes its own
backend and device); ``backend_for`` turns them into a backend object, once per process and pair.
``NumpyBackend`` runs the numpy references; ``OpenCLBackend`` (``renderer/opencl_backend``,
imported only when chosen, since it imports pyopencl) runs ``kernels/lens.cl``, ``thin_lens.cl``,
``shade.cl``, ``ewa.cl`` and ``bsdf.cl`` on one ``Device`` and keeps each MIP map's texels there,
keyed by the map, so scenes, cameras and textures stay plain data.
"""

from __future__ import annotations

import threading
from typing import Protocol

import numpy as np

from realistic.camera.base import BACKENDS, Camera, RayGenerator, check_backend
from realistic.optics.ghosts import GhostPath, GhostTrace, GhostTracer, trace_direct, trace_ghost
from realistic.optics.lens import LensSystem
from realistic.renderer.bsdf.base import BSDFSample, HitParameters
from realistic.renderer.footprint import triangle_footprint
from realistic.scene.materials import SurfaceMaterial
from realistic.scene.mipmap import MipMap
from realistic.scene.textures import Footprint, numpy_lookup

__all__ = ["BACKENDS", "Backend", "BsdfLauncher", "NumpyBackend", "backend_for"]


class BsdfLauncher(Protocol):
    """BSDFs of a batch of hits on a device (``renderer.bsdf_kernel.BsdfKernel``)."""

    def rows(self, material: SurfaceMaterial, hits: HitParameters, count: int) -> np.ndarray | None:
        """``material``'s parameter rows at ``count`` ``hits``; None where the device does not cover it."""

    def __call__(self, params: np.ndarray, wo: np.ndarray, light_wi: np.ndarray, u: np.ndarray,
                 u_lobe: np.ndarray, channels: int = 3) -> tuple[np.ndarray, np.ndarray, BSDFSample]:
        """f (L, N, C) and pdf (L, N) at light directions ``light_wi`` (L, N, 3), and one BSDF sample
        (C = ``channels``: 3 for RGB rays, 1 for spectral ones)."""

class Backend(Protocol):
    """What the renderer asks of a backend."""

    #: "numpy" or "opencl" (``BACKENDS``).
    name: str

    def ray_generator(self, camera: Camera, seed: int) -> RayGenerator:
        """The camera's rays of any ``SampleBlock`` with ``seed``."""

    def build_ahead(self, camera: Camera, time_choices: bool = True) -> None:
        """Build what ``ray_generator(camera, ...)`` will build, before the camera is prepared
        (its exit-pupil table made), so that a render thread can do it meanwhile. ``time_choices``:
        whether the render repays compiling: this process's kernels then time the build choices they
        have not timed yet and keep the binaries of every program built from now on for the next
        process, else take the quickest to build, untimed, and leave the binaries to a second build."""

    def image_lookup(self, mipmap: MipMap, texture_filter: str, st: np.ndarray, axes: Footprint | None
                     ) -> np.ndarray:
        """An image texture's lookups (N, 3) with any filter, with or without a footprint (a
        ``scene.textures.ImageLookup``)."""

    def triangle_footprint(self, vertices: np.ndarray, uv: np.ndarray, linear: np.ndarray, face: np.ndarray,
                           geom: np.ndarray, direction: np.ndarray, normal: np.ndarray, distance: np.ndarray,
                           spread_radians: float) -> Footprint:
        """The uv axes of the pixel footprints of hits on triangles ``face`` of a mesh's ``vertices``
        and ``uv`` placed by ``linear[geom]``: ``footprint.triangle_footprint``'s."""

    def ghost_tracer(self, lens: LensSystem) -> GhostTracer:
        """What traces ``lens``'s ghost paths (lens flare, ``renderer.flare``)."""

    def bsdf_kernel(self) -> BsdfLauncher | None:
        """What evaluates and samples the path integrator's BSDFs on a device (None: numpy does)."""


class NumpyBackend:
    """The numpy references: ``Camera.generate_rays``, ``MipMap``'s filters, the integrators' numpy shading."""

    name = "numpy"

    def ray_generator(self, camera: Camera, seed: int) -> RayGenerator:
        """``camera.generate_rays`` with ``seed`` (float64)."""
        return lambda block: camera.generate_rays(block, seed)

    def build_ahead(self, camera: Camera, time_choices: bool = True) -> None:
        """Nothing: numpy builds nothing."""

    def image_lookup(self, mipmap: MipMap, texture_filter: str, st: np.ndarray, axes: Footprint | None
                     ) -> np.ndarray:
        """``textures.numpy_lookup``: ``MipMap``'s filters."""
        return numpy_lookup(mipmap, texture_filter, st, axes)

    def triangle_footprint(self, vertices: np.ndarray, uv: np.ndarray, linear: np.ndarray, face: np.ndarray,
                           geom: np.ndarray, direction: np.ndarray, normal: np.ndarray, distance: np.ndarray,
                           spread_radians: float) -> Footprint:
        """``footprint.triangle_footprint``, the reference, over ``linear[geom]``."""
        return triangle_footprint(vertices, uv, face, linear[geom], direction, normal, distance, spread_radians)

    def ghost_tracer(self, lens: LensSystem) -> GhostTracer:
        """The float64 reference, ``optics.ghosts.trace_ghost`` (``trace_direct`` for None)."""
        def trace(film_distance_mm: float, path: GhostPath | None, origins: np.ndarray, directions: np.ndarray,
                  wavelength_nm: float | np.ndarray) -> GhostTrace:
            if path is None:
                return trace_direct(lens, film_distance_mm, origins, directions, wavelength_nm)
            return trace_ghost(lens, film_distance_mm, path, origins, directions, wavelength_nm)
        return trace

    def bsdf_kernel(self) -> BsdfLauncher | None:
        """None: the path integrator's numpy BSDFs."""
        return None


#: One backend per process and (name, device spec), so a device's programs and texels are reused.
_backends: dict[tuple[str, str | None], Backend] = {}
_backends_lock = threading.Lock()


def backend_for(name: str, cl_device: str | None = None) -> Backend:
    """The backend ``name`` ("opencl" or "numpy") names, on the OpenCL device ``cl_device``
    (``--cl-device``; None: the default) for "opencl", made once per process. A bad name, no
    platform or no matching device is a UserError."""
    check_backend(name)
    with _backends_lock:
        if (name, cl_device) not in _backends:
            _backends[name, cl_device] = NumpyBackend() if name == "numpy" else _opencl_backend(cl_device)
        return _backends[name, cl_device]


def _opencl_backend(cl_device: str | None) -> Backend:
    """A new OpenCL backend on ``cl_device`` (imports pyopencl: only when chosen)."""
    from realistic.device.opencl import Device
    from realistic.renderer.opencl_backend import OpenCLBackend

    return OpenCLBackend(Device.for_spec(cl_device))
