"""Area-light sampling in one compiled loop (``light_sampler._area_loop``, taken when every light is
an area light, as in the seed scene): bit for bit what the numpy path computes, ``AreaLightTable.points``
then ``LightSampler._towards_surface``, for disks and quads, one- and two-sided, at the disk's centre
and from points behind a light."""

import numpy as np

from realistic.core.transforms import rotate, translate
from realistic.renderer.light_sampler import LightSampler
from realistic.scene.model import AreaLight, Scene


def _numpy_sample(sampler: LightSampler, point: np.ndarray, u0: np.ndarray, u1: np.ndarray, u2: np.ndarray
                  ) -> tuple[np.ndarray, ...]:
    """The numpy path's (target, wi, distance, radiance, pdf) of area-light samples."""
    n = len(point)
    j = np.minimum(np.searchsorted(sampler.cdf, u0, side="right"), len(sampler.cdf) - 1)
    slot = sampler.area_slot[j]
    table = sampler.area_lights
    q = table.points(slot, u1.astype(np.float64), u2.astype(np.float64))
    wi, rgb = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32)
    distance, pdf = np.zeros(n, np.float32), np.zeros(n)
    sampler._towards_surface(slice(None), point, q, np.take(table.normal, slot, axis=0), table.two_sided[slot],
                             table.area[slot], np.take(table.radiance, slot, axis=0), wi, distance, rgb, pdf)
    return q, wi, distance, rgb, pdf * sampler.probability[j]


def test_the_compiled_area_loop_is_the_numpy_path_bit_for_bit():
    scene = Scene()
    scene.lights.extend([
        AreaLight("disk", (0.5, 0.5), (1.0, 2.0, 3.0), translate(1.0, 2.0, 3.0) @ rotate(30, (1, 0, 0))),
        AreaLight("quad", (2.0, 0.5), (4.0, 4.0, 4.0), translate(-1.0, 0.0, 2.0) @ rotate(90, (0, 1, 0)),
                  two_sided=True),
        AreaLight("disk", (8.0, 8.0), (40.0, 40.0, 40.0), translate(0, 10, 0) @ rotate(90, (1, 0, 0)))])
    sampler = LightSampler(scene, 10.0)
    rng = np.random.default_rng(12)
    n = 20_000
    point = ((rng.random((n, 3)) - 0.5) * 8).astype(np.float32)  # some behind a one-sided light
    u0, u1, u2 = rng.random((3, n)).astype(np.float32)
    u1[:3], u2[:3] = [0.5, 0.0, 0.5], [0.5, 0.0, 0.0]  # a disk's centre (the map's 0 / 0) and edges
    got = sampler.sample(point, u0, u1, u2, None)
    target, wi, distance, rgb, pdf = _numpy_sample(sampler, point, u0, u1, u2)
    for name, a, b in (("target", got.target, target), ("wi", got.wi, wi), ("distance", got.distance, distance),
                       ("radiance", got.radiance, rgb), ("pdf", got.pdf, pdf)):
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert np.array_equal(got.valid, (pdf > 0) & np.any(rgb != 0, axis=1)) and not got.delta.any()
    assert 0 < np.count_nonzero(got.pdf == 0) < n and sampler.area_only
