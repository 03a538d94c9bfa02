"""Image output: OpenEXR with metadata and PNG previews, written atomically; EXR input."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

import numpy as np

from realistic.errors import UserError

Metadata = dict[str, str | int | float]


def check_writable(path: Path) -> None:
    """Raise UserError now, before any work, if ``path`` cannot be written."""
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise UserError(f"{path}: cannot write the image: it is a directory")
    if not folder.is_dir():
        raise UserError(f"{path}: cannot write the image: directory {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise UserError(f"{path}: cannot write the image: permission denied")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomically(path: Path, write: Callable[[str], None]) -> None:
    """Call ``write(temporary_path)`` next to ``path``, then rename; no partial file is left on error."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix,
                                         dir=path.parent if str(path.parent) else ".")
    os.close(handle)
    try:
        write(temporary)
        os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes 0600: give the file ordinary permissions
        os.replace(temporary, path)
    except BaseException as err:
        Path(temporary).unlink(missing_ok=True)
        if isinstance(err, OSError):
            raise UserError(f"{path}: cannot write: {err.strerror or err}") from None
        raise


def write_exr(path: Path, image: np.ndarray, metadata: Metadata) -> None:
    """float32 RGB OpenEXR (ZIP) with ``metadata`` as extra header attributes."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **metadata}
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
