"""Reading images through imageio: integer images keep every level (divided by their type's maximum,
then sRGB-decoded), float images keep their values exactly, 8-bit images read as Pillow's RGB did, and
an unreadable file is a one-line UserError naming it. Test files are written here by hand from the
formats' specifications (PNG, PFM), not by the code under test."""

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from realistic.core.image_files import read_image, read_linear_rgb, srgb_decode, srgb_encode
from realistic.errors import UserError
from realistic.optics.stop_shape import mask_stop
from realistic.scene.pbrt.importer import import_pbrt

#: 4096 levels spread over 16 bits: 8 bits could hold at most 256 of them.
RAMP16 = (np.arange(4096, dtype=np.uint32) * 16 + 8).astype(np.uint16).reshape(64, 64)


def write_png16(path: Path, pixels: np.ndarray) -> None:
    """A 16-bit PNG (grey, RGB or RGBA by the last axis) with filter 0 on every row (PNG spec, 11.2)."""
    height, width, channels = pixels.shape
    colour_type = {1: 0, 3: 2, 4: 6}[channels]
    rows = b"".join(b"\0" + row.astype(">u2").tobytes() for row in pixels)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 16, colour_type, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows))
                     + chunk(b"IEND", b""))


def write_pfm(path: Path, pixels: np.ndarray, little_endian: bool = True) -> None:
    """A PFM: "PF" (RGB) or "Pf" (grey), width height, scale (negative: little-endian), rows bottom first."""
    kind = b"PF" if pixels.ndim == 3 else b"Pf"
    height, width = pixels.shape[:2]
    scale, dtype = (b"-1.0", "<f4") if little_endian else (b"1.0", ">f4")
    path.write_bytes(kind + b"\n%d %d\n" % (width, height) + scale + b"\n"
                     + np.ascontiguousarray(pixels[::-1], dtype).tobytes())


def expected_from_16_bits(levels: np.ndarray) -> np.ndarray:
    return srgb_decode(levels / 65535.0).astype(np.float32)


def test_a_16_bit_grey_png_keeps_its_4096_levels(tmp_path):
    path = tmp_path / "ramp.png"
    Image.fromarray(RAMP16).save(path)  # Pillow writes a uint16 array as a 16-bit grey PNG
    pixels, stored_linear = read_image(path)
    assert not stored_linear and pixels.dtype == np.float32 and pixels.shape == (64, 64, 3)
    assert len(np.unique(pixels)) == 4096
    np.testing.assert_allclose(pixels, np.repeat(expected_from_16_bits(RAMP16)[..., None], 3, axis=2), rtol=1e-6)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_a_16_bit_png_keeps_every_channel_and_level(tmp_path, channels):
    planes = [RAMP16, 65535 - RAMP16, RAMP16[::-1], np.full_like(RAMP16, 1000)][:channels]
    write_png16(tmp_path / "ramp.png", np.stack(planes, axis=-1))
    pixels = read_linear_rgb(tmp_path / "ramp.png")
    expected = np.stack([planes[0]] * 3 if channels == 1 else planes[:3], axis=-1)
    np.testing.assert_allclose(pixels, expected_from_16_bits(expected), rtol=1e-6)
    assert len(np.unique(pixels[..., 0])) == 4096


@pytest.mark.parametrize("little_endian", [True, False])
def test_a_float_pfm_ramp_keeps_its_values_exactly(tmp_path, little_endian):
    ramp = np.linspace(-2.0, 50.0, 32 * 48, dtype=np.float32).reshape(32, 48)
    rgb = np.stack([ramp, 2 * ramp, ramp[::-1]], axis=-1)
    write_pfm(tmp_path / "rgb.pfm", rgb, little_endian)
    write_pfm(tmp_path / "grey.pfm", ramp, little_endian)
    pixels, stored_linear = read_image(tmp_path / "rgb.pfm")
    assert stored_linear and pixels.dtype == np.float32
    assert np.array_equal(pixels, rgb)  # row 0 is the top row, though PFM stores the bottom row first
    assert np.array_equal(read_linear_rgb(tmp_path / "grey.pfm"), np.repeat(ramp[..., None], 3, axis=2))


MODES_8_BIT = ("RGB", "RGBA", "L", "LA", "P", "1")


def test_a_radiance_hdr_keeps_its_float_values(tmp_path):
    """Flat (not run-length encoded) RGBE scanlines, as a width under 8 requires; each texel is
    mantissa * 2^(exponent - 136) (Radiance's rgbe.c)."""
    rgbe = np.array([[[128, 64, 32, 129], [255, 1, 0, 140], [1, 2, 3, 100]],
                     [[200, 100, 50, 120], [0, 0, 0, 0], [10, 20, 30, 150]]], np.uint8)
    header = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 3\n"
    (tmp_path / "sky.hdr").write_bytes(header + rgbe.tobytes())
    pixels, stored_linear = read_image(tmp_path / "sky.hdr")
    exponent = rgbe[..., 3:].astype(np.float64)
    expected = np.where(exponent > 0, rgbe[..., :3] * 2.0 ** (exponent - 136), 0.0)
    assert stored_linear
    np.testing.assert_allclose(pixels, expected, rtol=1e-6)


@pytest.mark.parametrize("suffix,mode", [(s, m) for s in (".png", ".tga", ".bmp") for m in MODES_8_BIT
                                         if s != ".bmp" or "A" not in m])  # BMP holds no alpha
def test_8_bit_images_read_as_pillows_rgb_did(tmp_path, suffix, mode):
    rgba = np.random.default_rng(3).integers(0, 256, (9, 11, 4), dtype=np.uint8)
    image = Image.fromarray(rgba if "A" in mode else rgba[..., :3]).convert(mode)
    path = tmp_path / f"t{suffix}"
    image.save(path)
    with Image.open(path) as stored:
        expected = srgb_decode(np.asarray(stored.convert("RGB"), dtype=np.float64) / 255)
    pixels, stored_linear = read_image(path)
    assert not stored_linear
    np.testing.assert_allclose(pixels, expected, rtol=1e-6, atol=1e-9)


def test_a_jpeg_reads_as_pillows_rgb_did(tmp_path):
    path = tmp_path / "t.jpg"
    Image.fromarray(np.random.default_rng(4).integers(0, 256, (16, 16, 3), dtype=np.uint8)).save(path)
    with Image.open(path) as stored:
        expected = srgb_decode(np.asarray(stored.convert("RGB"), dtype=np.float64) / 255)
    np.testing.assert_allclose(read_linear_rgb(path), expected, rtol=1e-6, atol=1e-9)


def test_an_aperture_mask_from_a_16_bit_png_keeps_its_threshold(tmp_path):
    """Levels just below and just above linear 0.5: Pillow's 8-bit RGB clipped both to white (all open)."""
    below, above = (np.round(srgb_encode(np.array(v)) * 65535) for v in (0.49, 0.51))
    levels = np.full((64, 64), below, np.uint16)
    levels[:, 32:] = above
    Image.fromarray(levels).save(tmp_path / "mask.png")
    mask = mask_stop(tmp_path / "mask.png").mask
    assert mask[:, mask.shape[1] // 2:].all() and not mask[:, :mask.shape[1] // 2].any()


def test_an_environment_map_pfm_keeps_its_high_dynamic_range(tmp_path):
    sky = np.linspace(0.0, 200.0, 8 * 16 * 3, dtype=np.float32).reshape(8, 16, 3)
    write_pfm(tmp_path / "sky.pfm", sky)
    (tmp_path / "scene.pbrt").write_text('Film "image" "integer xresolution" [8] "integer yresolution" [8]\n'
                                         'Camera "perspective" "float fov" 40\nWorldBegin\n'
                                         'LightSource "infinite" "string mapname" "sky.pfm"\n')
    (light,) = import_pbrt(tmp_path / "scene.pbrt", dialect="v3").scene.lights
    assert np.array_equal(light.image, sky)


@pytest.mark.parametrize("encoding,expected", [("linear", 0.75), ("sRGB", float(srgb_decode(np.array(0.75))))])
def test_an_imagemap_pfm_is_stored_linear(tmp_path, encoding, expected):
    """pbrt-v4's encoding applies to the stored values: a float file's are its linear values, not re-encoded."""
    write_pfm(tmp_path / "t.pfm", np.full((4, 4, 3), 0.75, np.float32))
    (tmp_path / "s.pbrt").write_text(
        'Film "image" "integer xresolution" [4] "integer yresolution" [4]\nCamera "perspective" "float fov" 40\n'
        f'WorldBegin\nTexture "t" "color" "imagemap" "string filename" "t.pfm" "string encoding" "{encoding}"\n'
        'Material "matte" "texture Kd" "t"\n'
        'Shape "trianglemesh" "point P" [-1 -1 3  1 -1 3  1 1 3] "integer indices" [0 1 2] "float uv" [0 0 1 0 1 1]\n')
    texture = import_pbrt(tmp_path / "s.pbrt", dialect="v4").scene.instances[0].material.texture
    assert texture.pixels[0, 0, 0] == pytest.approx(expected, rel=1e-6)


def _truncated_copy(source: Path, target: Path) -> Path:
    target.write_bytes(source.read_bytes()[: source.stat().st_size // 2])
    return target


@pytest.mark.parametrize("suffix", [".png", ".pfm", ".jpg", ".tga", ".hdr", ".tif"])
def test_a_bogus_image_is_a_one_line_error_naming_it(tmp_path, suffix):
    path = tmp_path / f"bogus{suffix}"
    path.write_bytes(b"this is not an image\n" * 3)
    with pytest.raises(UserError) as err:
        read_linear_rgb(path)
    assert str(err.value).startswith(f"{path}: ") and "\n" not in str(err.value)


@pytest.mark.parametrize("suffix", [".png", ".pfm", ".jpg", ".tga"])
def test_a_truncated_image_is_a_one_line_error_naming_it(tmp_path, suffix):
    whole = tmp_path / f"whole{suffix}"
    if suffix == ".pfm":
        write_pfm(whole, np.ones((64, 64, 3), np.float32))
    elif suffix == ".png":
        write_png16(whole, np.stack([RAMP16] * 3, axis=-1))
    else:
        Image.fromarray(np.random.default_rng(5).integers(0, 256, (64, 64, 3), dtype=np.uint8)).save(whole)
    path = _truncated_copy(whole, tmp_path / f"cut{suffix}")
    with pytest.raises(UserError) as err:
        read_linear_rgb(path)
    assert str(err.value).startswith(f"{path}: ") and "\n" not in str(err.value)


def test_a_missing_image_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="missing.pfm: no such"):
        read_linear_rgb(tmp_path / "missing.pfm")
