"""Filtered image textures: the MIP map, ray footprints, the imagemap parameters, and a checkerboard
floor receding to the horizon.

References are independent of the code under test: image means, constants, hand-computed texel
blends, a scalar transcription of pbrt-v3's EWA loop (src/core/mipmap.h) over a few points,
footprints of planes seen at known angles, and for the floor a render of the same scene with a
constant albedo of 0.5, the checkerboard's exact average, from the same random numbers.
"""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ewa_helpers import pbrt_ellipse
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.image_files import write_exr
from realistic.core.transforms import look_at, rotate, translate
from realistic.errors import UserError
from realistic.optics.formats import load_lens
from realistic.optics.paraxial import paraxial_data
from realistic.renderer.footprint import uv_footprint
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import render
from realistic.scene.mipmap import MipMap
from realistic.scene.model import AreaLight, ImageTexture, Instance, Material, Mesh, Scene
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.textures import evaluate


def checkerboard(size: int = 256, check: int = 32) -> np.ndarray:
    """(size, size, 3) linear checks of 0 and 1, ``check`` texels on a side."""
    index = np.arange(size) // check
    values = ((index[:, None] + index[None, :]) % 2).astype(np.float32)
    return np.repeat(values[:, :, None], 3, axis=2)


# ---- the MIP map alone -----------------------------------------------------------------------------

@pytest.mark.parametrize("shape", [(64, 64), (37, 50), (1, 9), (16, 4)])
def test_every_level_keeps_the_image_mean_down_to_one_texel(shape):
    image = np.random.default_rng(1).random((*shape, 3)).astype(np.float32)
    mipmap = MipMap(image)
    assert mipmap.level_count == 1 + math.ceil(math.log2(max(shape)))
    assert mipmap.levels[-1].shape[:2] == (1, 1)
    for level in mipmap.levels:
        np.testing.assert_allclose(level.mean(axis=(0, 1)), image.mean(axis=(0, 1)), rtol=1e-5)


@pytest.mark.parametrize("wrap", ["repeat", "clamp"])
def test_every_filter_of_a_constant_is_the_constant(wrap):
    rng = np.random.default_rng(2)
    mipmap = MipMap(np.full((20, 12, 3), 0.3, np.float32), wrap)
    st_ = rng.uniform(-2, 3, (500, 2))
    axis0, axis1 = rng.normal(0, 0.05, (500, 2)), rng.normal(0, 0.01, (500, 2))
    width = rng.uniform(0, 2, 500)
    for values in (mipmap.ewa(st_, axis0, axis1), mipmap.trilinear(st_, width), mipmap.point(st_, width),
                   mipmap.bilinear_at_width(st_, width)):
        np.testing.assert_allclose(values, 0.3, rtol=1e-5)


def test_bilinear_blends_texel_centres_and_zero_width_trilinear_is_bilinear():
    image = np.zeros((4, 4, 3), np.float32)
    image[1, 1], image[1, 2] = 1.0, 3.0  # row 1, columns 1 and 2
    mipmap = MipMap(image)
    centres = np.array([[1.5 / 4, 1.5 / 4], [2.5 / 4, 1.5 / 4], [2 / 4, 1.5 / 4], [2 / 4, 2 / 4]])
    expected = [1.0, 3.0, 2.0, 1.0]  # centres, midway between them, and midway between rows 1 and 2
    np.testing.assert_allclose(mipmap.bilinear(centres)[:, 0], expected, atol=1e-6)
    np.testing.assert_allclose(mipmap.trilinear(centres, np.zeros(4)), mipmap.bilinear(centres), atol=1e-7)


def _one_hot() -> np.ndarray:
    """A 4 x 4 image, 1 at texel (0, 0) and 0 elsewhere: levels 4 x 4, 2 x 2 ([[1/4, 0], [0, 0]]), 1 x 1 (1/16)."""
    image = np.zeros((4, 4, 3), np.float32)
    image[0, 0] = 1.0
    return image


#: At st = (1/8, 1/8), level 0's texel (0, 0) centre, bilinear reads 1 on level 0; on level 1 (x = y =
#: -1/4: 3/4 of texel 0 and 1/4 of texel -1, wrapped, on each axis) 1/4 * 3/4 * 3/4 = 9/64; 1/16 on level 2.
_ONE_HOT_LEVELS = (1.0, 9 / 64, 1 / 16)


@pytest.mark.parametrize("blend_from,level,expected", [
    # pbrt-v3 src/core/mipmap.h MIPMap::Lookup: Lerp(level - iLevel, triangle(iLevel), triangle(iLevel + 1))
    (0, -1.0, 1.0),
    (0, 0.5, 0.5 * 1.0 + 0.5 * 9 / 64),
    (0, 1.25, 0.75 * 9 / 64 + 0.25 / 16),
    # pbrt-v4 src/pbrt/util/mipmap.cpp MIPMap::Filter: if (iLevel == 0) return Bilerp<T>(0, st); else the same Lerp
    (1, -1.0, 1.0),
    (1, 0.5, 1.0),
    (1, 1.0, 9 / 64),
    (1, 1.25, 0.75 * 9 / 64 + 0.25 / 16),
])
def test_trilinear_blends_from_level_0_as_pbrt_v3_or_level_1_as_pbrt_v4(blend_from, level, expected):
    """The continuous level is L - 1 + log2(width) = 2 + log2(width) here: both versions blend the
    levels around it from level 1 up; for a level in [0, 1) pbrt-v3 blends levels 0 and 1 and pbrt-v4
    reads level 0 alone (the values: ``_ONE_HOT_LEVELS``, worked by hand)."""
    mipmap = MipMap(_one_hot(), trilinear_blend_from=blend_from)
    assert [float(level_[0, 0, 0]) for level_ in mipmap.levels] == [1.0, 0.25, 1 / 16]
    value = mipmap.trilinear(np.array([[0.125, 0.125]]), np.array([2.0 ** (level - 2)]))
    np.testing.assert_allclose(value, np.full((1, 3), expected), rtol=1e-12)


@pytest.mark.parametrize("value", [2, -1, True, 0.0, "1"])
def test_a_trilinear_blend_start_other_than_0_or_1_is_a_one_line_error(value):
    with pytest.raises(UserError, match="trilinear blend start level must be 0") as caught:
        ImageTexture(_one_hot(), trilinear_blend_from=value)
    assert "\n" not in str(caught.value)


def test_the_point_filter_rounds_halves_away_from_zero_as_pbrt_v4():
    """pbrt-v4's point filter (src/pbrt/util/mipmap.cpp, MIPMap::Filter) takes the texel at
    std::round(st * size - 0.5), which rounds halves away from zero: on a texel's edge it takes the
    texel after it (before it left of 0), where numpy's round to even took every other one."""
    image = np.arange(16 * 3, dtype=np.float32).reshape(4, 4, 3)
    mipmap = MipMap(image, "clamp")
    edges = np.array([[0.25, 0.5], [0.5, 0.75], [0.75, 0.25], [0.0, 0.0], [-0.25, 1.0]])
    # st * 4 - 0.5 = 0.5, 1.5, 2.5, -0.5, -1.5, 3.5 -> 1, 2, 3, -1, -2, 4 (clamped into 0..3)
    expected = image[[2, 3, 1, 0, 3], [1, 2, 3, 0, 0]]
    np.testing.assert_array_equal(mipmap.point(edges, np.zeros(5)), expected)


@pytest.mark.parametrize("wrap", ["repeat", "black", "clamp"])
def test_footprints_past_the_coarsest_level_read_its_texel_unwrapped(wrap):
    """pbrt-v3 (MIPMap::Lookup) and pbrt-v4 (MIPMap::Filter) return Texel(Levels() - 1, 0, 0) once
    L - 1 + log2(width) reaches the coarsest level: the image mean, wherever st falls, also with the
    black wrap (which had darkened a bilinear or point lookup off the 1 x 1 level's centre)."""
    image = np.random.default_rng(9).random((8, 16, 3)).astype(np.float32)
    mipmap = MipMap(image, wrap)
    st_ = np.random.default_rng(10).uniform(-2, 3, (200, 2))
    width = np.random.default_rng(11).uniform(1, 4, 200)  # L - 1 + log2(width) >= L - 1 from width 1 up
    for lookup in (mipmap.point, mipmap.bilinear_at_width, mipmap.trilinear):
        np.testing.assert_array_equal(lookup(st_, width), np.broadcast_to(mipmap.levels[-1][0, 0], (200, 3)))


@pytest.mark.parametrize("wrap,expected", [("repeat", 0.5 * (1 + 5)), ("clamp", 1.0), ("black", 0.5)])
def test_wrap_modes_at_the_left_border(wrap, expected):
    image = np.zeros((2, 4, 3), np.float32)
    image[:, 0], image[:, 3] = 1.0, 5.0  # first and last columns
    # s = 0 lies midway between column -1 (outside) and column 0
    value = MipMap(image, wrap).bilinear(np.array([[0.0, 0.5]]))[0, 0]
    assert value == pytest.approx(expected, abs=1e-6)


def _ewa_reference(levels: list[np.ndarray], st_: np.ndarray, axis0: np.ndarray, axis1: np.ndarray,
                   max_anisotropy: float) -> np.ndarray:
    """pbrt-v3's MIPMap::Lookup with EWA, one point at a time, texels wrapped (repeat)."""
    count = len(levels)
    lut = np.exp(-2.0 * np.arange(128) / 127) - np.exp(-2.0)
    if axis0 @ axis0 < axis1 @ axis1:
        axis0, axis1 = axis1, axis0
    major, minor = np.linalg.norm(axis0), np.linalg.norm(axis1)
    if minor * max_anisotropy < major and minor > 0:
        axis1 = axis1 * major / (minor * max_anisotropy)
        minor = major / max_anisotropy
    lod = max(0.0, count - 1 + math.log2(minor))
    low = math.floor(lod)

    def one_level(level: int) -> np.ndarray:
        if level >= count:
            return levels[-1][0, 0]
        image = levels[level]
        h, w = image.shape[:2]
        s, t, a, b, c = pbrt_ellipse(image.shape, st_, axis0, axis1)
        total, weights = np.zeros(3), 0.0
        for y in range(math.floor(t - 40), math.ceil(t + 40) + 1):
            for x in range(math.floor(s - 40), math.ceil(s + 40) + 1):
                r2 = a * (x - s) ** 2 + b * (x - s) * (y - t) + c * (y - t) ** 2
                if r2 < 1:
                    weight = lut[min(int(r2 * 128), 127)]
                    total += weight * image[y % h, x % w]
                    weights += weight
        return total / weights

    return (1 - (lod - low)) * one_level(low) + (lod - low) * one_level(low + 1)


def test_ewa_matches_a_scalar_transcription_of_pbrt():
    rng = np.random.default_rng(3)
    image = rng.random((32, 64, 3)).astype(np.float32)
    mipmap = MipMap(image, "repeat", max_anisotropy=4.0)
    st_ = rng.uniform(-1, 2, (24, 2))
    axis0 = rng.normal(0, 0.03, (24, 2))
    axis1 = rng.normal(0, 0.004, (24, 2))
    got = mipmap.ewa(st_, axis0, axis1)
    expected = [_ewa_reference(mipmap.levels, st_[i], axis0[i], axis1[i], 4.0) for i in range(24)]
    np.testing.assert_allclose(got, np.array(expected), rtol=1e-4, atol=1e-5)


def test_max_anisotropy_widens_the_minor_axis():
    mipmap = MipMap(checkerboard(64, 4), max_anisotropy=1.0)
    st_ = np.random.default_rng(4).random((50, 2))
    major = np.tile([[0.08, 0.0]], (50, 1))
    thin, round_ = np.tile([[0.0, 1e-4]], (50, 1)), np.tile([[0.0, 0.08]], (50, 1))
    np.testing.assert_allclose(mipmap.ewa(st_, major, thin), mipmap.ewa(st_, major, round_), atol=1e-6)


def test_wide_footprints_average_a_fine_checkerboard():
    mipmap = MipMap(checkerboard(256, 2))
    st_ = np.random.default_rng(5).random((200, 2))
    np.testing.assert_allclose(mipmap.trilinear(st_, np.full(200, 0.1)), 0.5, atol=1e-6)
    np.testing.assert_allclose(mipmap.ewa(st_, np.tile([[0.05, 0.0]], (200, 1)),
                                          np.tile([[0.0, 0.02]], (200, 1))), 0.5, atol=0.02)


# ---- footprints ------------------------------------------------------------------------------------

def _plane_footprint(angle_deg: float, distance: float, spread: float, uv_per_unit: float):
    """Footprint on the plane z = 0 (uv = uv_per_unit * (x, y)) of a ray tilted ``angle_deg`` from its
    normal in the x-z plane."""
    a = math.radians(angle_deg)
    direction = np.array([[math.sin(a), 0.0, -math.cos(a)]])
    normal = np.array([[0.0, 0.0, 1.0]])
    edge1, edge2 = np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 2.0, 0.0]])
    duv1, duv2 = np.array([[uv_per_unit, 0.0]]), np.array([[0.0, 2.0 * uv_per_unit]])
    return uv_footprint(direction, normal, np.array([distance]), spread, edge1, edge2, duv1, duv2)


@pytest.mark.parametrize("angle", [0.0, 60.0, 80.0])
def test_a_pixel_cone_stretches_by_one_over_cosine_along_the_ray(angle):
    across, along = _plane_footprint(angle, 10.0, 0.002, 3.0)
    width = 10.0 * 0.002 * 3.0
    stretched = width / math.cos(math.radians(angle))
    assert np.linalg.norm(across) == pytest.approx(width) and np.linalg.norm(along) == pytest.approx(stretched)
    assert across[0] @ along[0] == pytest.approx(0.0, abs=1e-15)
    if angle > 0:  # the ray leans along x, so the stretched axis is u
        np.testing.assert_allclose(np.abs(along[0]), [stretched, 0.0], rtol=1e-9, atol=1e-12)


def test_pixel_spreads_are_the_angles_of_one_pixel():
    thin = ThinLensCamera(60.0, 0.0, 1.0, 200, 100, 1, np.eye(4))
    assert thin.pixel_spread_radians() == pytest.approx(2 * math.tan(math.radians(30)) / 100)
    lens = load_lens("dgauss")
    camera = LensCamera.looking_at(lens, np.zeros(3), np.array([0, 0, 1.0]), math.inf, 43.27, 300, 200, 1)
    pitch_mm = camera.film_size_mm[0] / 300
    # focused at infinity the film sits at the rear focal point: one pixel is pitch / EFL radians
    assert camera.pixel_spread_radians() == pytest.approx(pitch_mm / paraxial_data(lens).efl_mm, rel=1e-6)


# ---- a checkerboard floor receding to the horizon ------------------------------------------------

WIDTH, HEIGHT, HORIZON_ROW = 96, 128, 8
SPREAD = 2 * math.tan(math.radians(15.0)) / WIDTH  # one pixel of a 30 degree view across 96 pixels
REPEAT_UNITS = 16.0  # the floor repeats the 256-texel image every 16 units: a check is 2 units
FAR_ROWS = slice(HORIZON_ROW + 1, HORIZON_ROW + 7)  # 50 to 400 units away: many checks per pixel
NEAR_ROWS = slice(HEIGHT - 16, HEIGHT)  # about 1.7 units away: a pixel covers a quarter of a texel


class PointSampled(ThinLensCamera):
    """The same camera without footprints: image textures are read at one point per ray."""

    def pixel_spread_radians(self) -> float:
        return 0.0


def floor_scene(texture: ImageTexture) -> Scene:
    corners = np.array([[-2e4, 0, -10], [2e4, 0, -10], [2e4, 0, 2e4], [-2e4, 0, 2e4]], float)
    scene = Scene(background=(0.0, 0.0, 0.0))
    scene.meshes.append(Mesh(corners, np.array([[0, 1, 2], [0, 2, 3]]), uv=corners[:, [0, 2]] / REPEAT_UNITS))
    scene.instances.append(Instance(0, np.eye(4), Material((1.0, 1.0, 1.0), texture)))
    # a disk high above the far floor: its irradiance varies little over the disk, so little noise
    scene.lights.append(AreaLight("disk", (500.0, 500.0), (1.0, 1.0, 1.0),
                                  translate(0, 1000, 200) @ rotate(90, (1, 0, 0))))
    return scene


def render_floor(texture: ImageTexture, spp: int, camera_class: type = ThinLensCamera, width: int = WIDTH
                 ) -> np.ndarray:
    """Red channel of the floor 1 unit below a pinhole whose horizon is row ``HORIZON_ROW``; narrower
    images keep the pixel's angle and the rows."""
    fov = 2 * math.degrees(math.atan(SPREAD * width / 2))
    tilt = (HEIGHT / 2 - HORIZON_ROW) * SPREAD
    camera = camera_class(fov, 0.0, 1.0, width, HEIGHT, spp, look_at(np.array([0, 1.0, 0]), np.array([0, 1 - tilt, 1])))
    return render(RenderJob(floor_scene(texture), (camera,), "numpy"))[0].image[..., 0]


@pytest.fixture(scope="module")
def floors_4spp():
    grey = render_floor(ImageTexture(np.full((1, 1, 3), 0.5, np.float32)), 4, PointSampled)
    point = render_floor(ImageTexture(checkerboard()), 4, PointSampled)
    filtered = {name: render_floor(ImageTexture(checkerboard(), filter=name), 4) for name in ("trilinear", "ewa")}
    return grey, point, filtered


@pytest.mark.parametrize("name", ["trilinear", "ewa"])
def test_far_away_filtering_gives_the_average_without_moire(floors_4spp, name):
    grey, point, filtered = floors_4spp
    assert grey[FAR_ROWS].min() > 0  # the far rows are floor
    albedo_point = 0.5 * point[FAR_ROWS] / grey[FAR_ROWS]
    albedo_filtered = 0.5 * filtered[name][FAR_ROWS] / grey[FAR_ROWS]
    assert albedo_filtered.mean() == pytest.approx(0.5, abs=0.01)
    assert albedo_point.std() > 0.15  # 4 samples of 0 or 1 per pixel (weighted by the light's samples)
    assert albedo_filtered.std() < albedo_point.std() / 10


@pytest.mark.parametrize("name", ["trilinear", "ewa"])
def test_close_up_filtering_changes_nothing(floors_4spp, name):
    grey, point, filtered = floors_4spp
    difference = np.abs(filtered[name][NEAR_ROWS] - point[NEAR_ROWS]) / grey[NEAR_ROWS].mean()
    # trilinear reads level 0 bilinearly; pbrt's EWA smooths over at least a texel, which shows only
    # on the pixels at a check's edge (2 texels of every 32 across each axis)
    assert difference.mean() < 0.01
    assert np.percentile(difference, 90) < 0.01


def test_point_and_filtered_agree_in_the_mean_at_high_spp():
    grey = render_floor(ImageTexture(np.full((1, 1, 3), 0.5, np.float32)), 64, PointSampled, 24)
    point = render_floor(ImageTexture(checkerboard()), 64, PointSampled, 24)
    filtered = render_floor(ImageTexture(checkerboard(), filter="ewa"), 64, width=24)
    for row in range(FAR_ROWS.start, FAR_ROWS.stop, 2):
        band = slice(row, row + 2)
        expected = point[band].mean() / grey[band].mean()
        assert filtered[band].mean() / grey[band].mean() == pytest.approx(expected, abs=0.03)


def test_without_a_footprint_an_image_texture_reads_its_finest_level():
    rng = np.random.default_rng(6)
    texture = ImageTexture(rng.random((8, 8, 3)).astype(np.float32), scale=(2.0, 3.0), v_origin="top")
    uv = rng.random((100, 2))
    x = (uv[:, 0] * 2 % 1) * 8 - 0.5
    y = (uv[:, 1] * 3 % 1) * 8 - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    p = texture.pixels
    expected = ((p[y0 % 8, x0 % 8] * (1 - fx) + p[y0 % 8, (x0 + 1) % 8] * fx) * (1 - fy)
                + (p[(y0 + 1) % 8, x0 % 8] * (1 - fx) + p[(y0 + 1) % 8, (x0 + 1) % 8] * fx) * fy)
    np.testing.assert_allclose(evaluate(texture, uv), expected, atol=1e-5)


# ---- the imagemap parameters -----------------------------------------------------------------------

SCENE_HEAD = ('Film "image" "integer xresolution" [4] "integer yresolution" [4]\n'
              'Camera "perspective" "float fov" 40\nWorldBegin\n')
SCENE_TAIL = ('Material "matte" "texture Kd" "t"\n'
              'Shape "trianglemesh" "point P" [-1 -1 3  1 -1 3  1 1 3] "integer indices" [0 1 2]'
              ' "float uv" [0 0 1 0 1 1]\n')


def _imagemap_scene(tmp_path, parameters: str, dialect: str = "auto") -> ImageTexture:
    write_exr(tmp_path / "t.exr", np.full((4, 4, 3), 0.25, np.float32))
    path = tmp_path / "s.pbrt"
    path.write_text(SCENE_HEAD + f'Texture "t" "color" "imagemap" "string filename" "t.exr" {parameters}\n'
                    + SCENE_TAIL)
    return import_pbrt(path, dialect=dialect).scene.instances[0].material.texture


@pytest.mark.parametrize("dialect,parameters,filter_,texel", [
    ("v2", "", "ewa", 0.25),
    ("v2", '"bool trilinear" "true" "float scale" 2 "float gamma" 2', "trilinear", 0.25),  # (2 x 0.25)^2
    ("v3", '"float scale" 3 "string wrap" "clamp"', "ewa", 0.75),
    ("v3", '"bool gamma" "true"', "ewa", ((0.25 + 0.055) / 1.055) ** 2.4),  # sRGB-decoded EXR values
    ("v4", "", "bilinear", 0.25),
    ("v4", '"string filter" "ewa" "string encoding" "gamma 2" "bool invert" "true"', "ewa", 1 - 0.0625),
])
def test_imagemap_parameters_per_dialect(tmp_path, dialect, parameters, filter_, texel):
    texture = _imagemap_scene(tmp_path, parameters, dialect)
    assert texture.filter == filter_
    assert texture.pixels[0, 0, 0] == pytest.approx(texel, rel=1e-5)


@pytest.mark.parametrize("dialect,parameters,blend_from,expected", [
    ("v2", '"bool trilinear" "true"', 0, 0.5 * 1.0 + 0.5 * 9 / 64),
    ("v3", '"bool trilinear" "true"', 0, 0.5 * 1.0 + 0.5 * 9 / 64),
    ("v4", '"string filter" "trilinear"', 1, 1.0),
])
def test_a_trilinear_imagemap_blends_as_its_pbrt_version_does(tmp_path, dialect, parameters, blend_from, expected):
    """pbrt-v2/v3 files blend levels 0 and 1 at a continuous level of 0.5, pbrt-v4 files read level 0
    alone there (``test_trilinear_blends_from_level_0_as_pbrt_v3_or_level_1_as_pbrt_v4``'s values): a
    footprint of width 2^-1.5 (level 2 - 1.5) at st (1/8, 1/8) of the one-hot image, whose uv is
    (1/8, 1/8) for a top-origin (v2) image and (1/8, 7/8) for a bottom-origin (v3, v4) one."""
    write_exr(tmp_path / "t.exr", _one_hot())
    path = tmp_path / "s.pbrt"
    path.write_text(SCENE_HEAD + f'Texture "t" "color" "imagemap" "string filename" "t.exr" {parameters}\n'
                    + SCENE_TAIL)
    texture = import_pbrt(path, dialect=dialect).scene.instances[0].material.texture
    assert (texture.filter, texture.trilinear_blend_from) == ("trilinear", blend_from)
    uv = np.array([[0.125, 0.125 if texture.v_origin == "top" else 0.875]])
    half = 2.0 ** -2.5  # the width is twice the largest axis component: 2^-1.5
    colour = evaluate(texture, uv, (np.array([[half, 0.0]]), np.array([[0.0, half]])))
    np.testing.assert_allclose(colour, np.full((1, 3), expected), rtol=1e-6)


@pytest.mark.parametrize("dialect,parameters,message", [
    ("v3", '"string wrap" "mirror"', "wrap must be one of"),
    ("v2", '"float maxanisotropy" 0.5', "maxanisotropy must be between"),
    ("v3", '"string filter" "ewa"', '"filter" is pbrt-v4'),
    ("v4", '"string filter" "gaussian"', "filter must be one of"),
    ("v4", '"string encoding" "gamma x"', "needs a number"),
    ("v3", '"float trilinear" 1', "must be one bool"),
])
def test_bad_imagemap_parameters_are_one_line_errors_naming_the_line(tmp_path, dialect, parameters, message):
    with pytest.raises(UserError, match=message) as caught:
        _imagemap_scene(tmp_path, parameters, dialect)
    assert "s.pbrt:4:" in str(caught.value) and "\n" not in str(caught.value)


NAMES = ["filter", "trilinear", "maxanisotropy", "wrap", "scale", "gamma", "encoding", "invert", "uscale",
         "vscale", "udelta", "vdelta"]
VALUES = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=32).map(lambda v: f"{v:.9g}"),
                   st.sampled_from(['"true"', '"false"', '"ewa"', '"point"', '"clamp"', '"black"', '"mirror"',
                                    '"sRGB"', '"linear"', '"gamma 2.2"', '"gamma -1"', '"gamma x"', '""', "1e39"]))


@given(st.lists(st.tuples(st.sampled_from(["float", "bool", "string", "integer", "rgb"]), st.sampled_from(NAMES),
                          st.lists(VALUES, min_size=1, max_size=3)), max_size=4),
       st.sampled_from(["v1", "v2", "v3", "v4"]))
def test_imagemap_parameter_parsing_succeeds_or_says_why(tmp_path, parameters, dialect):
    text = " ".join(f'"{kind} {name}" [{" ".join(values)}]' for kind, name, values in parameters)
    try:
        texture = _imagemap_scene(tmp_path, text, dialect)
    except UserError as err:
        assert "\n" not in str(err)
        return
    uv = np.random.default_rng(0).random((16, 2))
    footprint = (np.full((16, 2), 0.1), np.full((16, 2), -0.02))
    assert np.all(np.isfinite(evaluate(texture, uv, footprint)))
