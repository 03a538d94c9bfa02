"""The bundled lens library: every prescription file shipped in ``optics/formats/lenses``, summarised.

A library entry is what ``lens list`` shows: focal length and f-number (paraxial, d line), the
image circle, the number of glass elements and of aspheric surfaces, and the source line from the
file's header comment. The *image circle* is the diameter of the film circle, focused at infinity,
within which the relative illumination (vignetting x cos^4, ``realistic.optics.field_curves``) stays
at least ``IMAGE_CIRCLE_ILLUMINATION`` of the centre's.
"""

from __future__ import annotations

import json

import numpy as np

from realistic.optics.field_curves import field_curves
from realistic.optics.formats import bundled_lens_files, bundled_lens_text, load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data

#: Relative illumination (of the centre's) that bounds the image circle.
IMAGE_CIRCLE_ILLUMINATION = 0.1


def read_library_lens(name: str) -> tuple[LensSystem, str]:
    """(lens, source text) of bundled lens ``name``: the header comments of a ``.dat`` file (less its
    column-name lines), the description of a ``.json`` one."""
    text = bundled_lens_text(name)
    if bundled_lens_files()[name].endswith(".json"):
        header = str(json.loads(text).get("description", ""))
    else:
        comments = [line.lstrip("#").strip() for line in text.splitlines() if line.startswith("#")]
        header = " ".join(c for c in comments if c and not c.startswith("Columns") and "\t" not in c)
    return load_lens(name), header


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
        "name": name, "file": bundled_lens_files()[name], "focal_length_mm": para.efl_mm, "f_number": para.f_number,
        "image_circle_mm": image_circle_mm(lens), "elements": element_count(lens),
        "aspheres": int(getattr(lens, "asphere_count", 0)), "source": header,
    }

