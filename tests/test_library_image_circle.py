"""The library's image circle (coarse scan and bisection) against a dense field-curve scan."""

import pytest

from realistic.optics.field_curves import field_curves
from realistic.optics.library import IMAGE_CIRCLE_ILLUMINATION, image_circle_mm, read_library_lens


@pytest.mark.parametrize("name", ["dgauss", "zoom.70-200mm-135"])
def test_relative_illumination_crosses_the_threshold_at_the_image_circle(name):
    lens, _ = read_library_lens(name)
    radius = image_circle_mm(lens) / 2
    # field curves out to 1.2 x that radius in 2.5 % steps, traced independently of the bisection
    rows = field_curves(lens, film_diagonal_mm=2 * 1.2 * radius / 0.999, points=49, samples=4000)
    inside = [r["relative_illumination"] for r in rows if r["film_radius_mm"] <= 0.95 * radius]
    outside = [r["relative_illumination"] for r in rows if r["film_radius_mm"] >= 1.05 * radius]
    assert min(inside) >= IMAGE_CIRCLE_ILLUMINATION
    assert max(outside) < IMAGE_CIRCLE_ILLUMINATION


def test_a_cached_image_circle_equals_a_fresh_one(monkeypatch):
    lens, _ = read_library_lens("tessar.100mm")
    cached = [image_circle_mm(lens, points=7, samples=1000) for _ in range(2)]  # the second from the disk cache
    monkeypatch.setenv("REALISTIC_CACHE_DIR", "off")
    assert cached[0] == cached[1] == image_circle_mm(lens, points=7, samples=1000)
