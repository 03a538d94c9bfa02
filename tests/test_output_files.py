"""Output files a photographer and a pbrt user expect (issue 33): the EXR's standard attributes,
read back as the file stores them; a metered exposure; PNG (8 and 16 bits) and PFM outputs."""

import dataclasses
import hashlib
import math
import struct
from pathlib import Path

import cv2
import imageio.v3 as iio
import numpy as np
import pytest

import realistic as rl
from realistic.camera.base import SampleBlock
from realistic.camera.exposure import (
    MeterReading,
    exposure_scale,
    format_shutter,
    meter_reading,
    metered_stops,
    parse_exposure,
)
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.cli import main
from realistic.core import rng
from realistic.core.image_files import SRGB_CHROMATICITIES, read_exr, srgb_encode, write_exr
from realistic.core.transforms import look_at
from realistic.renderer.job import RenderJob, RenderResult
from realistic.renderer.output import BetterImageKept, prescription_sha256, standard_metadata

SMALL = {"resolution": (8, 6), "spp": 2, "lens_sampling": "rear", "dispersion": False}
CLI = ["--backend", "numpy", "--res", "8x6", "--spp", "2", "--lens-sampling", "rear", "--dispersion", "off",
       "--threads", "1"]


def _api_render() -> RenderResult:
    scene = rl.load_scene(**SMALL)
    return rl.render_job(RenderJob(scene, (scene.camera,), "numpy", 0), rl.ThreadPasses(1))[0]


def _attribute_types(path: Path) -> dict[str, tuple[str, bytes]]:
    """Each header attribute's (type name, raw value) as the file stores them (OpenEXR's layout:
    magic, version, then name NUL type NUL int32 size value ..., ended by a NUL), read without
    OpenEXR's library."""
    data = path.read_bytes()
    assert data[:4] == b"\x76\x2f\x31\x01"
    attributes, pos = {}, 8
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        type_end = data.index(b"\0", end + 1)
        kind = data[end + 1:type_end].decode()
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        attributes[name] = (kind, data[type_end + 5:type_end + 5 + size])
        pos = type_end + 5 + size
    return attributes


def test_the_exr_header_holds_standard_attributes_as_numbers(tmp_path):
    result = _api_render()
    rl.save(result, tmp_path / "r.exr")
    stored = _attribute_types(tmp_path / "r.exr")
    kinds = {name: kind for name, (kind, _) in stored.items()}
    assert kinds["chromaticities"] == "chromaticities"
    np.testing.assert_allclose(struct.unpack("<8f", stored["chromaticities"][1]), SRGB_CHROMATICITIES, rtol=1e-6)
    assert kinds["worldToCamera"] == kinds["worldToNDC"] == "m44f"
    assert kinds["software"] == "string" and stored["software"][1] == f"realistic {rl.__version__}".encode()
    assert kinds["samplesPerPixel"] == kinds["spp"] == kinds["samplesDone"] == "int"
    assert kinds["renderTimeSeconds"] == kinds["fNumber"] == kinds["focusDistanceMm"] == "float"
    header = read_exr(tmp_path / "r.exr")[1]
    lens = result.camera.lens
    assert header["lens"] == lens.name and header["lensSha256"] == prescription_sha256(lens)
    assert header["samplesPerPixel"] == 2 and header["samplesDone"] == 8 * 6 * 2
    assert kinds["aperture"] == kinds["focus"] == "float"
    assert header["aperture"] == pytest.approx(header["fNumber"]) and header["focus"] == pytest.approx(
        header["focusDistanceMm"] / 1000)


def test_a_photographic_exposure_is_in_openexr_s_terms_and_auto_meters_its_preview(tmp_path):
    result = _api_render()
    photographic = rl.Photographic(1 / 125, 400)
    assert rl.save(result, tmp_path / "r.exr", photographic) == 0.0  # as the camera exposed it
    header = read_exr(tmp_path / "r.exr")[1]
    assert header["expTime"] == pytest.approx(1 / 125) and header["isoSpeed"] == 400
    stops = rl.save(result, tmp_path / "r.exr", photographic, exposure="auto")
    assert stops == pytest.approx(metered_stops(result.image * np.float32(photographic.scale)))


def test_the_prescription_hash_is_the_surface_table_s():
    lens = rl.load_lens("dgauss")
    table = np.column_stack([lens.radius_mm, lens.thickness_mm, lens.index_d, lens.abbe_v, lens.aperture_mm,
                             lens.conic, lens.aspheric_coefficients])
    expected = hashlib.sha256(table.astype("<f8").tobytes() + struct.pack("<q", lens.stop)).hexdigest()
    assert prescription_sha256(lens) == expected
    assert prescription_sha256(dataclasses.replace(lens, name="renamed")) == expected
    bent = lens.radius_mm.copy()
    bent[0] *= 1.001
    assert prescription_sha256(dataclasses.replace(lens, radius_mm=bent)) != expected


def _header_matrices(camera, tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """worldToCamera and worldToNDC as written to an EXR and read back (float32 M44f)."""
    path = tmp_path / "m.exr"
    write_exr(path, np.zeros((camera.height, camera.width, 3), np.float32), standard_metadata(camera))
    header = read_exr(path)[1]
    return np.asarray(header["worldToCamera"], np.float64), np.asarray(header["worldToNDC"], np.float64)


def _raster(ndc_from_world: np.ndarray, points: np.ndarray, width: int, height: int) -> np.ndarray:
    """Raster (x, y) of world points through pbrt-v4's worldToNDC: NDC = (screen + 1) / 2, with the
    shorter image side spanning screen [-1, 1], y up (module docstring of renderer.output)."""
    h = np.column_stack([points, np.ones(len(points))]) @ ndc_from_world.T
    ndc = h[:, :2] / h[:, 3:]
    aspect = width / height
    half_x, half_y = (aspect, 1.0) if aspect > 1 else (1.0, 1 / aspect)
    return np.column_stack([(2 * ndc[:, 0] - 1 + half_x) / (2 * half_x) * width,
                            (half_y - (2 * ndc[:, 1] - 1)) / (2 * half_y) * height])


def test_world_to_ndc_sends_a_point_to_the_pixel_whose_ray_reaches_it(tmp_path):
    eye, target = np.array([1.0, 2.0, -3.0]), np.array([-0.5, 0.3, 2.0])
    camera = ThinLensCamera(50.0, 0.0, 1e6, 40, 24, 1, look_at(eye, target))
    camera_from_world, ndc_from_world = _header_matrices(camera, tmp_path)
    rays = camera.generate_rays(SampleBlock(0, 40 * 24, 1), seed=3)
    distance = np.random.default_rng(0).uniform(0.5, 50.0, len(rays.pixel))
    points = rays.origin + rays.direction * distance[:, None]
    raster = _raster(ndc_from_world, points, 40, 24)
    centre = np.column_stack([rays.pixel % 40 + 0.5, rays.pixel // 40 + 0.5])
    assert np.max(np.abs(raster - centre)) <= 0.5 + 1e-4  # in the pixel the ray came from
    np.testing.assert_allclose(camera_from_world @ [*eye, 1], [0, 0, 0, 1], atol=1e-6)
    along = camera_from_world @ [*target, 1]
    np.testing.assert_allclose(along[:3], [0, 0, np.linalg.norm(target - eye)], atol=1e-5)


def test_a_lens_camera_s_world_to_ndc_is_its_paraxial_projection(tmp_path):
    # a small stop, so that each ray is nearly its film point's chief ray: a point anywhere along
    # it images near that film point, and exactly so near the axis in the plane in focus
    lens = rl.load_lens("dgauss").with_stop_diameter(0.25)
    width, height = 240, 160
    eye, target = np.array([0.2, 1.0, 4.0]), np.array([0.0, 0.5, 0.0])
    camera = LensCamera.looking_at(lens, eye, target, width=width, height=height, spp=1)
    camera_from_world, ndc_from_world = _header_matrices(camera, tmp_path)
    focus = float(np.linalg.norm(target - eye))
    np.testing.assert_allclose((camera_from_world @ [*target, 1])[:3], [0, 0, focus], atol=1e-5)
    block = SampleBlock(0, width * height, 1)
    rays = camera.generate_rays(block, seed=1)
    pixel, sample = block.ids()
    u = rng.stratified4(pixel, sample, 1)
    film = camera.filtered_film_points(pixel, u[0], u[1])[0]  # each ray's film point (mm)
    film_w, film_h = camera.film_size_mm
    raster = np.column_stack([width * (0.5 - film[:, 0] / film_w), height * (0.5 + film[:, 1] / film_h)])
    near_axis = (rays.weight > 0) & (np.hypot(raster[:, 0] - width / 2, raster[:, 1] - height / 2) < 20)
    assert near_axis.sum() > 500
    origin, direction, raster = rays.origin[near_axis], rays.direction[near_axis], raster[near_axis]
    along_z = (direction @ camera_from_world[:3, :3].T)[:, 2]
    origin_z = origin @ camera_from_world[2, :3] + camera_from_world[2, 3]
    for depth, pixels in ((focus, 0.02), (1.0, 0.1), (20.0, 0.1)):  # camera-space z, world units
        points = origin + direction * ((depth - origin_z) / along_z)[:, None]
        assert np.max(np.abs(_raster(ndc_from_world, points, width, height) - raster)) < pixels, depth


def _scene(rng: np.random.Generator) -> np.ndarray:
    """A textured scene: log-normal luminance over 5 stops, in colour."""
    grey = 0.05 * 2.0 ** rng.normal(0, 1.2, (120, 160))
    return (grey[..., None] * rng.uniform(0.5, 1.5, (1, 1, 3))).astype(np.float32)


def test_near_identical_scenes_meter_alike_and_twice_the_light_is_one_stop():
    scene = _scene(np.random.default_rng(7))
    stops = metered_stops(scene)
    highlight = scene.copy()
    highlight[10:22, 20:36] = 500.0  # a light source in view: 1 % of the frame, 13 stops over
    black = scene.copy()
    black[::10, ::10] = 0.0  # 1 % dead pixels
    assert abs(metered_stops(highlight) - stops) < 0.2
    assert abs(metered_stops(black) - stops) < 0.2
    assert metered_stops(scene * np.float32(2)) == pytest.approx(stops - 1, abs=1e-9)
    assert metered_stops(np.zeros((4, 4, 3), np.float32)) == 0.0


def test_the_old_percentile_swing_is_gone():
    # the 97th percentile of luminance fell on either side of a light's edge: 10 stops apart
    dim = np.full((100, 100, 3), 0.1, np.float32)
    a, b = dim.copy(), dim.copy()
    a.reshape(-1, 3)[:350] = 100.0
    b.reshape(-1, 3)[:250] = 100.0
    assert abs(metered_stops(a) - metered_stops(b)) < 0.2
    assert 0.1 * 2 ** metered_stops(b) == pytest.approx(0.18, rel=0.25)  # the scene itself near middle grey


def test_a_meter_reading_against_shutter_and_iso_is_the_iso_2720_relation():
    # a uniform field of luminance L through f/N: E = pi L / (4 N^2); EV100 = log2(L 100 / K)
    luminance, n, iso = 400.0, 8.0, 400.0
    image = np.full((4, 4, 3), math.pi * luminance / (4 * n * n), np.float32)
    correct = n * n * 12.5 / (luminance * iso)
    reading = meter_reading(image, correct / 2**6.4, iso, n)
    assert isinstance(reading, MeterReading)
    assert reading.stops_over == pytest.approx(-6.4, abs=1e-6)
    assert reading.wanted_ev100 == pytest.approx(math.log2(luminance * 100 / 12.5), abs=1e-6)
    assert reading.given_ev100 - reading.wanted_ev100 == pytest.approx(6.4, abs=1e-6)
    assert reading.metered_shutter_s == pytest.approx(correct, rel=1e-6)
    assert "6.4 stops under" in reading.describe()
    assert float(image[0, 0, 0]) * exposure_scale(reading.metered_shutter_s, iso) == pytest.approx(0.18, rel=1e-6)
    assert meter_reading(np.zeros((2, 2, 3), np.float32), 0.01, 100, n) is None


def test_shutter_times_read_as_a_photographer_writes_them():
    assert [format_shutter(t) for t in (1 / 125, 1 / 2.5, 1.64, 32.4, 1 / 1000)] == \
        ["1/125", "1/2.5", "1.6", "32", "1/1000"]


def test_exposure_parses_auto_or_stops():
    assert parse_exposure("auto") == "auto" and parse_exposure("AUTO") == "auto"
    assert parse_exposure("-1.5") == -1.5
    with pytest.raises(rl.UserError, match="neither a number of stops nor 'auto'"):
        parse_exposure("bright")


def test_a_png_output_is_that_png_alone_metered(tmp_path):
    result = _api_render()
    stops = rl.save(result, tmp_path / "r.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.png"]  # as pbrt-v4: only the file named
    assert stops == pytest.approx(metered_stops(result.image))
    stored = cv2.imread(str(tmp_path / "r.png"), cv2.IMREAD_UNCHANGED)[..., ::-1]
    assert stored.dtype == np.uint8
    expected = np.round(srgb_encode(result.image * np.float32(2.0**stops)) * 255)
    np.testing.assert_array_equal(stored, expected)


def test_a_16_bit_png_keeps_16_bits(tmp_path):
    result = _api_render()
    stops = rl.save(result, tmp_path / "r.png", exposure=-1.0, png_bits=16)
    assert stops == -1.0
    stored = cv2.imread(str(tmp_path / "r.png"), cv2.IMREAD_UNCHANGED)[..., ::-1]
    assert stored.dtype == np.uint16
    np.testing.assert_array_equal(stored, np.round(srgb_encode(result.image * np.float32(0.5)) * 65535))


def test_a_pfm_output_holds_the_float_image(tmp_path):
    result = _api_render()
    rl.save(result, tmp_path / "r.pfm", rl.Photographic(1 / 125, 400))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.pfm"]
    stored = iio.imread(tmp_path / "r.pfm", plugin="opencv", flags=cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(stored, (result.image * np.float32(exposure_scale(1 / 125, 400))))
    assert (tmp_path / "r.pfm").read_bytes().startswith(b"PF\n8 6\n-1.0\n")


@pytest.mark.parametrize("suffix", [".png", ".pfm"])
def test_an_interrupted_render_replaces_no_png_or_pfm_and_a_failed_write_is_rescued(tmp_path, suffix):
    scene = rl.load_scene(**SMALL)
    job = RenderJob(scene, (scene.camera,), "numpy")
    partial = RenderResult(np.zeros((6, 8, 3), np.float32), 10, 96, 0, 0, 0.0, True, job=job)
    out = tmp_path / f"r{suffix}"
    out.write_bytes(b"an earlier render")
    with pytest.raises(BetterImageKept, match="cannot say how many samples"):
        rl.save(partial, out)
    assert out.read_bytes() == b"an earlier render"
    with pytest.raises(rl.UserError, match="the render was saved as") as caught:
        rl.save(_api_render(), tmp_path / "no such folder" / f"x{suffix}")
    rescued = Path(str(caught.value).split("the render was saved as ")[1].split(" instead")[0])
    try:
        assert rescued.suffix == suffix and rescued.stat().st_size > 0
    finally:
        rescued.unlink()


def test_the_cli_writes_a_png_alone_and_prints_the_meter_reading(tmp_path, capsys):
    out = tmp_path / "shot.png"
    assert main(["render", *CLI, "--fstop", "8", "--shutter", "1/125", "--iso", "400", "--png-bits", "16",
                 "--out", str(out)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.png"]
    assert cv2.imread(str(out), cv2.IMREAD_UNCHANGED).dtype == np.uint16
    line = [x for x in capsys.readouterr().err.splitlines() if "meter" in x][-1]
    assert "f/8" in line and "1/125 s at ISO 400" in line and "stops under" in line
    assert "would meter correctly" in line


def test_the_cli_refuses_other_image_types(tmp_path, capsys):
    assert main(["render", *CLI, "--out", str(tmp_path / "x.tif")]) == 2
    assert "x.tif: the output must be an .exr file (the PNG preview goes beside it), a .png or a .pfm" in \
        capsys.readouterr().err


@pytest.mark.parametrize("named,written", [("shot.png", "shot.png"), ("shot.pfm", "shot.pfm"),
                                           ("shot.tga", "shot.exr")])
def test_a_pbrt_scene_s_film_file_name_is_the_output(tmp_path, monkeypatch, named, written):
    scene = tmp_path / "s.pbrt"
    scene.write_text(f'Film "image" "integer xresolution" [8] "integer yresolution" [6] "string filename" "{named}"\n'
                     'Sampler "random" "integer pixelsamples" 1\nCamera "perspective" "float fov" 40\n'
                     'WorldBegin\nShape "sphere"\nWorldEnd\n')
    monkeypatch.chdir(tmp_path)
    assert main(["render", str(scene), "--backend", "numpy", "--threads", "1"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["s.pbrt", written] + (
        ["shot.png"] if written.endswith(".exr") else []))
