"""Fresnel transmission and the quarter-wave MgF2 coating (realistic.optics.coating) against closed
forms, and what it does to a lens's transmission and T-stop."""

import numpy as np
import pytest

from realistic import load_lens
from realistic.errors import UserError
from realistic.optics.coating import (
    BARE,
    DESIGN_WAVELENGTH_NM,
    IDEAL,
    LAYER,
    MGF2_INDEX,
    mgf2_index,
    reflect_transmit,
    reflectance,
    transmittance,
)
from realistic.optics.forward_trace import reversed_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data
from realistic.optics.report import on_axis_transmittance, t_stop
from realistic.optics.tracer import trace_from_film

COSINES = np.linspace(0.0, 1.0, 41)[1:]


@pytest.mark.parametrize(("n1", "n2"), [(1.0, 1.52), (1.52, 1.0), (1.0, 1.9), (1.62, 1.5)])
def test_bare_normal_incidence_is_the_closed_form(n1, n2):
    assert reflectance(BARE, n1, n2, 1.0, 550.0) == pytest.approx(((n1 - n2) / (n1 + n2)) ** 2, rel=1e-14)


@pytest.mark.parametrize(("n1", "n2"), [(1.0, 1.5), (1.5, 1.0), (1.0, 1.8)])
def test_rp_vanishes_at_brewsters_angle(n1, n2):
    theta = np.arctan(n2 / n1)
    rs, rp, _, _ = reflect_transmit(BARE, n1, n2, np.cos(theta), 550.0)
    assert rp == pytest.approx(0.0, abs=1e-28) and rs > 0.01


@pytest.mark.parametrize("model", [BARE, LAYER])
@pytest.mark.parametrize(("n1", "n2"), [(1.0, 1.52), (1.52, 1.0), (1.0, 1.9), (1.9, 1.0), (1.5, 1.6), (1.6, 1.5)])
def test_reflected_and_transmitted_light_sum_to_one(model, n1, n2):
    """R and T come from their own amplitudes (t, with the flux factor n2 cos2 / n1 cos1), so the sum
    checks both; past the critical angle everything is reflected."""
    wavelength = np.array([380.0, 450.0, 550.0, 650.0, 780.0])[:, None]
    rs, rp, ts, tp = reflect_transmit(model, n1, n2, COSINES, wavelength)
    np.testing.assert_allclose(rs + ts, 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(rp + tp, 1.0, rtol=0, atol=1e-13)
    assert np.all((rs >= 0) & (rp >= 0) & (ts >= 0) & (tp >= 0))


def test_ideal_transmits_everything():
    assert np.all(transmittance(IDEAL, 1.0, 1.7, COSINES, 550.0) == 1.0)


def test_quarter_wave_layer_of_index_sqrt_n_glass_cancels_reflection(monkeypatch):
    """A quarter-wave layer of index sqrt(n_glass) reflects nothing at its design wavelength, at normal
    incidence, from either side."""
    import realistic.optics.coating as coating

    monkeypatch.setattr(coating, "MGF2_INDEX", np.sqrt(1.9044))
    monkeypatch.setattr(coating, "mgf2_index", lambda wavelength_nm: np.full_like(wavelength_nm, np.sqrt(1.9044)))
    for n0, n2 in ((1.0, 1.9044), (1.9044, 1.0)):
        assert coating.reflectance(LAYER, n0, n2, 1.0, coating.DESIGN_WAVELENGTH_NM) == pytest.approx(0, abs=1e-30)


def test_mgf2_on_crown_is_the_closed_form_at_its_design_wavelength():
    """((n0 n_g - n1^2) / (n0 n_g + n1^2))^2: about 1.24 % for n_g = 1.52, from 4.26 % bare."""
    closed = ((1.52 - MGF2_INDEX**2) / (1.52 + MGF2_INDEX**2)) ** 2
    assert reflectance(LAYER, 1.0, 1.52, 1.0, 550.0) == pytest.approx(closed, rel=1e-13)
    assert closed == pytest.approx(0.0124, abs=1e-4)
    away = reflectance(LAYER, 1.0, 1.52, 1.0, np.array([400.0, 700.0]))
    assert np.all(away > closed) and np.all(away < reflectance(BARE, 1.0, 1.52, 1.0, 550.0))


def test_mgf2_is_dispersive_as_dodge_measured_it():
    """The ordinary index of Dodge's (1984) Sellmeier fit: 1.3785 at 550 nm, falling with lambda."""
    assert 1.378 <= mgf2_index(550.0) <= 1.380
    assert MGF2_INDEX == mgf2_index(DESIGN_WAVELENGTH_NM)
    assert mgf2_index(450.0) > mgf2_index(550.0) > mgf2_index(650.0)


def test_the_coated_reflectance_minimum_stays_near_the_design_wavelength():
    """The layer is a quarter wave at 550 nm whatever its dispersion (its thickness is lambda0 / (4 n(lambda0)));
    the minimum of R moves a few nm longer only as the lower index there matches the glass better."""
    wavelengths = np.arange(450.0, 650.0, 0.25)
    for glass in (1.52, 1.7):
        r = reflectance(LAYER, 1.0, glass, 1.0, wavelengths)
        assert abs(wavelengths[np.argmin(r)] - DESIGN_WAVELENGTH_NM) < 10.0
        closed = ((glass - MGF2_INDEX**2) / (glass + MGF2_INDEX**2)) ** 2
        assert reflectance(LAYER, 1.0, glass, 1.0, DESIGN_WAVELENGTH_NM) == pytest.approx(closed, rel=1e-13)


def test_a_layer_is_a_half_wave_at_half_the_design_wavelength():
    """Where the layer is a half wave thick, lambda = 2 n(lambda) d (near lambda0 / 2, moved by the dispersion),
    it is absent (Born and Wolf 1.6.4): R is the bare one."""
    half = DESIGN_WAVELENGTH_NM / 2
    for _ in range(50):  # the fixed point of lambda = 2 n(lambda) lambda0 / (4 n(lambda0))
        half = float(mgf2_index(half)) * DESIGN_WAVELENGTH_NM / (2 * MGF2_INDEX)
    assert 276 < half < 282
    assert reflectance(LAYER, 1.0, 1.52, 1.0, half) == pytest.approx(reflectance(BARE, 1.0, 1.52, 1.0, half))


def _axial_transmittance(lens) -> float:
    film = 50.0
    return float(trace_from_film(lens, film, np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]])
                                 ).transmittance[0])


def _singlet(coating: str) -> LensSystem:
    """A biconvex N-BK7-like singlet (n_d 1.5168) behind a flat stop in air."""
    return LensSystem("singlet", np.array([0.0, 50.0, -50.0]), np.array([5.0, 5.0, 45.0]),
                      np.array([1.0, 1.5168, 1.0]), np.zeros(3), np.array([10.0, 20.0, 20.0]), 0
                      ).with_coating(coating)


@pytest.mark.parametrize("name", ["dgauss", "tessar.100mm", "canon-rf50-f1.2"])
def test_on_axis_each_interface_multiplies_by_one_minus_r(name):
    """On axis (normal incidence everywhere) the bare lens transmits the product of (1 - R_k),
    R_k = ((n - n') / (n + n'))^2 at each interface, cemented ones included."""
    lens = load_lens(name).with_coating("none")
    front = np.concatenate([[1.0], lens.index_d[:-1]])
    expected = np.prod(1 - ((lens.index_d - front) / (lens.index_d + front)) ** 2)
    assert _axial_transmittance(lens) == pytest.approx(expected, rel=1e-12)


def test_a_many_element_lens_bare_transmits_less_than_a_singlet():
    """The singlet keeps (1 - R)^2; the double Gauss, many more glass-air faces, much less."""
    r = ((1.5168 - 1) / (1.5168 + 1)) ** 2
    assert _axial_transmittance(_singlet("none")) == pytest.approx((1 - r) ** 2, rel=1e-12)
    assert _axial_transmittance(load_lens("dgauss").with_coating("none")) < (1 - r) ** 8
    assert _axial_transmittance(_singlet("ideal")) == 1.0


def test_more_surfaces_transmit_less_and_coatings_recover_most_of_it():
    dgauss = load_lens("dgauss")
    bare, coated, ideal = (_axial_transmittance(dgauss.with_coating(c)) for c in ("none", "mgf2", "ideal"))
    assert ideal == 1.0 and bare < coated < 1.0
    glass_air = int(np.sum((dgauss.index_d == 1.0) != (np.concatenate([[1.0], dgauss.index_d[:-1]]) == 1.0)))
    assert bare < (1 - 0.04) ** glass_air  # each glass-air face reflects over 4 % (n > 1.5)


def test_t_stop_is_the_f_number_over_the_root_of_the_transmittance():
    lens = load_lens("dgauss").with_coating("none")
    t = on_axis_transmittance(lens)
    assert t == pytest.approx(_axial_transmittance(lens), rel=1e-9)
    assert t_stop(lens) == pytest.approx(paraxial_data(lens).f_number / np.sqrt(t), rel=1e-12)
    assert t_stop(lens.with_coating("ideal")) == pytest.approx(paraxial_data(lens).f_number, rel=1e-12)


def test_coating_names_and_counts_are_checked():
    lens = load_lens("dgauss")
    with pytest.raises(UserError, match="unknown coating 'gold'"):
        lens.with_coating("gold")
    with pytest.raises(UserError, match="coatings given"):
        lens.with_coating(("none", "mgf2"))
    per_surface = lens.with_coating(("mgf2",) + ("none",) * (lens.surface_count - 1))
    assert per_surface.coating[0] == "mgf2" and per_surface.interface_models[0] == LAYER


def test_render_options_carry_the_coating_to_the_lens_and_check_its_name():
    from realistic.cli import build_parser
    from realistic.cli.scene_arguments import options_from_args
    from realistic.renderer.inputs import RenderOptions, build_render_inputs

    with pytest.raises(UserError, match="unknown coating 'gold'"):
        RenderOptions(coating="gold")
    args = build_parser().parse_args(["render", "--coating", "mgf2", "--res", "8x6"])
    options = options_from_args(args, 1)
    assert options.coating == "mgf2"
    camera = build_render_inputs(options).camera
    assert set(camera.lens.coating) == {"mgf2"} and camera.metadata()["coating"] == "mgf2"
    assert set(build_render_inputs(RenderOptions(resolution=(8, 6), spp=1)).camera.lens.coating) == {"ideal"}


def test_the_image_centre_dims_by_the_on_axis_transmittance():
    """Rays near the axis meet every surface almost normally: the centre pixels of the bare double
    Gauss's rays carry the on-axis transmittance of the weight of the ideal lens's same rays."""
    from realistic.camera.base import SampleBlock
    from realistic.camera.lens_camera import LensCamera

    lens = load_lens("dgauss")
    camera = LensCamera(lens, 60.0, 1.0, 3, 3, spp=4000)
    block = SampleBlock(4 * 4000, 4000, 4000)  # the centre pixel, 0.33 mm wide
    ideal = camera.generate_rays(block)
    bare = camera.with_coating("none").generate_rays(block)
    ratio = bare.weight.sum() / ideal.weight.sum()
    axial = on_axis_transmittance(lens.with_coating("none"))
    assert axial * 0.97 < ratio < axial  # obliquity only adds loss (stop-size rays at f/2: a few %)


def test_ideal_leaves_the_reference_weight_untouched():
    """Under ``ideal`` (the default) every ray's transmittance is exactly 1, the factor the reference's
    weight takes: its weights, and so its images, are the ones from before coatings, bit for bit."""
    lens = load_lens("dgauss")
    slope = np.linspace(-0.3, 0.3, 201)
    directions = np.column_stack([slope, 0.5 * slope, np.ones_like(slope)])
    traced = trace_from_film(lens, 60.0, np.zeros((201, 3)), directions, np.linspace(380.0, 780.0, 201))
    assert np.count_nonzero(traced.passed) > 20 and np.all(traced.transmittance == 1.0)
    assert np.all(trace_from_film(lens.with_coating("none"), 60.0, np.zeros((201, 3)), directions
                                  ).transmittance[traced.passed] < 1.0)


def test_a_lens_seen_from_the_film_keeps_each_surface_s_coating():
    """reversed_lens (forward traces from the object side) reverses the coatings with the surfaces,
    so every interface keeps its own model: bare where it was bare, coated where it was coated."""
    lens = load_lens("dgauss")
    names = ["mgf2" if i % 3 == 0 else "none" if i % 3 == 1 else "ideal" for i in range(lens.surface_count)]
    coated = lens.with_coating(names)
    back = reversed_lens(coated)
    assert back.coating == tuple(names[::-1])
    np.testing.assert_array_equal(back.interface_models, coated.interface_models[::-1])
    assert set(coated.interface_models) == {IDEAL, BARE, LAYER}
