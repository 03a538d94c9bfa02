"""The bundled lens library: every prescription file shipped in ``optics/formats/lenses``, summarised.

A library entry is what ``lens list`` shows: focal length and f-number (paraxial, d line), the
image circle, the number of glass elements and of aspheric surfaces, and the source line from the
file's header comment. The *image circle* is the diameter of the film circle, focused at infinity,
within which the relative illumination (vignetting x cos^4, ``realistic.optics.field_curves``) stays
at least ``IMAGE_CIRCLE_ILLUMINATION`` of the centre's.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from realistic.errors import LensFileError
from realistic.optics.field_curves import field_curves
from realistic.optics.formats import BUNDLED_LENSES, load_lens
from realistic.optics.formats.pbrt_dat import parse_prescription
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data

#: Relative illumination (of the centre's) that bounds the image circle.
IMAGE_CIRCLE_ILLUMINATION = 0.1
_PACKAGE = "realistic.optics.formats"


def library_files() -> dict[str, str]:
    """Library name -> file name of every bundled ``.dat`` prescription: the short names of
    ``BUNDLED_LENSES`` where one exists, else the file name without ``.dat``."""
    short = {file: name for name, file in BUNDLED_LENSES.items()}
    files = sorted(p.name for p in (resources.files(_PACKAGE) / "lenses").iterdir() if p.name.endswith(".dat"))
    return {short.get(f, f[:-len(".dat")]): f for f in files}


def read_library_lens(name: str) -> tuple[LensSystem, str]:
    """(lens, header comment text) of library lens ``name`` (a key of ``library_files``)."""
    file = library_files()[name]
    text = (resources.files(_PACKAGE) / "lenses" / file).read_text(encoding="utf-8")
    comments = [line.lstrip("#").strip() for line in text.splitlines() if line.startswith("#")]
    # Column-name lines ("Columns: ...", "radius<TAB>sep<TAB>n ...") say nothing about the source.
    header = " ".join(c for c in comments if c and not c.startswith("Columns") and "\t" not in c)
    return parse_prescription(text, path=f"{name} ({file})", name=name), header


def element_count(lens: LensSystem) -> int:
    """Glass elements: runs of one glass between surfaces (a cemented doublet counts two)."""
    glass = lens.index_d != 1.0
    starts = glass & np.concatenate([[True], lens.index_d[1:] != lens.index_d[:-1]])
    return int(np.count_nonzero(starts))


def image_circle_mm(lens: LensSystem, points: int = 41, samples: int = 4000) -> float:
    """Diameter (mm) of the image circle (see the module docstring), searched out to 4 x EFL."""
    efl = abs(paraxial_data(lens).efl_mm)
    rows = field_curves(lens, film_diagonal_mm=min(8.0 * efl, 1000.0), points=points, samples=samples)
    radii = np.array([r["film_radius_mm"] for r in rows])
    light = np.array([r["relative_illumination"] for r in rows])
    below = np.flatnonzero(light < IMAGE_CIRCLE_ILLUMINATION)
    if len(below) == 0:
        return 2.0 * float(radii[-1])
    k = int(below[0])
    # Linear interpolation between the last sample above the threshold and the first below it.
    t = (light[k - 1] - IMAGE_CIRCLE_ILLUMINATION) / (light[k - 1] - light[k])
    return 2.0 * float(radii[k - 1] + t * (radii[k] - radii[k - 1]))


def library_entry(name: str) -> dict:
    """What ``lens list`` reports for library lens ``name``."""
    lens, header = read_library_lens(name)
    para = paraxial_data(lens)
    return {
        "name": name, "file": library_files()[name], "focal_length_mm": para.efl_mm, "f_number": para.f_number,
        "image_circle_mm": image_circle_mm(lens), "elements": element_count(lens),
        "aspheres": int(getattr(lens, "asphere_count", 0)), "source": header,
    }



def resolve_lens(name_or_path: str) -> LensSystem:
    """A library lens by name (``library_files``), else whatever ``load_lens`` accepts."""
    names = library_files()
    if name_or_path in names and name_or_path not in BUNDLED_LENSES:
        return read_library_lens(name_or_path)[0]
    try:
        exists = Path(name_or_path).exists()
    except (OSError, ValueError):
        exists = True  # let load_lens say what is wrong with the path
    if not exists and name_or_path not in BUNDLED_LENSES:
        raise LensFileError(name_or_path, None, f"no such lens file, and not a library lens name "
                                                f"({', '.join(names)}; 'lens list' describes them)")
    return load_lens(name_or_path)
