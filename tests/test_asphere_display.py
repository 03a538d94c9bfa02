"""Aspheres as ``lens plot`` draws them and ``lens info`` lists them.

The sag is recomputed here term by term from the even-asphere formula (powers of r, no Horner
scheme), independently of ``realistic.optics.asphere``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from realistic import load_lens
from realistic.cli import main
from realistic.optics.drawing import plot_cross_section, surface_profile
from realistic.optics.paraxial import film_distance_for_focus
from realistic.optics.report import format_summary, lens_summary

ASPHERIC = ["phone-us10101561", "canon-ef24-f1.4", "canon-rf50-f1.2"]


def _sag_by_terms(r: np.ndarray, radius: float, conic: float, coefficients: np.ndarray) -> np.ndarray:
    c = 1.0 / radius
    sag = c * r**2 / (1.0 + np.sqrt(1.0 - (1.0 + conic) * c**2 * r**2))
    for power, a in zip(range(4, 22, 2), coefficients):
        sag = sag + a * r**power
    return sag


@pytest.mark.parametrize("name", ASPHERIC)
def test_profile_of_an_asphere_is_its_vertex_less_its_sag(name):
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 2000.0)
    vertex_z = lens.vertex_z_mm(film)
    for i in np.flatnonzero(lens.aspheric):
        r = np.linspace(-lens.aperture_mm[i] / 2, lens.aperture_mm[i] / 2, 13)
        expected = vertex_z[i] - _sag_by_terms(r, lens.radius_mm[i], lens.conic[i], lens.aspheric_coefficients[i])
        np.testing.assert_allclose(surface_profile(lens, film, i, r), expected, rtol=0, atol=1e-9)
        # the asphere departs visibly (> 1 um) from its base sphere where that is defined: the test can fail
        with np.errstate(invalid="ignore"):
            sphere = vertex_z[i] - _sag_by_terms(r, lens.radius_mm[i], 0.0, np.zeros(9))
        assert np.nanmax(np.abs(expected - sphere)) > 1e-3


def test_the_drawn_curve_of_each_asphere_follows_its_sag(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    lens = load_lens("phone-us10101561")
    film = film_distance_for_focus(lens, 2000.0)
    plot_cross_section(lens, film, tmp_path / "phone.png")
    assert (tmp_path / "phone.png").stat().st_size > 0
    curves = [line.get_data() for line in figures[0].axes[0].get_lines()]
    vertex_z = lens.vertex_z_mm(film)
    for i in np.flatnonzero(lens.aspheric):
        half = lens.aperture_mm[i] / 2
        drawn = [(z, h) for z, h in curves if len(h) > 2 and np.isclose(np.max(h), half) and np.allclose(
            z, vertex_z[i] - _sag_by_terms(np.asarray(h), lens.radius_mm[i], lens.conic[i],
                                           lens.aspheric_coefficients[i]), atol=1e-9)]
        assert drawn, f"surface {i}: no drawn curve follows the sag"


@pytest.mark.parametrize("name", ASPHERIC)
def test_info_lists_conic_and_coefficients_of_each_asphere(name):
    lens = load_lens(name)
    summary = lens_summary(lens)
    text = format_summary(summary)
    for i, surface in enumerate(summary["surfaces"]):
        if not lens.aspheric[i]:
            assert "conic" not in surface and "aspheric_coefficients" not in surface
            continue
        assert surface["conic"] == lens.conic[i]
        stated = {p: a for p, a in zip(range(4, 22, 2), lens.aspheric_coefficients[i]) if a != 0}
        assert surface["aspheric_coefficients"] == {f"A{p}": a for p, a in stated.items()}
        row = next(line for line in text.splitlines() if line.startswith(f"{i:3d}  conic k"))
        fields = row.split()
        assert float(fields[3]) == pytest.approx(lens.conic[i], rel=1e-5)
        listed = {int(k[1:]): float(v) for k, v in zip(fields[4::2], fields[5::2])}
        assert listed.keys() == stated.keys()
        for p, a in stated.items():
            assert listed[p] == pytest.approx(a, rel=1e-6)


def test_info_json_carries_the_conic(capsys):
    lens = load_lens("phone-us10101561")
    assert main(["lens", "info", "phone-us10101561", "--json"]) in (0, None)
    surfaces = json.loads(capsys.readouterr().out)["surfaces"]
    assert [s.get("conic") for s in surfaces] == [float(k) if a else None for k, a in zip(lens.conic, lens.aspheric)]
