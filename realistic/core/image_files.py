"""Image files: OpenEXR with metadata, PNG (8- and 16-bit sRGB) and PFM outputs (written atomically);
EXR (OpenEXR) and other images (imageio) read at their stored bit depth or float values."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from realistic.core.atomic_files import write_atomically
from realistic.core.input_files import input_file
from realistic.errors import UserError

#: EXR header attributes by value: str -> string, int -> int, float -> float, an (N,) float array
#: -> V2f or V3f, a (4, 4) float array -> M44f, the 8-tuple under ``chromaticities`` -> chromaticities.
Metadata = dict[str, str | int | float | tuple[float, ...] | np.ndarray]

#: CIE xy of the red, green and blue primaries and the white point of linear sRGB / Rec. 709 (D65):
#: the colour space of every image the renderer writes (its film integrates to linear sRGB).
SRGB_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


def write_exr(path: Path, image: np.ndarray, metadata: Metadata | None = None,
              window: tuple[int, int, int, int] | None = None,
              channels: dict[str, np.ndarray] | None = None) -> None:
    """float32 RGB OpenEXR (ZIP) with ``metadata`` as extra header attributes (typed as ``Metadata``
    says; vectors and matrices as float32) and the standard ``chromaticities`` of linear sRGB unless
    ``metadata`` gives others. pbrt-v4 (``Image::WriteEXR``, src/pbrt/util/image.cpp) leaves sRGB's
    out because macOS Preview then re-encodes the pixels; OpenEXR's default is the same primaries,
    so writing them only says explicitly what a reader assumes. ``window`` (x, y, full width, full
    height): the image is the part of a larger one at pixel (x, y), as a cropped render is: its data
    window starts there, its display window is the full image (pbrt-v4's way). ``channels`` (name ->
    (H, W) image, such as "Albedo.R" or "P.Z": layers by OpenEXR's dotted names) go beside R, G, B."""
    import OpenEXR

    attributes = {name: _attribute(value) for name, value in (metadata or {}).items()}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              "chromaticities": SRGB_CHROMATICITIES, **attributes}
    if window is not None:
        x, y, width, height = window
        header["dataWindow"] = ((x, y), (x + image.shape[1] - 1, y + image.shape[0] - 1))
        header["displayWindow"] = ((0, 0), (width - 1, height - 1))
    pixels = {"RGB": np.ascontiguousarray(image, dtype=np.float32)}
    pixels.update({name: np.ascontiguousarray(value, dtype=np.float32) for name, value in (channels or {}).items()})
    write_atomically(path, lambda name: OpenEXR.File(header, pixels).write(name))


def _attribute(value: str | int | float | tuple[float, ...] | np.ndarray) -> object:
    """A header value as OpenEXR's binding types it: numpy scalars as Python numbers, float arrays
    as float32 (V2f, V3f, M44f rather than their double forms)."""
    if isinstance(value, np.ndarray):
        return np.ascontiguousarray(value, dtype=np.float32)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def read_exr(path: Path) -> tuple[np.ndarray, dict]:
    """(RGB float32 (H, W, 3), header) of an EXR file."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path)) as exr:
            header = dict(exr.header())
            channels = exr.channels()
            if "RGB" in channels or "RGBA" in channels:
                pixels = channels.get("RGB", channels.get("RGBA")).pixels[..., :3]
            else:
                first = next(iter(channels.values())).pixels
                pixels = np.repeat(first[..., None], 3, axis=2) if first.ndim == 2 else first[..., :3]
    except Exception as err:
        raise UserError(f"{path}: not a readable OpenEXR image ({err})") from None
    return np.asarray(pixels, dtype=np.float32), header


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer function on values clipped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """The inverse of ``srgb_encode``: sRGB-encoded values in [0, 1] to linear."""
    x = np.clip(encoded, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


#: Bits per sample a PNG may be written with.
PNG_BITS = (8, 16)


def check_png_bits(bits: int) -> int:
    """A PNG's bits per sample: 8 or 16 (``PNG_BITS``)."""
    if bits not in PNG_BITS:
        raise UserError(f"PNG bits per sample must be 8 or 16, got {bits!r}")
    return bits


def preview_pixels(image: np.ndarray, exposure_stops: float, bits: int = 8) -> np.ndarray:
    """sRGB pixels (H, W, 3) of linear ``image`` scaled by 2^exposure_stops, clipped to [0, 1] and
    quantised to ``bits`` (8: uint8, 16: uint16): what a PNG holds, and what a notebook shows."""
    check_png_bits(bits)
    encoded = srgb_encode(image.astype(np.float32) * np.float32(2.0**exposure_stops))
    top = (1 << bits) - 1
    return np.round(encoded * top).astype(np.uint8 if bits == 8 else np.uint16)


def png_bytes(image: np.ndarray, exposure_stops: float, bits: int = 8) -> bytes:
    """The PNG file of ``preview_pixels`` in memory: 8 bits through Pillow (the bytes imageio's Pillow
    plugin wrote, without imageio's import, a tenth of a second of a first render's start), 16
    through imageio's OpenCV plugin (Pillow writes no 16-bit RGB)."""
    samples = preview_pixels(image, exposure_stops, bits)
    if bits == 8:
        from PIL import Image

        data = io.BytesIO()
        Image.fromarray(samples).save(data, format="PNG")
        return data.getvalue()
    import imageio.v3 as iio

    return bytes(iio.imwrite("<bytes>", samples, plugin="opencv", extension=".png"))


def write_png(path: Path, image: np.ndarray, exposure_stops: float, bits: int = 8) -> None:
    """sRGB PNG of linear ``image`` scaled by 2^exposure_stops (``png_bytes``), written atomically."""
    # encoded in memory, then written: Pillow writing to a file reports a full disk only when the
    # file object is collected ("Exception ignored"), after a truncated file would be renamed in place
    data = png_bytes(image, exposure_stops, bits)
    write_atomically(path, lambda name: Path(name).write_bytes(data))


def write_pfm(path: Path, image: np.ndarray) -> None:
    """Linear RGB ``image`` as a PFM (Portable Float Map) as pbrt-v4 writes it (``Image::WritePFM``):
    ``PF``, the width and height, scale -1 (little-endian float32), rows from the bottom up."""
    pixels = np.ascontiguousarray(np.asarray(image, dtype="<f4")[::-1])
    height, width = pixels.shape[:2]
    data = f"PF\n{width} {height}\n-1.0\n".encode("ascii") + pixels.tobytes()
    write_atomically(path, lambda name: Path(name).write_bytes(data))


#: Suffixes read through imageio's OpenCV plugin: the formats whose bit depth or float values Pillow
#: cannot hold (16-bit RGB PNG and TIFF, float RGB PFM and TIFF, Radiance HDR). Other non-EXR images
#: (JPEG, TGA, BMP, ...) go through its Pillow plugin.
_OPENCV_SUFFIXES = frozenset({".png", ".pfm", ".hdr", ".tif", ".tiff"})
#: Pillow modes with more than 8 bits per sample (single-channel); other modes are read converted to RGB.
_DEEP_PILLOW_MODES = ("I", "F")


#: Most pixels an input image may have: 16384 x 8192, the largest environment maps in use (2 GiB as
#: float32 RGB). A header may claim far more than its file holds (a "decompression bomb").
MAX_INPUT_PIXELS = 1 << 27


def _check_pixel_count(path: Path) -> None:
    """Refuse an image whose header claims more than ``MAX_INPUT_PIXELS``, before decoding it. The
    header is read by Pillow, which opens lazily; a format Pillow does not know is left to its reader."""
    import warnings

    from PIL import Image, UnidentifiedImageError

    too_many = UserError(f"{path}: the image claims more pixels than {MAX_INPUT_PIXELS:,} (16384 x 8192), "
                         f"the most an input image may have")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # the check below decides
            with Image.open(path) as image:
                width, height = image.size
    except Image.DecompressionBombError:  # Pillow's own limit, which lies above ours
        raise too_many from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
        return
    if width * height > MAX_INPUT_PIXELS:
        raise too_many


def read_image(path: str | Path) -> tuple[np.ndarray, bool]:
    """(linear RGB float32 (H, W, 3), whether the file stored linear float values): EXR and other float
    images as stored; integer images divided by their type's maximum (so 8- and 16-bit keep every level)
    and sRGB-decoded. Grey is repeated into RGB, alpha dropped."""
    path = input_file(path, "texture file")
    if path.suffix.lower() == ".exr":
        return read_exr(path)[0], True
    _check_pixel_count(path)
    try:
        pixels = _read_with_imageio(path)
    except Exception as err:  # imageio, Pillow and OpenCV raise many types for unreadable files
        message = " ".join(str(err).split()) or type(err).__name__
        raise UserError(f"{path}: not a readable image ({message})") from None
    rgb = _rgb_channels(pixels, path)
    if np.issubdtype(rgb.dtype, np.floating):
        return rgb.astype(np.float32), True
    return srgb_decode(rgb.astype(np.float64) / np.iinfo(rgb.dtype).max).astype(np.float32), False


def read_linear_rgb(path: str | Path) -> np.ndarray:
    """Linear RGB float32 (H, W, 3) of an image file (``read_image`` without its flag)."""
    return read_image(path)[0]


def _read_with_imageio(path: Path) -> np.ndarray:
    """The first image in ``path`` at its stored type: OpenCV for ``_OPENCV_SUFFIXES``, else Pillow,
    converted to RGB (as CMYK, YCbCr and palette images need) unless its samples have more than 8 bits."""
    import imageio.v3 as iio

    if path.suffix.lower() in _OPENCV_SUFFIXES:
        import cv2

        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # its log would repeat our error
        return iio.imread(path, plugin="opencv", index=0, flags=cv2.IMREAD_UNCHANGED)
    mode = str(iio.immeta(path, plugin="pillow", index=0).get("mode", ""))
    deep = mode.startswith(_DEEP_PILLOW_MODES)
    return iio.imread(path, plugin="pillow", index=0, mode=None if deep else "RGB")


def _rgb_channels(pixels: np.ndarray, path: Path) -> np.ndarray:
    """(H, W, 3) of an image read as (H, W) grey, (H, W, 1|2) grey (+ alpha) or (H, W, 3|4) RGB (+ alpha)."""
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if pixels.ndim != 3 or pixels.shape[2] not in (1, 2, 3, 4) or 0 in pixels.shape:
        raise UserError(f"{path}: not a grey or RGB image (array of shape {pixels.shape})")
    if pixels.shape[2] <= 2:
        return np.repeat(pixels[..., :1], 3, axis=2)
    return pixels[..., :3]
