"""Pixel filters: their integrals, the unbiasedness of filter importance sampling, pbrt's defaults per
version, and the PixelFilter directive.

The references are independent of the code under test: integrals by composite Simpson quadrature of
the filter's formula written out here, filtered values of a step edge and a linear ramp in closed form
(or by that quadrature), the defaults as each pbrt's source sets them.
"""

import dataclasses
import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import realistic as rl
from realistic.core.pixel_filter import PIXEL_BOX, TABLE_BINS, PixelFilter, filter_name
from realistic.errors import UserError
from realistic.renderer.inputs import RenderOptions
from realistic.scene.pbrt.importer import import_pbrt

FILTERS = [PixelFilter("box", 0.5, 1.5), PixelFilter("triangle", 2.0, 1.0), PixelFilter("gaussian", 2.0, 1.5, 2.0),
           PixelFilter("gaussian", 1.5, 1.5, 0.7), PixelFilter("mitchell", 2.0, 2.0),
           PixelFilter("mitchell", 1.5, 2.5, b=0.0, c=0.5),
           PixelFilter("sinc", 4.0, 3.0, sinc_scale=1.0, window_scale=1 / 3),
           PixelFilter("sinc", 4.0, 4.0, sinc_scale=0.75, window_scale=0.25)]


def formula(f: PixelFilter, x: np.ndarray, r: float) -> np.ndarray:
    """The pbrt filter along one axis, written out again from the pbrt sources for the tests."""
    inside = np.abs(x) <= r
    if f.name == "box":
        v = np.ones_like(x)
    elif f.name == "triangle":
        v = r - np.abs(x)
    elif f.name == "gaussian":
        v = np.exp(-f.alpha * x**2) - math.exp(-f.alpha * r * r)
    elif f.name == "mitchell":
        t, b, c = np.abs(2 * x / r), f.b, f.c
        v = np.where(t < 1, (12 - 9 * b - 6 * c) * t**3 + (-18 + 12 * b + 6 * c) * t**2 + 6 - 2 * b,
                     (-b - 6 * c) * t**3 + (6 * b + 30 * c) * t**2 - (12 * b + 48 * c) * t + 8 * b + 24 * c) / 6
    else:
        def sinc(t):
            safe = np.where(t == 0, 1.0, t)
            return np.where(t == 0, 1.0, np.sin(np.pi * safe) / (np.pi * safe))
        v = sinc(f.sinc_scale * x) * sinc(f.window_scale * x)
    return np.where(inside, v, 0.0)


def simpson(f: PixelFilter, r: float, lo: float | None = None, n: int = 200_000) -> float:
    """Composite Simpson integral of ``formula`` over [lo (default -r), r]."""
    lo = -r if lo is None else lo
    x = np.linspace(lo, r, n + 1)
    y = formula(f, x, r)
    return (r - lo) / n / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


@pytest.mark.parametrize("f", FILTERS, ids=lambda f: f.describe())
def test_integral_matches_quadrature(f):
    for r in (f.radius_x, f.radius_y):
        assert f.integral_1d(r) == pytest.approx(simpson(f, r), rel=1e-7, abs=1e-9)
    assert f.integral() == pytest.approx(simpson(f, f.radius_x) * simpson(f, f.radius_y), rel=1e-7)


@pytest.mark.parametrize("f", FILTERS, ids=lambda f: f.describe())
def test_evaluation_is_the_pbrt_formula(f):
    x = np.linspace(-f.radius_x - 1, f.radius_x + 1, 1001)
    np.testing.assert_allclose(f.evaluate_1d(x, f.radius_x), formula(f, x, f.radius_x), atol=1e-12)


def _estimate(values: np.ndarray) -> tuple[float, float]:
    return float(values.mean()), float(values.std() / math.sqrt(len(values)))


@pytest.mark.parametrize("f", FILTERS, ids=lambda f: f.describe())
def test_sampling_is_unbiased_for_a_step_edge_and_a_ramp(f):
    """The Monte Carlo estimate mean(w g(offset)) matches (f * g)(0) / integral(f) for g a step edge at
    e (in x) and a ramp a + b y (in y), within five standard errors."""
    count = 400_000
    gen = np.random.default_rng(7)
    u_x, u_y = gen.random(count, np.float32), gen.random(count, np.float32)
    dx, dy, w = f.offsets(u_x, u_y)
    assert np.all(np.abs(dx) <= f.radius_x) and np.all(np.abs(dy) <= f.radius_y)
    for edge in (-0.3 * f.radius_x, 0.1, 0.55 * f.radius_x):
        if f.name == "gaussian":  # closed form
            a, r = f.alpha, f.radius_x
            part = (math.sqrt(math.pi / a) / 2 * (math.erf(math.sqrt(a) * r) - math.erf(math.sqrt(a) * edge))
                    - math.exp(-a * r * r) * (r - edge))
        elif f.name in ("box", "triangle"):  # closed form
            r = f.radius_x
            part = r - edge if f.name == "box" else (
                (r - edge) ** 2 / 2 if edge >= 0 else r * r / 2 + (r * (-edge) - edge * edge / 2))
        else:
            part = simpson(f, f.radius_x, lo=edge)
        expected = part / simpson(f, f.radius_x)
        mean, error = _estimate(w * (dx > edge))
        assert abs(mean - expected) < 5 * error + 2e-4, (edge, mean, expected, error)
    mean, error = _estimate(w * (0.3 + 2.0 * dy))  # a symmetric filter keeps a ramp's centre value
    assert abs(mean - 0.3) < 5 * error + 2e-4


def test_the_default_box_is_plain_jitter_bit_for_bit():
    u = np.random.default_rng(1).random(100_000, np.float32)
    dx, dy, w = PIXEL_BOX.offsets(u, u[::-1])
    assert np.array_equal(0.5 + dx, u.astype(np.float64)) and np.array_equal(0.5 + dy, u[::-1].astype(np.float64))
    assert np.all(w == 1.0)


def test_negative_lobes_carry_negative_weights_that_normalise():
    f = PixelFilter("sinc", 4.0, 4.0)
    u = (np.arange(200_000, dtype=np.float32) + 0.5) / 200_000
    dx, _, w = f.offsets(u, np.full_like(u, 0.5))
    table = f.x_table
    assert (w < 0).any() and np.all(np.sign(w) == np.sign(formula(f, dx, 4.0)) * np.sign(formula(f, 0 * dx, 4.0)))
    # E[w_x] = integral(f) / integral(f) = 1; the fixed centre sample along y weighs integral|f| / integral(f)
    assert w.mean() == pytest.approx(f.y_table.ratio, abs=1e-3)
    assert table.ratio == pytest.approx(simpson_abs(f, 4.0) / simpson(f, 4.0), rel=1e-3)
    assert len(table.cdf) == TABLE_BINS + 1


def simpson_abs(f: PixelFilter, r: float, n: int = 200_000) -> float:
    x = np.linspace(-r, r, n + 1)
    y = np.abs(formula(f, x, r))
    return 2 * r / n / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


def test_filter_names_and_parameters_are_checked_once():
    assert filter_name("lanczos") == "sinc"
    for bad in (lambda: filter_name("catmull-rom"), lambda: PixelFilter("box", 0.0, 1.0),
                lambda: PixelFilter("box", 17.0, 1.0), lambda: PixelFilter("gaussian", 2, 2, alpha=math.nan),
                lambda: RenderOptions(pixel_filter="bessel")):
        with pytest.raises(UserError) as err:
            bad()
        assert "\n" not in str(err.value)


# ---- pbrt scenes ---------------------------------------------------------------------------------

def scene_file(folder: Path, header: str, name: str = "s.pbrt") -> Path:
    path = folder / name
    path.write_text(f'{header}LookAt 0 0 -1  0 0 0  0 1 0\nCamera "perspective" "float fov" 60\n'
                    'Film "image" "integer xresolution" 8 "integer yresolution" 8\nWorldBegin\n'
                    'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1]\nTranslate 0 0 -2\n'
                    'Shape "disk" "float radius" 6\nAttributeEnd\nWorldEnd\n')
    return path


@pytest.mark.parametrize("dialect,expected", [("v1", "mitchell radius 2x2 B 0.333333 C 0.333333"),
                                              ("v2", "box radius 0.5x0.5"), ("v3", "box radius 0.5x0.5"),
                                              ("v4", "gaussian radius 1.5x1.5 alpha 2")])
def test_each_pbrt_default_filter_when_the_scene_names_none(tmp_path, dialect, expected):
    """pbrt-v1 core/api.cpp: mitchell; pbrt-v2 and v3 src/core/api.cpp: box (0.5); pbrt-v4: gaussian
    (radius 1.5, sigma 0.5 = alpha 2)."""
    imported = import_pbrt(scene_file(tmp_path, ""), dialect=dialect)
    assert imported.scene.camera.pixel_filter.describe() == expected
    assert imported.scene.camera.metadata()["pixelFilter"] == expected


@pytest.mark.parametrize("dialect,line,expected", [
    ("v2", 'PixelFilter "gaussian" "float xwidth" 1 "float ywidth" 3 "float alpha" 4',
     PixelFilter("gaussian", 1.0, 3.0, 4.0)),
    ("v4", 'PixelFilter "gaussian" "float xradius" 1 "float sigma" 0.25', PixelFilter("gaussian", 1.0, 1.5, 8.0)),
    ("v3", 'PixelFilter "sinc" "float xwidth" 2 "float tau" 2', PixelFilter("sinc", 2.0, 4.0, 2.0, sinc_scale=1.0,
                                                                           window_scale=0.5)),
    ("v2", 'PixelFilter "sinc" "float xwidth" 2 "float tau" 2', PixelFilter("sinc", 2.0, 4.0, 2.0, sinc_scale=1.0,
                                                                           window_scale=0.5)),
    ("v4", 'PixelFilter "mitchell" "float B" 0 "float C" 0.5', PixelFilter("mitchell", 2.0, 2.0, b=0.0, c=0.5)),
    ("v3", 'PixelFilter "triangle" "float ywidth" 1', PixelFilter("triangle", 2.0, 1.0))])
def test_pixel_filter_parameters_in_each_dialect(tmp_path, dialect, line, expected):
    camera = import_pbrt(scene_file(tmp_path, line + "\n"), dialect=dialect).scene.camera
    got = camera.pixel_filter
    for name in ("name", "radius_x", "radius_y", "b", "c"):
        assert getattr(got, name) == pytest.approx(getattr(expected, name))
    if got.name == "gaussian":
        assert got.alpha == pytest.approx(expected.alpha)
    if got.name == "sinc":  # v2 measures both sincs in radii: sinc(tau x / r) sinc(x / r)
        assert (got.sinc_scale, got.window_scale) == pytest.approx((1.0, 0.5))


@pytest.mark.parametrize("line", ['PixelFilter "box" "float xwidth" 0', 'PixelFilter "box" "float xwidth" 20',
                                  'PixelFilter "gaussian" "float ywidth" -1',
                                  'PixelFilter "mitchell" "float xwidth" 1e999', 'PixelFilter "sinc" "float tau" 0',
                                  'PixelFilter "box" "string xwidth" "wide"'])
def test_bad_pixel_filter_parameters_are_one_line_naming_file_and_line(tmp_path, line):
    path = scene_file(tmp_path, "\n\n" + line + "\n")
    with pytest.raises(UserError) as err:
        import_pbrt(path, dialect="v3")
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{path}:3"), message


def test_an_unknown_filter_is_a_warning_and_the_dialect_default(tmp_path):
    imported = import_pbrt(scene_file(tmp_path, 'PixelFilter "catmull-rom"\n'), dialect="v4")
    assert imported.scene.camera.pixel_filter.name == "gaussian"
    assert any(re.search(r"s\.pbrt:1: unsupported: PixelFilter \"catmull-rom\"", w) for w in imported.warnings)


def test_the_filter_option_replaces_the_scenes_at_the_dialect_defaults(tmp_path):
    path = scene_file(tmp_path, 'PixelFilter "box" "float xwidth" 1\n')
    assert rl.load_scene(str(path), pixel_filter="sinc", pbrt_dialect="v2").camera.pixel_filter.sinc_scale == 0.75
    scene = rl.load_scene(str(path), pixel_filter="lanczos", pbrt_dialect="v4")
    assert scene.camera.pixel_filter.describe().startswith("sinc radius 4x4")


def test_mesh_scenes_keep_the_box_unless_asked():
    assert rl.load_scene(None, resolution=(8, 8), spp=1).camera.pixel_filter == PIXEL_BOX
    asked = rl.load_scene(None, resolution=(8, 8), spp=1, pixel_filter="gaussian").camera.pixel_filter
    assert asked.describe() == "gaussian radius 1.5x1.5 alpha 2"


PARAMETER = st.sampled_from(["xwidth", "ywidth", "xradius", "yradius", "alpha", "sigma", "B", "C", "tau"])
NUMBER = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=32), st.sampled_from([0.0, -1.0, 1e-30,
                                                                                                   1e30, 16.0, 16.01]))


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["box", "triangle", "gaussian", "mitchell", "sinc", "lanczos", "x"]),
       params=st.dictionaries(PARAMETER, NUMBER, max_size=4), dialect=st.sampled_from(["v1", "v2", "v3", "v4"]))
def test_any_pixel_filter_parameters_give_a_filter_or_one_line(name, params, dialect):
    text = " ".join(f'"float {key}" {value!r}' for key, value in params.items())
    with tempfile.TemporaryDirectory() as folder:
        path = scene_file(Path(folder), f'PixelFilter "{name}" {text}\n')
        try:
            camera = import_pbrt(path, dialect=dialect).scene.camera
        except UserError as err:
            assert "\n" not in str(err) and str(err).startswith(str(path)), str(err)
            return
        f = camera.pixel_filter
        dx, dy, w = f.offsets(np.array([0.1, 0.5, 0.9], np.float32), np.array([0.3, 0.7, 0.0], np.float32))
        assert np.all(np.isfinite(w)) and np.all(np.abs(dx) <= f.radius_x) and np.all(np.abs(dy) <= f.radius_y)


def test_the_cli_filter_option_is_checked_by_the_same_check():
    from realistic.cli import build_parser
    from realistic.cli.scene_arguments import options_from_args

    args = build_parser().parse_args(["render", "--filter", "lanczos"])
    assert options_from_args(args, None).pixel_filter == "sinc"
    with pytest.raises(UserError, match="unknown pixel filter 'bessel'") as err:
        build_parser().parse_args(["render", "--filter", "bessel"])
    assert "\n" not in str(err.value)


EDGE_SCENE = """LookAt 0 0 0  0 0 1  0 1 0
Camera "perspective" "float fov" 30
Film "image" "integer xresolution" 16 "integer yresolution" 4
WorldBegin
AttributeBegin
AreaLightSource "diffuse" "rgb L" [1 1 1]
Translate 1000.1 0 10
ReverseOrientation
Shape "disk" "float radius" 1000
AttributeEnd
WorldEnd
"""


@pytest.mark.parametrize("name", ["triangle", "gaussian", "sinc"])
def test_a_rendered_step_edge_is_the_filtered_step(tmp_path, name):
    """A pinhole looks at the straight edge of a huge emitter (radiance 1); each column's value is
    the integral of the filter beyond the edge over its whole integral, negative lobes included
    (the render keeps rays of negative weight)."""
    path = tmp_path / "edge.pbrt"
    path.write_text(EDGE_SCENE)
    scene = rl.load_scene(str(path), spp=4096, pbrt_dialect="v3", pixel_filter=name)
    column = rl.render(scene, backend="numpy")[:, :, 0].mean(axis=0)
    # the edge is at x = 0.1 on the plane z = 10: screen x 0.01 / tan(15 deg) of the half-height,
    # the screen window's half-width is 4 (aspect 16:4), raster x = 16 (1 + screen / 4) / 2
    edge = 8 * (1 + 0.01 / math.tan(math.radians(15)) / 4)
    f = scene.camera.pixel_filter
    r = f.radius_x
    total = simpson(f, r)
    for i in range(16):
        lo = edge - (i + 0.5)
        expected = 1.0 if lo <= -r else 0.0 if lo >= r else simpson(f, r, lo=lo) / total
        assert column[i] == pytest.approx(expected, abs=0.02), (i, column[i], expected)


def test_the_pupil_table_bounds_samples_a_wide_filter_puts_beyond_the_film():
    """A sinc of radius 4 puts film points up to 3.5 pixels past the corner pixels; the camera's
    exit-pupil table reaches that far, so no ray those points pass falls outside its boxes (a table
    of the film alone loses some: the test can fail)."""
    from conftest import rays_the_pupil_table_loses
    from realistic.camera.lens_camera import LensCamera
    from realistic.optics.formats import load_lens
    from realistic.optics.sampling import exit_pupil_table

    lens = load_lens("wide")
    camera = dataclasses.replace(LensCamera.looking_at(lens, (0, 0, 0), (0, 0, -5), width=40, height=30, spp=1),
                                 pixel_filter=PixelFilter("sinc", 4.0, 4.0))
    assert camera.sampled_film_diagonal_mm > camera.film_diagonal_mm + 5  # 3.5 px of 1.08 mm on each side
    reach_mm = camera.sampled_film_diagonal_mm / 2
    film_only = exit_pupil_table(lens, camera.film_distance_mm, camera.film_diagonal_mm)
    for table, lost_expected in ((camera.pupil, False), (film_only, True)):
        passed, lost = rays_the_pupil_table_loses(lens, camera.film_distance_mm, table, seed=5,
                                                  film_radius_mm=reach_mm)
        assert passed > 1000 and (lost > 0) == lost_expected
