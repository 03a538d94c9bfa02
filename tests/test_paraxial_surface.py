"""Paraxial (ideal thin lens) surfaces: Zemax's PARAXIAL and PARAXIAL_XY traced by the float64 tracer
and the kernel, their first-order data, formats and drawing, against the closed forms of an ideal lens."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from kernel_reference import assert_kernel_matches, camera_for_lens
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.psf import fft_point_spread
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.errors import LensFileError, UserError
from realistic.optics.drawing import plot_cross_section
from realistic.optics.formats import load_lens
from realistic.optics.formats.codev import format_codev
from realistic.optics.formats.json_lens import format_json_lens, parse_json_lens
from realistic.optics.formats.pbrt_dat import format_prescription
from realistic.optics.formats.zemax import format_zmx, parse_zmx
from realistic.optics.forward_trace import reversed_lens
from realistic.optics.paraxial import paraxial_data
from realistic.optics.tracer import trace_from_film
from realistic.optics.wavefront import wavefront
from realistic.renderer.backends import backend_for

F_MM = 50.0


def zmx(*surfaces: str) -> str:
    """A Zemax file: object at infinity, ``surfaces`` (each a block of keyword lines), a flat image."""
    blocks = ["MODE SEQ", "UNIT MM", "SURF 0", "  TYPE STANDARD", "  CURV 0", "  DISZ INFINITY"]
    for k, body in enumerate(surfaces, start=1):
        blocks += [f"SURF {k}", *("  " + line for line in body.strip().splitlines())]
    blocks += [f"SURF {len(surfaces) + 1}", "  TYPE STANDARD", "  CURV 0", "  DISZ 0", "  DIAM 40"]
    return "\n".join(blocks) + "\n"


def single(focal_mm: float = F_MM, semi_mm: float = 10.0) -> str:
    return zmx(f"STOP\nTYPE PARAXIAL\nCURV 0\nPARM 1 {focal_mm}\nPARM 2 1\nDISZ {focal_mm}\nDIAM {semi_mm}")


def test_a_paraxial_surface_focuses_every_field_angle_at_its_focal_length() -> None:
    lens = parse_zmx(single())
    reverse = reversed_lens(lens)  # scene side first as the tracer's film side: rays travel scene to film
    gap = 10.0
    grid = np.linspace(-9.5, 9.5, 9)
    x, y = (a.ravel() for a in np.meshgrid(grid, grid))
    inside = x * x + y * y < 9.9 ** 2
    x, y = x[inside], y[inside]
    for field_deg in (0.0, 5.0, 10.0, 20.0, 30.0, 40.0):
        t = math.tan(math.radians(field_deg))
        direction = np.array([0.0, t, 1.0]) / math.hypot(t, 1.0)
        origins = np.column_stack([x, y - t * gap, np.zeros_like(x)])  # each aimed at (x, y) on the lens
        traced = trace_from_film(reverse, gap, origins, np.broadcast_to(direction, origins.shape))
        assert traced.passed.all()
        image_z = gap + F_MM
        o, d = traced.origin, traced.direction
        landing = o[:, :2] + d[:, :2] / d[:, 2:] * (image_z - o[:, 2:])
        np.testing.assert_allclose(landing[:, 0], 0.0, atol=1e-12)
        np.testing.assert_allclose(landing[:, 1], F_MM * t, rtol=0, atol=1e-12)


def test_rays_from_a_film_point_at_the_focal_plane_leave_parallel() -> None:
    lens = parse_zmx(single())
    for height in (0.0, 3.0, 12.0):
        angles = np.linspace(-0.15, 0.15, 7)
        a, b = (v.ravel() for v in np.meshgrid(angles, angles))
        directions = np.column_stack([a, b, np.ones_like(a)])
        origins = np.broadcast_to([height, -0.5 * height, 0.0], directions.shape)
        traced = trace_from_film(lens, F_MM, origins, directions)
        expected = np.array([-height, 0.5 * height, F_MM])
        np.testing.assert_allclose(traced.direction[traced.passed], np.broadcast_to(
            expected / np.linalg.norm(expected), (int(traced.passed.sum()), 3)), rtol=0, atol=1e-14)


def test_paraxial_efl_is_the_focal_length_and_a_pair_obeys_the_thin_lens_sum() -> None:
    assert paraxial_data(parse_zmx(single(80.0))).efl_mm == pytest.approx(80.0, rel=1e-14)
    f1, f2, d = 60.0, -120.0, 15.0
    pair = parse_zmx(zmx("STOP\nCURV 0\nDISZ 0\nDIAM 8", f"TYPE PARAXIAL\nPARM 1 {f1}\nDISZ {d}\nDIAM 10",
                         f"TYPE PARAXIAL\nPARM 1 {f2}\nDISZ 60\nDIAM 10"))
    expected = 1 / (1 / f1 + 1 / f2 - d / (f1 * f2))
    data = paraxial_data(pair)
    assert data.efl_mm == pytest.approx(expected, rel=1e-13)
    assert data.bfl_mm == pytest.approx(expected * (1 - d / f1), rel=1e-13)  # BFL = f (1 - d / f1)
    # real rays parallel to the axis cross it at the back focal distance behind the second lens
    heights = np.linspace(0.5, 7.5, 8)
    reverse = reversed_lens(pair)
    traced = trace_from_film(reverse, 1.0, np.column_stack([heights, 0 * heights, 0 * heights]),
                             np.broadcast_to([0.0, 0.0, 1.0], (8, 3)))
    o, dd = traced.origin, traced.direction
    crossing = o[:, 2] - o[:, 0] * dd[:, 2] / dd[:, 0]
    np.testing.assert_allclose(crossing - (1.0 + d), data.bfl_mm, rtol=1e-12)


def test_paraxial_xy_has_its_two_powers_apart() -> None:
    lens = parse_zmx(zmx("STOP\nTYPE PARAXIAL_XY\nPARM 1 0.02\nPARM 2 0.04\nDISZ 25\nDIAM 10"))
    np.testing.assert_array_equal(lens.paraxial_power_per_mm[0], [0.02, 0.04])
    assert paraxial_data(lens).efl_mm == pytest.approx(25.0)  # the meridional (y) power
    reverse = reversed_lens(lens)
    start = np.array([[4.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
    traced = trace_from_film(reverse, 1.0, start, np.broadcast_to([0.0, 0.0, 1.0], (2, 3)))
    slopes = traced.direction[:, :2] / traced.direction[:, 2:]
    np.testing.assert_allclose(slopes, [[-4.0 / 50.0, 0.0], [0.0, -4.0 / 25.0]], atol=1e-15)


def test_bad_paraxial_surfaces_name_their_line() -> None:
    with pytest.raises(LensFileError, match=r":11: a PARAXIAL surface needs a finite, non-zero focal length"):
        parse_zmx(single(0.0))
    with pytest.raises(LensFileError, match="a paraxial surface is a plane"):
        parse_zmx(zmx("STOP\nTYPE PARAXIAL\nCURV 0.01\nPARM 1 50\nDISZ 50\nDIAM 5"))
    with pytest.raises(LensFileError, match="a paraxial surface needs air on both sides"):
        parse_zmx(zmx("STOP\nTYPE PARAXIAL\nPARM 1 50\nDISZ 2\nGLAS ___BLANK 1 0 1.5 60\nDIAM 5",
                      "CURV -0.01\nDISZ 50\nDIAM 5"))
    with pytest.raises(LensFileError, match=r":12: TYPE COORDBRK: coordinate breaks"):
        parse_zmx(zmx("STOP\nDISZ 1\nDIAM 5", "TYPE COORDBRK\nDISZ 0", "TYPE PARAXIAL\nPARM 1 50\nDISZ 50\nDIAM 5"))


def test_zemax_and_json_round_trip_a_paraxial_surface() -> None:
    lens = parse_zmx(zmx("STOP\nCURV 0\nDISZ 2\nDIAM 8", "TYPE PARAXIAL\nPARM 1 40\nDISZ 5\nDIAM 10",
                         "TYPE PARAXIAL_XY\nPARM 1 0\nPARM 2 0.01\nDISZ 30\nDIAM 10"))
    for text, parse in ((format_zmx(lens), parse_zmx), (format_json_lens(lens), parse_json_lens)):
        again = parse(text)
        np.testing.assert_allclose(again.paraxial_power_per_mm, lens.paraxial_power_per_mm, rtol=1e-15)
        assert again.stop == lens.stop and np.all(np.isinf(again.radius_mm[1:]))
    surfaces = json.loads(format_json_lens(lens))["surfaces"]
    assert [s.get("focal_length_mm") for s in surfaces] == [None, 40.0, [None, 100.0]]


@pytest.mark.usefixtures("opencl_platform")
def test_kernel_matches_the_tracer_and_focuses_a_paraxial_lens(tmp_path) -> None:
    path = tmp_path / "ideal.zmx"
    path.write_text(single(F_MM, 12.0))
    lens = load_lens(str(path))
    camera = camera_for_lens(lens)
    seed = 5
    block = SampleBlock(0, camera.sample_count, camera.spp)
    kernel = backend_for("opencl").ray_generator(camera, seed)(block)
    assert_kernel_matches(kernel, camera.generate_rays(block, seed), camera, seed)
    # at the focal plane every ray leaves with slope -(film point) / f: the film point lies in its pixel
    focused = LensCamera(lens, F_MM, 43.27, 32, 24, spp=8)
    rays = backend_for("opencl").ray_generator(focused, seed)(SampleBlock(0, focused.sample_count, focused.spp))
    lit = rays.weight > 0
    assert lit.mean() > 0.5
    film = -F_MM * rays.direction[lit, :2] / rays.direction[lit, 2:]
    width, height = focused.film_size_mm
    column, row = rays.pixel[lit] % focused.width, rays.pixel[lit] // focused.width
    # the kernel's film point: x = -((column + 0.5 + jitter) / W - 0.5) w, y = ((row + 0.5 + jitter) / H - 0.5) h
    centre = np.column_stack([-((column + 0.5) / focused.width - 0.5) * width,
                              ((row + 0.5) / focused.height - 0.5) * height])
    half_pixel = np.array([width / focused.width, height / focused.height]) / 2
    assert np.all(np.abs(film - centre) <= half_pixel + 1e-4)


def test_a_paraxial_lens_draws(tmp_path) -> None:
    lens = parse_zmx(single())
    plot_cross_section(lens, F_MM, tmp_path / "ideal.png")
    assert (tmp_path / "ideal.png").stat().st_size > 0


def test_an_ideal_lens_has_a_flat_wavefront_at_every_field_and_distance() -> None:
    lens = parse_zmx(single())
    for field_deg in (0.0, 10.0, 25.0, 40.0):
        front = wavefront(lens, field_deg, 587.5618, F_MM, samples_across=32)
        assert front.rms_waves < 1e-9
        assert front.reference_mm[1] == pytest.approx(-F_MM * math.tan(math.radians(field_deg)), abs=1e-9)
    for distance_mm in (300.0, 1e4):  # a point a in front of the lens, the film at its image: 1/b = 1/f - 1/a
        film = 1 / (1 / F_MM - 1 / distance_mm)
        for field_deg in (0.0, 10.0):
            front = wavefront(lens, field_deg, 587.5618, film, 32, object_distance_mm=distance_mm)
            assert front.rms_waves < 1e-8
            spread = fft_point_spread(lens, distance_mm + film, field_deg, pixel_mm=0.0005, size=16)
            assert spread.strehl == pytest.approx(1.0, abs=1e-9)


def test_a_zmx_with_a_paraxial_surface_renders(tmp_path, capsys) -> None:
    path = tmp_path / "ideal.zmx"
    path.write_text(single(F_MM, 6.0))
    out = tmp_path / "ideal.exr"
    status = main(["render", "scenes/default.pbrt", "--lens", str(path), "--backend", "numpy", "--res", "24x16",
                   "--spp", "2", "--out", str(out)])
    assert status == 0, capsys.readouterr().err
    image, header = read_exr(out)
    assert np.isfinite(image).all() and (image > 0).mean() > 0.5
    assert header["lens"] == "ideal"


def test_formats_without_paraxial_surfaces_refuse_to_write_one() -> None:
    lens = parse_zmx(zmx("STOP\nCURV 0\nDISZ 2\nDIAM 8", "TYPE PARAXIAL\nPARM 1 40\nDISZ 40\nDIAM 10"))
    for write in (format_prescription, format_codev):
        with pytest.raises(UserError, match="surface 1 is paraxial .* convert to .zmx or .json"):
            write(lens)


def test_lens_info_names_paraxial_surfaces(tmp_path, capsys) -> None:
    path = tmp_path / "pair.zmx"
    path.write_text(zmx("STOP\nCURV 0\nDISZ 2\nDIAM 8", "TYPE PARAXIAL\nPARM 1 40\nDISZ 5\nDIAM 10",
                        "TYPE PARAXIAL_XY\nPARM 1 0\nPARM 2 0.01\nDISZ 30\nDIAM 10"))
    assert main(["lens", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "paraxial f 40 mm" in out and "paraxial f inf x 100 mm" in out


def test_a_paraxial_stop_is_written_to_zemax_only() -> None:
    lens = parse_zmx(single())
    with pytest.raises(UserError, match="its stop is paraxial, .* convert to .zmx$"):
        format_json_lens(lens)
    again = parse_zmx(format_zmx(lens))
    assert again.stop == 0 and again.paraxial[0] and paraxial_data(again).efl_mm == pytest.approx(F_MM, rel=1e-15)
