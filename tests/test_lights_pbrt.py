"""pbrt LightSource and Integrator lines into our lights and integrator, per pbrt version."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from realistic.core.image_files import write_exr
from realistic.errors import UserError
from realistic.renderer.inputs import RenderOptions
from realistic.scene.lights import DistantLight, InfiniteLight, PointLight, SpotLight
from realistic.scene.pbrt.importer import import_pbrt

CAMERA = 'Film "image" "integer xresolution" [8] "integer yresolution" [8]\nCamera "perspective" "float fov" 40\n'


def _import(tmp_path, world: str, version: str = "auto", head: str = ""):
    path = tmp_path / "scene.pbrt"
    path.write_text(head + CAMERA + "WorldBegin\n" + world)
    return import_pbrt(path, dialect=version)


def test_point_light_position_intensity_and_scale_per_version(tmp_path):
    world = 'Translate 1 2 3\nLightSource "point" "rgb I" [1 2 3] "point from" [0 0 1] "{}" {}\n'
    (v3,) = _import(tmp_path, world.format("rgb scale", "[2 2 2]"), "v3").scene.lights
    assert isinstance(v3, PointLight)
    np.testing.assert_allclose(v3.position, [1, 2, 4])
    np.testing.assert_allclose(v3.intensity, [2, 4, 6])
    (v4,) = _import(tmp_path, world.format("float power", "100"), "v4").scene.lights
    np.testing.assert_allclose(v4.intensity, np.array([1, 2, 3]) * 100 / (4 * math.pi))  # pbrt-v4: k_e = 4 pi


@pytest.mark.parametrize("version,kind", [("v3", "quartic"), ("v2", "quartic"), ("v4", "smoothstep")])
def test_spot_light_cone_axis_and_falloff_per_version(tmp_path, version, kind):
    world = ('LightSource "spot" "rgb I" [4 4 4] "point from" [0 0 5] "point to" [0 0 0] '
             '"float coneangle" 30 "float conedeltaangle" 10\n')
    (light,) = _import(tmp_path, world, version).scene.lights
    assert isinstance(light, SpotLight) and light.falloff_kind == kind
    np.testing.assert_allclose(light.position, [0, 0, 5])
    np.testing.assert_allclose(light.light_to_world[:3, 2], [0, 0, -1], atol=1e-12)  # the cone points down
    assert light.cos_total_width == pytest.approx(math.cos(math.radians(30)))
    assert light.cos_falloff_start == pytest.approx(math.cos(math.radians(20)))


def test_distant_light_points_from_to(tmp_path):
    (light,) = _import(tmp_path, 'LightSource "distant" "rgb L" [1 1 1] "point from" [0 0 0] '
                                 '"point to" [1 0 0]\n').scene.lights
    assert isinstance(light, DistantLight)
    np.testing.assert_allclose(light.direction, [-1, 0, 0])  # toward the light: from - to


def test_infinite_lights_constant_and_mapped_per_version(tmp_path):
    image = np.ones((4, 8, 3), np.float32)
    write_exr(tmp_path / "sky.exr", image)
    write_exr(tmp_path / "square.exr", np.ones((64, 64, 3), np.float32))
    (constant,) = _import(tmp_path, 'LightSource "infinite" "rgb L" [.5 .6 .7]\n').scene.lights
    assert isinstance(constant, InfiniteLight) and constant.image is None and constant.radiance == (.5, .6, .7)
    (v3,) = _import(tmp_path, 'LightSource "infinite" "string mapname" "sky.exr"\n', "v3").scene.lights
    assert v3.mapping == "latlong" and v3.image.shape == (4, 8, 3)
    (v4,) = _import(tmp_path, 'LightSource "infinite" "string filename" "square.exr" "float illuminance" 2\n',
                    "v4").scene.lights
    assert v4.mapping == "equal-area"
    # pbrt-v4 sums a map's upper-hemisphere texels' L cos times 2 pi / texels (src/pbrt/lights.cpp); for a
    # white map that tends to 2 pi * (1/2 of the texels) * (mean cos 1/2) / texels = pi / 2
    assert v4.radiance[0] == pytest.approx(2 / (math.pi / 2), rel=0.01)
    with pytest.raises(UserError, match=r"scene.pbrt:\d+: .*square"):
        _import(tmp_path, 'LightSource "infinite" "string filename" "sky.exr"\n', "v4")


def test_unsupported_lights_are_reported_with_file_and_line(tmp_path):
    imported = _import(tmp_path, 'LightSource "goniometric"\nLightSource "projection"\n')
    assert imported.scene.lights == []
    text = "\n".join(imported.warnings)
    assert 'scene.pbrt:4: unsupported: LightSource "goniometric" is not supported' in text
    assert 'scene.pbrt:5: unsupported: LightSource "projection"' in text


@pytest.mark.parametrize("line,expected", [('Integrator "path" "integer maxdepth" 7\n', ("path", 7)),
                                           ('SurfaceIntegrator "directlighting"\n', ("directlighting", 5)),
                                           ('Integrator "volpath" "integer maxdepth" 3\n', ("path", 3)),
                                           # no line: each version's default (v2 directlighting, v3 path)
                                           ('Renderer "sampler"\n', ("directlighting", 5)),
                                           ("", ("path", 5))])
def test_integrator_line(tmp_path, line, expected):
    imported = _import(tmp_path, "", head=line)
    assert (imported.scene.integrator, imported.scene.max_depth) == expected
    if "volpath" in line:
        assert any('Integrator "volpath" (rendered with "path")' in w for w in imported.warnings)


def test_integrator_options_override_and_are_checked(tmp_path):
    with pytest.raises(UserError, match="unknown integrator"):
        RenderOptions(integrator="bdpt")
    with pytest.raises(UserError, match="maximum path depth"):
        RenderOptions(max_depth=-1)


NUMBER = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10).map(float))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(["point", "spot", "distant", "infinite", "goniometric"]),
       version=st.sampled_from(["v2", "v3", "v4"]),
       values=st.lists(NUMBER, min_size=1, max_size=4),
       name=st.sampled_from(["I", "L", "scale", "from", "to", "coneangle", "conedeltaangle", "power",
                             "illuminance"]),
       depth=NUMBER)
def test_light_and_integrator_parameters_import_or_fail_in_one_line(tmp_path, kind, version, values, name, depth):
    numbers = " ".join(repr(v) if math.isfinite(v) else ("1e999" if v > 0 else "-1e999") if not math.isnan(v)
                       else "nan" for v in values)
    world = f'LightSource "{kind}" "float {name}" [{numbers}]\n'
    head = f'Integrator "path" "integer maxdepth" [{depth!r}]\n' if math.isfinite(depth) else ""
    try:
        imported = _import(tmp_path, world, version, head)
    except UserError as err:
        assert "\n" not in str(err) and "scene.pbrt:" in str(err)
        return
    for light in imported.scene.lights:
        assert all(math.isfinite(x) for x in np.ravel(getattr(light, "intensity", getattr(light, "radiance", 0))))
