"""Lens file formats; ``load_lens`` dispatches by bundled name or file extension.

Readers import the lens model (``realistic.optics.lens``) and never the reverse.

- ``pbrt_dat``: pbrt-style ``.dat`` prescriptions (and any extension other than those below).
- ``zemax``: Zemax sequential ``.zmx`` files (ASCII or UTF-16).
- ``json_lens``: isetlens / pbrt-v4 omni ``.json`` prescriptions (aspheres included).
- ``codev``: CODE V ``.seq`` sequence files.
- ``lenses/``: the bundled prescriptions, package data, named by ``bundled_lens_files``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from realistic.core.input_files import decode_text, read_input
from realistic.errors import LensFileError, UserError
from realistic.optics.formats.codev import format_codev, parse_codev
from realistic.optics.formats.json_lens import format_json_lens, parse_json_lens
from realistic.optics.formats.pbrt_dat import format_prescription, parse_prescription
from realistic.optics.formats.zemax import decode_zmx, format_zmx, parse_zmx
from realistic.optics.lens import LensSystem

#: Writers by file extension (``lens convert``); readers dispatch on the same extensions.
WRITERS = {".dat": format_prescription, ".json": format_json_lens, ".zmx": format_zmx, ".seq": format_codev}

#: Short names of the bundled prescriptions (package data in ``lenses/`` beside this module).
BUNDLED_LENSES = {
    "dgauss": "dgauss.50mm.dat",
    "wide": "wide.22mm.dat",
    "fisheye": "fisheye.10mm.dat",
    "telephoto": "telephoto.250mm.dat",
    "dgauss100": "dgauss100.dat",
    # aspheric lenses (JSON): source, example and what was set beyond the source in each file's description
    "phone-us10101561": "phone.us10101561.e3.json",
    "canon-ef24-f1.4": "canon-ef24.us20100033848.e3.json",
    "canon-rf50-f1.2": "canon-rf50.us20190265441.e2.json",
}


def bundled_lens_files() -> dict[str, str]:
    """Name -> file of every bundled prescription: the short names of ``BUNDLED_LENSES``, and every
    other file under its file name less the extension (``tessar.100mm``); ``lens list`` shows them."""
    short = {file: name for name, file in BUNDLED_LENSES.items()}
    files = sorted(p.name for p in (resources.files(__package__) / "lenses").iterdir()
                   if p.name.endswith((".dat", ".json")))
    return {short.get(f, f.rsplit(".", 1)[0]): f for f in files}


def load_lens(name_or_path: str | Path) -> LensSystem:
    """Load a bundled lens by name (``dgauss``, ``tessar.100mm``, ...) or a prescription file by path.

    A path ending in ``.zmx`` is read as a Zemax sequential file, ``.json`` as an isetlens/omni
    prescription, ``.seq`` as a CODE V sequence file; anything else as a pbrt-style ``.dat``.
    """
    key = str(name_or_path)
    bundled = bundled_lens_files()
    if key in bundled:
        return parse_text(bundled_lens_text(key), f"{key} ({bundled[key]})", Path(bundled[key]).suffix, name=key)
    path = Path(key)
    data = read_input(path, "lens file", f", and not a bundled lens name ({', '.join(bundled)}; 'realistic lens "
                      f"list' describes them)", LensFileError)
    if path.suffix.lower() == ".zmx":
        return parse_zmx(decode_zmx(data, key), key)
    text = decode_text(data, key, "the lens file", LensFileError)
    return parse_text(text, key, path.suffix.lower())


def bundled_lens_text(name: str) -> str:
    """The text of bundled lens ``name`` (a key of ``bundled_lens_files``)."""
    return (resources.files(__package__) / "lenses" / bundled_lens_files()[name]).read_text(encoding="utf-8")


def parse_text(text: str, path: str, suffix: str, name: str | None = None) -> LensSystem:
    """Parse prescription text by its file extension (``.json``, ``.seq``, else ``.dat``)."""
    if suffix == ".json":
        return parse_json_lens(text, path, name)
    if suffix == ".seq":
        return parse_codev(text, path, name)
    return parse_prescription(text, path=path, name=name)


def format_lens(lens: LensSystem, suffix: str) -> str:
    """``lens`` as the text of a ``.dat``, ``.json``, ``.zmx`` or ``.seq`` file (exact floats)."""
    if suffix not in WRITERS:
        raise UserError(f"cannot write a lens as {suffix or 'a file without an extension'!r}: "
                        f"use one of {', '.join(WRITERS)}")
    return WRITERS[suffix](lens)
