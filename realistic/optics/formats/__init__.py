"""Lens file formats; ``load_lens`` dispatches by bundled name or file extension.

Readers import the lens model (``realistic.optics.lens``) and never the reverse.

- ``pbrt_dat``: pbrt-style ``.dat`` prescriptions (and any extension other than those below).
- ``zemax``: Zemax sequential ``.zmx`` files (ASCII or UTF-16).
- ``lenses/``: the bundled prescriptions, package data, named by ``BUNDLED_LENSES``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from realistic.errors import LensFileError
from realistic.optics.formats.pbrt_dat import parse_prescription
from realistic.optics.formats.zemax import decode_zmx, parse_zmx
from realistic.optics.lens import LensSystem

#: Short names of the bundled prescriptions (package data in ``lenses/`` beside this module).
BUNDLED_LENSES = {
    "dgauss": "dgauss.50mm.dat",
    "wide": "wide.22mm.dat",
    "fisheye": "fisheye.10mm.dat",
    "telephoto": "telephoto.250mm.dat",
    "dgauss100": "dgauss100.dat",
}


def load_lens(name_or_path: str | Path) -> LensSystem:
    """Load a bundled lens by short name (``dgauss``, ``wide``, ...) or a prescription file by path.

    A path ending in ``.zmx`` is read as a Zemax sequential file (``realistic.optics.formats.zemax``).
    """
    key = str(name_or_path)
    if key in BUNDLED_LENSES:
        resource = resources.files(__package__) / "lenses" / BUNDLED_LENSES[key]
        return parse_prescription(resource.read_text(encoding="utf-8"), path=f"{key} ({BUNDLED_LENSES[key]})",
                                  name=key)
    path = Path(key)
    try:
        is_dir, is_file, exists = path.is_dir(), path.is_file(), path.exists()
    except (OSError, ValueError) as err:  # a name too long for the system, say
        raise LensFileError(key, None, f"cannot read: {getattr(err, 'strerror', None) or err}") from None
    if is_dir:
        raise LensFileError(key, None, "is a directory, not a lens file")
    if exists and not is_file:
        raise LensFileError(key, None, "is not a regular file (a lens file is a .dat or .zmx prescription)")
    if not is_file:
        names = ", ".join(BUNDLED_LENSES)
        raise LensFileError(key, None, f"no such lens file, and not a bundled lens name ({names})")
    try:
        data = path.read_bytes()
        if path.suffix.lower() == ".zmx":
            return parse_zmx(decode_zmx(data, key), key)
        text = data.decode("utf-8-sig")
    except (OSError, UnicodeDecodeError) as err:
        raise LensFileError(key, None, f"cannot read: {err}") from None
    return parse_prescription(text, path=key)
