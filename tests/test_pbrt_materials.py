"""pbrt material types, in v1/v2/v3 and v4 spellings, as scene materials; warnings name file and line."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import shared_file
from realistic.errors import UserError
from realistic.scene.materials import (
    CoatedDiffuse,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Measured,
    Mirror,
    Mix,
    Plastic,
    ScaledTexture,
    Substrate,
)
from realistic.scene.model import CheckerTexture, Material
from realistic.scene.pbrt.importer import import_pbrt, import_world


def _one(tmp_path, body, dialect):
    """The material of the one sphere in a scene whose world is ``body`` (one line per directive)."""
    path = tmp_path / "scene.pbrt"
    path.write_text('Camera "perspective"\nWorldBegin\n' + body + '\nShape "sphere"\nWorldEnd\n')
    scene, parsed, _ = import_world(path, dialect=dialect)
    return scene.instances[-1].material, parsed.warnings, path


def test_matte_and_diffuse(tmp_path):
    m, warnings, _ = _one(tmp_path, 'Material "matte" "rgb Kd" [.1 .2 .3] "float sigma" 20', "v2")
    assert m == Material((0.1, 0.2, 0.3), None, 20.0) and not warnings
    m, _, _ = _one(tmp_path, 'Material "diffuse" "rgb reflectance" [.4 .5 .6]', "v4")
    assert m == Material((0.4, 0.5, 0.6))
    m, _, _ = _one(tmp_path, 'Material "matte"', "v3")
    assert m == Material((0.5, 0.5, 0.5))


@pytest.mark.parametrize("dialect, rule", [("v2", "blinn"), ("v3", "pbrt-v3")])
def test_plastic_per_version(tmp_path, dialect, rule):
    m, warnings, _ = _one(tmp_path, 'Material "plastic" "rgb Kd" [.1 .2 .3] "rgb Ks" [.4 .4 .4] '
                                    '"float roughness" .05', dialect)
    assert m == Plastic((0.1, 0.2, 0.3), (0.4, 0.4, 0.4), 0.05, rule, 1 / 1.5) and not warnings
    m, _, _ = _one(tmp_path, 'Material "plastic" "bool remaproughness" "false"', "v3")
    assert m == Plastic((0.25,) * 3, (0.25,) * 3, 0.1, "alpha", 1 / 1.5)


def test_v4_coateddiffuse_is_a_thin_coat_with_a_warning(tmp_path):
    m, warnings, path = _one(tmp_path, 'Material "coateddiffuse" "rgb reflectance" [.2 .3 .4] "float roughness" .3',
                             "v4")
    assert m == CoatedDiffuse((0.2, 0.3, 0.4), 0.3, "sqrt", 1.5)
    assert any(w.startswith(f'{path}:3: unsupported: Material "coateddiffuse", rendered as a diffuse base') for w in
               warnings)


def test_metal_and_conductor(tmp_path):
    m, warnings, _ = _one(tmp_path, 'Material "metal" "rgb eta" [.2 .9 1.1] "rgb k" [3.9 2.4 2.1] '
                                    '"float roughness" .02', "v2")
    assert m == Conductor((0.2, 0.9, 1.1), (3.9, 2.4, 2.1), 0.02, 0.02, "blinn") and not warnings
    m, _, _ = _one(tmp_path, 'Material "metal" "spectrum eta" [400 1.5 500 1.5 600 1.5 700 1.5] '
                             '"float uroughness" .1 "float vroughness" .2', "v3")
    # pbrt-v3's FromSampled: a flat 1.5 as 1.5 x the unadapted sRGB of E, (1.205, 0.948, 0.909) x 470 / 471
    assert np.allclose(m.eta, 1.5 * np.array([1.205, 0.948, 0.909]) * 470 / 471, rtol=1e-3)
    assert (m.roughness_u, m.roughness_v, m.rule) == (0.1, 0.2, "pbrt-v3")
    m, warnings, path = _one(tmp_path, 'Material "conductor" "spectrum eta" "metal-CuZn-eta" '
                                       '"spectrum k" "metal-CuZn-k"', "v4")
    assert isinstance(m, Conductor) and m.roughness_u == 0.0 and m.rule == "sqrt"
    assert any('named spectrum "metal-CuZn-eta"' in w for w in warnings)
    m, _, _ = _one(tmp_path, 'Material "conductor" "rgb reflectance" [.64 .64 .64] "float roughness" .1', "v4")
    assert m.eta == (1.0, 1.0, 1.0) and np.allclose(m.k, 2 * 0.8 / 0.6)  # k = 2 sqrt(R) / sqrt(1 - R)
    m, warnings, _ = _one(tmp_path, 'Material "coatedconductor" "float conductor.roughness" .2', "v4")
    assert isinstance(m, Conductor) and m.roughness_u == 0.2
    assert any('"coatedconductor", rendered as its conductor' in w for w in warnings)


def test_mirror_glass_dielectric_thin(tmp_path):
    assert _one(tmp_path, 'Material "mirror" "rgb Kr" [.8 .8 .8]', "v2")[0] == Mirror((0.8,) * 3)
    assert _one(tmp_path, 'Material "glass" "float index" 1.33', "v2")[0] == Dielectric(1.33)
    assert _one(tmp_path, 'Material "glass" "float eta" 1.6 "rgb Kt" [.9 .9 1]', "v3")[0] == \
        Dielectric(1.6, (1.0,) * 3, (0.9, 0.9, 1.0))
    assert _one(tmp_path, 'Material "dielectric" "float eta" 1.7', "v4")[0] == Dielectric(1.7)
    assert _one(tmp_path, 'Material "thindielectric"', "v4")[0] == Dielectric(1.5, thin=True)
    m, warnings, _ = _one(tmp_path, 'Material "dielectric" "float roughness" .3', "v4")
    assert m == Dielectric(1.5, roughness_u=0.3, roughness_v=0.3, rule="sqrt") and not warnings


def test_rough_glass_parameters_per_version(tmp_path):
    """pbrt-v3 glass.cpp reads uroughness and vroughness (no roughness); pbrt-v4 DielectricMaterial
    reads roughness as their default; pbrt-v2 glass and pbrt-v4 thindielectric are smooth."""
    m, warnings, _ = _one(tmp_path, 'Material "glass" "float uroughness" .1 "float vroughness" .2', "v3")
    assert m == Dielectric(1.5, roughness_u=0.1, roughness_v=0.2, rule="pbrt-v3") and not warnings
    m, _, _ = _one(tmp_path, 'Material "glass" "float uroughness" .1 "bool remaproughness" "false"', "v3")
    assert m == Dielectric(1.5, roughness_u=0.1, roughness_v=0.0, rule="alpha")
    m, path = _one(tmp_path, 'Material "glass" "float roughness" .3 "bool remaproughness" "true"', "v3")[::2]
    unused = [w for w in import_pbrt(path, dialect="v3").warnings if "not used" in w]
    assert m == Dielectric(1.5) and len(unused) == 1 and '"roughness"' in unused[0]  # remaproughness is read
    m, _, _ = _one(tmp_path, 'Material "dielectric" "float roughness" .3 "float vroughness" .1', "v4")
    assert m == Dielectric(1.5, roughness_u=0.3, roughness_v=0.1, rule="sqrt")
    assert _one(tmp_path, 'Material "thindielectric" "float roughness" .3', "v4")[0] == Dielectric(1.5, thin=True)
    assert _one(tmp_path, 'Material "glass" "float uroughness" .3', "v2")[0] == Dielectric(1.5)


def test_substrate_translucent_diffusetransmission(tmp_path):
    m, _, _ = _one(tmp_path, 'Material "substrate" "rgb Kd" [.5 .4 .3] "rgb Ks" [.1 .1 .1] '
                             '"float uroughness" .2 "float vroughness" .05', "v3")
    assert m == Substrate((0.5, 0.4, 0.3), (0.1,) * 3, 0.2, 0.05, "pbrt-v3")
    m, warnings, _ = _one(tmp_path, 'Material "translucent" "rgb Kd" [.5 .5 .5] "rgb reflect" [.2 .2 .2] '
                                    '"rgb transmit" [.6 .6 .6]', "v2")
    assert m == DiffuseTransmission((0.1,) * 3, (0.3,) * 3) and warnings
    m, _, _ = _one(tmp_path, 'Material "diffusetransmission" "rgb transmittance" [.5 .5 .5] "float scale" 2', "v4")
    assert m == DiffuseTransmission((0.5,) * 3, (1.0,) * 3)


def test_mix_in_each_version_weights_the_right_material(tmp_path):
    named = ('MakeNamedMaterial "a" "string type" "matte" "rgb Kd" [1 0 0]\n'
             'MakeNamedMaterial "b" "string type" "mirror"\n')
    m, _, _ = _one(tmp_path, named + 'Material "mix" "string namedmaterial1" "a" "string namedmaterial2" "b" '
                                     '"float amount" .3', "v3")
    # pbrt-v1/v2/v3: amount weights namedmaterial1 -> (1 - amount) b + amount a
    assert m == Mix(Mirror((0.9,) * 3), Material((1.0, 0.0, 0.0)), 0.3)
    m, _, _ = _one(tmp_path, named + 'Material "mix" "string materials" ["a" "b"] "float amount" .3', "v4")
    # pbrt-v4: amount is the chance of the second
    assert m == Mix(Material((1.0, 0.0, 0.0)), Mirror((0.9,) * 3), 0.3)
    with pytest.raises(UserError, match=r"scene.pbrt:3: .*\"nope\""):
        _one(tmp_path, 'Material "mix" "string materials" ["nope" "b"]', "v4")


def test_measured_reads_the_file_or_names_the_scene_line(tmp_path):
    brdf = shared_file("scenes/pbrt/brdfs/garnet_red.brdf")
    m, warnings, _ = _one(tmp_path, f'Material "measured" "string filename" "{brdf}"', "v2")
    assert m == Measured(str(brdf)) and not warnings
    with pytest.raises(UserError, match=r"scene.pbrt:3: measured BRDF file \"missing.brdf\" not found"):
        _one(tmp_path, 'Material "measured" "string filename" "missing.brdf"', "v2")
    (tmp_path / "bad.merl").write_bytes(b"\x01\x00")
    with pytest.raises(UserError, match=r"scene.pbrt:3: .*bad.merl: MERL BRDF table shorter"):
        _one(tmp_path, 'Material "measured" "string filename" "bad.merl"', "v2")


def test_textures_on_colours_and_roughness_and_bump_maps_warn_once(tmp_path):
    textures = ('Texture "c" "color" "checkerboard" "rgb tex1" [1 1 1] "rgb tex2" [0 0 0]\n'
                'Texture "s" "color" "scale" "texture tex1" "c" "color tex2" [.5 .5 .5]\n'
                'Texture "r" "float" "checkerboard" "float tex1" .1 "float tex2" .3\n')
    m, warnings, path = _one(tmp_path, textures + 'Material "plastic" "texture Kd" "s" "texture Ks" "c" '
                                                  '"texture roughness" "r" "texture bumpmap" "r"\n'
                                                  'Shape "sphere"\nMaterial "substrate" "texture bumpmap" "r"', "v3")
    first = _one(tmp_path, textures + 'Material "plastic" "texture Kd" "s" "texture Ks" "c" "texture roughness" "r"',
                 "v3")[0]
    assert isinstance(first.diffuse, ScaledTexture) and first.diffuse.scale == (0.5, 0.5, 0.5)
    assert isinstance(first.specular, CheckerTexture) and isinstance(first.roughness, CheckerTexture)
    bumps = [w for w in warnings if '"bumpmap"' in w]
    assert len(bumps) == 2 and bumps[0].startswith(f"{path}:6:")  # once per material type and line


@pytest.mark.parametrize("kind, dialect", [("hair", "v4"), ("kdsubsurface", "v2"), ("fourier", "v3"),
                                           ("uber", "v3"), ("interface", "v4"), ("shinymetal", "v1")])
def test_types_without_an_exact_counterpart_warn_with_file_and_line(tmp_path, kind, dialect):
    m, warnings, path = _one(tmp_path, f'Material "{kind}"', dialect)
    assert any(w.startswith(f'{path}:3: unsupported: Material "{kind}"') for w in warnings) or kind == "shinymetal"
    expected = {"interface": Dielectric, "uber": Plastic, "shinymetal": Conductor}.get(kind, Material)
    assert isinstance(m, expected)


def test_a_scene_of_every_material_renders(tmp_path):
    """Until the integrator shades through BSDFs it renders each material's matte equivalent; either
    way every material type must import and render to finite pixels."""
    from realistic.renderer.inputs import RenderOptions, build_render_inputs
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import render

    brdf = shared_file("scenes/pbrt/brdfs/acryl_blue.brdf")
    kinds = ['"matte" "float sigma" 10', '"plastic"', '"metal"', '"mirror"', '"glass"', '"substrate"',
             '"translucent"', f'"measured" "string filename" "{brdf}"', '"uber"']
    shapes = "".join(f'AttributeBegin\nMaterial {k}\nTranslate {i - 4} 0 0\nShape "sphere" "float radius" .4\n'
                     f"AttributeEnd\n" for i, k in enumerate(kinds))
    path = tmp_path / "all.pbrt"
    path.write_text('Film "image" "integer xresolution" 16 "integer yresolution" 8\nLookAt 0 0 -8 0 0 0 0 1 0\n'
                    'Camera "perspective" "float fov" 70\nWorldBegin\nAttributeBegin\nAreaLightSource "area" '
                    '"rgb L" [4 4 4]\nTranslate 0 5 0\nRotate 90 1 0 0\nShape "disk" "float radius" 3\nAttributeEnd\n'
                    'MakeNamedMaterial "m" "string type" "matte"\n' + shapes + "WorldEnd\n")
    imported = build_render_inputs(RenderOptions(scene=path, spp=1))
    image = render(RenderJob(imported.scene, (imported.camera,), "numpy"))[0].image
    assert np.all(np.isfinite(image)) and image.max() > 0


def test_copper_is_pbrts_tabulated_copper_and_the_default_metal(tmp_path):
    from realistic.scene.metals import COPPER_K, COPPER_N, COPPER_NM, copper

    eta, k = copper()
    # RGB of a spectrum lies within its range where the colour matching functions are positive-ish:
    # copper's index falls from about 1.2 (blue) to 0.2 (red); k rises from about 2.1 to 4.
    assert eta[2] > eta[1] > eta[0] and 0 < eta[0] < 0.4 and 1.0 < eta[2] < 1.3
    assert k[0] > k[1] > k[2] and min(COPPER_K) < k[2] and k[0] < max(COPPER_K)
    assert min(COPPER_N) < eta[1] < max(COPPER_N)
    m, warnings, _ = _one(tmp_path, 'Material "conductor" "spectrum eta" "metal-Cu-eta" "spectrum k" "metal-Cu-k"',
                          "v4")
    assert (m.eta, m.k) == (eta, k) == (Conductor().eta, Conductor().k) and not warnings
    # pbrt-v3 metal.cpp makes its default by Spectrum::FromSampled of the same tables: as a file writing them
    pairs = " ".join(f"{w} {v}" for w, v in zip(COPPER_NM, COPPER_N))
    kpairs = " ".join(f"{w} {v}" for w, v in zip(COPPER_NM, COPPER_K))
    written, _, _ = _one(tmp_path, f'Material "metal" "spectrum eta" [{pairs}] "spectrum k" [{kpairs}]', "v3")
    default = _one(tmp_path, 'Material "metal"', "v3")[0]
    assert np.allclose(default.eta, written.eta, rtol=1e-12) and np.allclose(default.k, written.k, rtol=1e-12)
    assert default.eta != eta and (default.roughness_u, default.rule) == (0.01, "pbrt-v3")


def test_uber_coat_index_per_version(tmp_path):
    assert _one(tmp_path, 'Material "uber" "float eta" 1.33', "v3")[0].eta == 1.33  # FresnelDielectric(1, eta)
    assert _one(tmp_path, 'Material "uber"', "v2")[0].eta == pytest.approx(1 / 1.5)  # FresnelDielectric(1.5, 1)


_TYPES = ["matte", "diffuse", "plastic", "uber", "coateddiffuse", "metal", "conductor", "coatedconductor", "mirror",
          "glass", "dielectric", "thindielectric", "substrate", "translucent", "diffusetransmission", "mix",
          "measured", "hair", "interface", "shinymetal"]
_PARAMS = ['"float roughness"', '"float uroughness"', '"float sigma"', '"float eta"', '"float index"',
           '"rgb Kd"', '"rgb Ks"', '"rgb Kr"', '"rgb eta"', '"rgb k"', '"rgb reflectance"', '"float amount"',
           '"spectrum eta"', '"string filename"', '"bool remaproughness"', '"string namedmaterial1"',
           '"texture Kd"', '"texture roughness"', '"float scale"']
_VALUES = ["[-1]", "[0]", "[1e30]", "[.5 .5 .5]", "[1 2]", '"a"', '"true"', "[400 1 500]", "[-5 -5 -5]", '"x.brdf"',
           "[]", '"t"']


@given(st.sampled_from(_TYPES), st.lists(st.tuples(st.sampled_from(_PARAMS), st.sampled_from(_VALUES)), max_size=4),
       st.sampled_from(["v2", "v3", "v4"]))
def test_any_material_line_imports_or_fails_with_one_line_naming_it(tmp_path_factory, kind, params, dialect):
    folder = tmp_path_factory.mktemp("fuzz")
    body = ('Texture "t" "float" "checkerboard"\nMakeNamedMaterial "a" "string type" "matte"\n'
            f'Material "{kind}" ' + " ".join(f"{name} {value}" for name, value in params))
    try:
        _one(folder, body, dialect)
    except UserError as err:
        assert "\n" not in str(err) and f"{folder / 'scene.pbrt'}:" in str(err)
