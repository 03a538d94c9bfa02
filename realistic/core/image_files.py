"""Image files: OpenEXR with metadata and PNG previews (written atomically), EXR and other images read."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from realistic.core.atomic_files import write_atomically
from realistic.errors import UserError

Metadata = dict[str, str | int | float]


def write_exr(path: Path, image: np.ndarray, metadata: Metadata | None = None) -> None:
    """float32 RGB OpenEXR (ZIP) with ``metadata`` as extra header attributes."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **(metadata or {})}
    pixels = np.ascontiguousarray(image, dtype=np.float32)
    write_atomically(path, lambda name: OpenEXR.File(header, {"RGB": pixels}).write(name))


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


def auto_exposure(image: np.ndarray) -> float:
    """Exposure in stops that maps the 97th percentile of luminance to 0.8 (0 for a black image)."""
    luminance = image @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    bright = float(np.percentile(luminance, 97))
    return float(np.log2(0.8 / bright)) if bright > 0 else 0.0


def write_png(path: Path, image: np.ndarray, exposure_stops: float) -> None:
    """8-bit sRGB PNG preview of linear ``image`` scaled by 2^exposure_stops."""
    from PIL import Image

    encoded = srgb_encode(image.astype(np.float32) * np.float32(2.0**exposure_stops))
    rgb = np.round(encoded * 255).astype(np.uint8)
    write_atomically(path, lambda name: Image.fromarray(rgb, "RGB").save(name, format="PNG"))


def read_linear_rgb(path: str | Path) -> np.ndarray:
    """Linear RGB float32 (H, W, 3): EXR as stored, other formats (PNG, JPEG, ...) sRGB-decoded."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such texture file")
    if path.suffix.lower() == ".exr":
        return read_exr(path)[0]
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as img:
            rgb = np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0
    except (OSError, UnidentifiedImageError) as err:
        raise UserError(f"{path}: not a readable image ({err})") from None
    return srgb_decode(rgb).astype(np.float32)
