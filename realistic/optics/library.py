"""The bundled lens library: every prescription file shipped in ``optics/formats/lenses``, summarised.

A library entry is what ``lens list`` shows: focal length and f-number (paraxial, d line), the
image circle, the number of glass elements and of aspheric surfaces, and the source line from the
file's header comment. The *image circle* is the diameter of the film circle, focused at infinity,
within which the relative illumination (vignetting x cos^4, ``realistic.optics.field_curves``) stays
at least ``IMAGE_CIRCLE_ILLUMINATION`` of the centre's.
"""

from __future__ import annotations

import json
import math
from typing import TypedDict

import numpy as np

from realistic.core.disk_cache import cache_key, load_arrays, store_arrays
from realistic.optics.formats import bundled_lens_files, bundled_lens_text, load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.sampling import camera_weight, exit_pupil_table
from realistic.optics.tracer import trace_from_film

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


def image_circle_mm(lens: LensSystem, points: int = 9, samples: int = 4000) -> float:
    """Diameter (mm) of the image circle (see the module docstring), searched out to 4 x EFL.

    The relative illumination is traced at ``points`` film radii from the centre to the edge (one
    batch), then the first interval where it falls below the threshold is bisected
    ``BISECTIONS`` times and the crossing interpolated linearly in the last bracket: about a third
    of the rays of a 41-point field curve, at a finer final spacing. A dip narrower than the coarse
    spacing is missed, as it was by the 41-point scan when narrower than its spacing. Results are
    kept in the disk cache (``realistic.core.disk_cache``), keyed by the prescription.
    """
    key = cache_key("image-circle", IMAGE_CIRCLE_VERSION, _lens_key(lens), points, samples)
    stored = load_arrays(key)
    if stored is not None and set(stored) == {"diameter_mm"} and stored["diameter_mm"].shape == ():
        diameter = float(stored["diameter_mm"])  # an entry is trusted only within what the search returns
        if 0 <= diameter <= _search_diagonal_mm(lens):
            return diameter
    diameter = _image_circle_traced(lens, points, samples)
    store_arrays(key, {"diameter_mm": np.asarray(diameter)})
    return diameter


#: Bump when the image-circle search changes, so cached diameters are recomputed.
IMAGE_CIRCLE_VERSION = 1
#: Halvings of the coarse interval that holds the threshold crossing.
BISECTIONS = 6


def _lens_key(lens: LensSystem) -> bytes:
    """Everything of a prescription that the image circle depends on, as bytes."""
    arrays = (lens.radius_mm, lens.thickness_mm, lens.index_d, lens.abbe_v, lens.aperture_mm, lens.conic,
              lens.aspheric_coefficients) + ((lens.paraxial_power_per_mm,) if lens.paraxial.any() else ())
    shape = repr((lens.stop, lens.stop_shape)).encode()
    return b"".join(np.ascontiguousarray(a, dtype=np.float64).tobytes() for a in arrays) + shape


def _search_diagonal_mm(lens: LensSystem) -> float:
    """The film diagonal the image circle is searched in: 8 x EFL, at most 1000 mm."""
    return min(8.0 * abs(paraxial_data(lens).efl_mm), 1000.0)


def _image_circle_traced(lens: LensSystem, points: int, samples: int) -> float:
    """The image-circle diameter by a coarse scan and a bisection of relative illumination."""
    film_diagonal = _search_diagonal_mm(lens)
    film_distance = film_distance_for_focus(lens, math.inf)
    table = exit_pupil_table(lens, film_distance, film_diagonal)
    rng = np.random.default_rng(0)
    u1, u2 = rng.random(samples), rng.random(samples)

    def illumination(radii: np.ndarray) -> np.ndarray:
        """Mean camera weight at each film radius (same pupil samples at every radius)."""
        film_xy = np.column_stack([np.repeat(radii, samples), np.zeros(len(radii) * samples)])
        film = np.column_stack([film_xy, np.zeros(len(film_xy))])
        targets, area = table.sample(film_xy, np.tile(u1, len(radii)), np.tile(u2, len(radii)))
        passed = trace_from_film(lens, film_distance, film, targets - film).passed
        weight = np.where(passed, camera_weight(film, targets, area, table.plane_z_mm), 0.0)
        return weight.reshape(len(radii), samples).mean(axis=1)

    radii = np.linspace(0.0, film_diagonal / 2 * 0.999, points)
    light = illumination(radii)
    threshold = IMAGE_CIRCLE_ILLUMINATION * light[0]
    below = np.flatnonzero(light < threshold)
    if len(below) == 0:
        return 2.0 * float(radii[-1])
    k = int(below[0])
    lo, hi, light_lo, light_hi = radii[k - 1], radii[k], light[k - 1], light[k]
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        light_mid = illumination(np.array([mid]))[0]
        if light_mid < threshold:
            hi, light_hi = mid, light_mid
        else:
            lo, light_lo = mid, light_mid
    # Linear interpolation between the last radius above the threshold and the first below it.
    t = (light_lo - threshold) / (light_lo - light_hi)
    return 2.0 * float(lo + t * (hi - lo))


class LibraryEntry(TypedDict):
    """What ``lens list`` reports for one library lens."""

    name: str
    file: str
    focal_length_mm: float
    f_number: float
    image_circle_mm: float
    elements: int
    aspheres: int
    source: str


def library_entry(name: str) -> LibraryEntry:
    """What ``lens list`` reports for library lens ``name``."""
    lens, header = read_library_lens(name)
    para = paraxial_data(lens)
    return {
        "name": name, "file": bundled_lens_files()[name], "focal_length_mm": para.efl_mm, "f_number": para.f_number,
        "image_circle_mm": image_circle_mm(lens), "elements": element_count(lens),
        "aspheres": lens.asphere_count, "source": header,
    }

