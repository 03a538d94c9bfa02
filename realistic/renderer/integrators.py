"""Which integrator renders a scene: ``Scene.integrator`` ("directlighting" or "path") and its depth.

Lambertian surfaces lit by area lights alone under "directlighting" keep ``DirectLighting``, the
light-sampling fast path whose images the homework scenes have always had (with only diffuse BSDFs
and area lights MIS adds cost and no accuracy worth it). On the "opencl" backend, with RGB rays,
measured BRDFs of irregular samples (pbrt-v2's ``.brdf`` files, the seed scene's dragons) join them:
``kernels/shade.cl`` shades them from their tables with a BSDF sample per light sample, MIS as
pbrt-v2's ``directlighting``. Everything else goes through ``PathIntegrator`` (MIS direct lighting,
or path tracing).
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.backends import Backend
from realistic.renderer.bsdf import Lambertian, bsdf_for
from realistic.renderer.direct_lighting import DirectLighting, is_tabulated
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, Scene

INTEGRATORS = ("directlighting", "path")


class _NoHits:
    """Parameters at no hits: enough for ``bsdf_for`` to tell which BSDF a material makes."""

    def colour(self, value: object) -> np.ndarray:
        return np.zeros((0, 3), np.float32)

    def scalar(self, value: object) -> np.ndarray:
        return np.zeros(0, np.float32)


def is_lambertian(scene: Scene, tabulated: bool = False) -> bool:
    """Whether every instance's material makes a Lambertian BSDF (or, with ``tabulated``, is a
    measured BRDF ``DirectLighting`` shades from its table)."""
    materials = {id(inst.material): inst.material for inst in scene.instances}
    return all((tabulated and is_tabulated(material)) or isinstance(bsdf_for(material, _NoHits()), Lambertian)
               for material in materials.values())


def lights_light_each_other(scene: Scene) -> bool:
    """Whether one of the scene's area lights can reflect another's light: a light with a material
    (``AreaLight.material``) among two or more. ``DirectLighting`` ends rays at lights, which is
    exact otherwise (a planar light cannot light itself); ``PathIntegrator``'s "direct" mode shades
    a light's surface as pbrt-v3's DirectLightingIntegrator does."""
    return len(scene.lights) > 1 and any(light.material is not None for light in scene.lights)


def make_integrator(scene: Scene, intersector: Intersector, light_samples: int = 1, seed: int = 0,
                    pixel_spread_radians: float = 0.0, *, backend: Backend | str = "numpy",
                    spectral: bool = False) -> DirectLighting:
    """The integrator ``scene.integrator`` names, at ``scene.max_depth``. An "opencl" ``backend``
    (``renderer.backends``, or its name) lets ``DirectLighting`` shade with its OpenCL kernel
    (built for ``spectral`` rays or RGB ones) and ``PathIntegrator`` evaluate and sample the BSDFs
    ``kernels/bsdf.cl`` covers."""
    if scene.integrator not in INTEGRATORS:
        raise ValueError(f"unknown integrator {scene.integrator!r} (choose {', '.join(INTEGRATORS)})")
    name = backend if isinstance(backend, str) else backend.name
    area_lights_only = all(isinstance(light, AreaLight) for light in scene.lights)
    if scene.integrator == "directlighting" and area_lights_only and not lights_light_each_other(scene) \
            and is_lambertian(scene, tabulated=name == "opencl" and not spectral):
        return DirectLighting(scene, intersector, light_samples, seed, pixel_spread_radians, backend=backend,
                              spectral=spectral)
    mode = "direct" if scene.integrator == "directlighting" else "path"
    return PathIntegrator(scene, intersector, light_samples, seed, pixel_spread_radians, scene.max_depth, mode,
                          backend=backend)
