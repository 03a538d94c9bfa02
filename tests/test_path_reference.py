"""The general integrator against ``DirectLighting`` on the shading reference's textured scene.

With light sampling alone (``mis`` False) and area lights only, ``PathIntegrator`` "direct" draws the
same random numbers (``rng.light_uniforms``) and evaluates the same estimator through the BSDF
interface, so each ray's radiance must agree to float32 rounding: EWA-filtered image, checker and grid
textures over pixel footprints, smooth normals, one- and two-sided lights, the background, RGB and
spectral rays. ``DirectLighting`` itself is checked against a slow float64 reference in
``test_shading_reference``.
"""

import numpy as np
import pytest

from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.optics.formats import load_lens
from realistic.renderer.backends import backend_for
from realistic.renderer.direct_lighting import DirectLighting
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from test_shading_reference import textured_scene

SEED, SPP, LIGHT_SAMPLES = 7, 2, 2


@pytest.mark.parametrize("spectral", [False, True])
def test_light_sampling_through_the_bsdf_interface_matches_direct_lighting(spectral):
    scene, eye, target = textured_scene()
    camera = LensCamera.looking_at(load_lens("dgauss"), eye, target, None, FULL_FRAME_DIAGONAL_MM, 24, 16, SPP)
    rays = backend_for("numpy").ray_generator(camera, SEED)(SampleBlock(0, camera.sample_count, camera.spp))
    alive = np.flatnonzero(rays.weight != 0)
    args = (rays.origin[alive].astype(np.float32), rays.direction[alive].astype(np.float32), rays.pixel[alive],
            alive % SPP, None, np.random.default_rng(1).uniform(400, 700, len(alive)) if spectral else None)
    spread = camera.pixel_spread_radians()
    expected, _ = DirectLighting(scene, Intersector(scene), LIGHT_SAMPLES, SEED, spread).radiance(*args)
    general = PathIntegrator(scene, Intersector(scene), LIGHT_SAMPLES, SEED, spread, 1, "direct", mis=False)
    got, _ = general.radiance(*args)
    scale = float(np.abs(expected).max())
    compared = np.arange(len(alive))
    if spectral:
        # bsdf_for multiplies a material's colour and texture as spectra, DirectLighting as RGB before
        # taking the spectrum: textured surfaces differ by design there
        geom = Intersector(scene).closest(args[0], args[1]).geom
        textured = [i for i, inst in enumerate(scene.instances) if inst.material.texture is not None]
        compared = np.flatnonzero(~np.isin(geom, textured))
        assert len(compared) > len(alive) // 4
    close = np.all(np.isclose(got[compared], expected[compared], rtol=1e-4, atol=1e-5 * scale), axis=1)
    differ = compared[~close]
    # where the view lies below a smooth mesh's interpolated normal (a silhouette) the BSDF interface's
    # Lambertian is black, as pbrt-v4's DiffuseBxDF (SameHemisphere in the shading frame); DirectLighting
    # shades it as pbrt-v3 did: those rays alone may differ
    hits = Intersector(scene).closest(args[0][differ], args[1][differ])
    smooth = {i for i, inst in enumerate(scene.instances) if scene.meshes[inst.mesh].normals is not None
              and np.ptp(scene.meshes[inst.mesh].normals, axis=0).max() > 1e-6}
    assert len(differ) <= len(alive) // 200 and np.all(got[differ] == 0) and set(hits.geom) <= smooth
    assert np.count_nonzero(expected.max(axis=1) > 2 * max(scene.background)) > len(alive) // 4  # lit surfaces
