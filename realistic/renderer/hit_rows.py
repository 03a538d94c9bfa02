"""The hits on one material, and colours placed back in their rows: what the device textures need
around ``EwaKernel.at_hits`` (``DirectLighting._host_albedo`` and ``BounceKernel._albedo`` both).

Each is a numba loop (``core.jit``: one pass, where numpy made several over every ray), or its numpy
form where the loops do not run compiled (``core.jit.use_compiled_loops``), giving the same rows."""

from __future__ import annotations

import numpy as np

from realistic.core.jit import compiled, compiled_loops


def _rows_on_material(geom: np.ndarray, geom_material: np.ndarray, material: int, rows: np.ndarray) -> int:
    """Write into ``rows`` (int32, at least len(geom)) in order the rays whose closest hit is on an
    instance (embree geometry id 0 .. len(geom_material) - 1) of material index ``material``, and
    return how many."""
    count = 0
    for i in range(len(geom)):
        g = geom[i]
        if 0 <= g < len(geom_material) and geom_material[g] == material:
            rows[count] = i
            count += 1
    return count


def _place_rows(values: np.ndarray, rows: np.ndarray, out: np.ndarray) -> None:
    """out[rows] = values (rows of 3 float32): numpy's fancy-index store cost as much as the pick."""
    for i in range(len(rows)):
        for c in range(3):
            out[rows[i], c] = values[i, c]


def rows_on_material(geom: np.ndarray, geom_material: np.ndarray, material: int, rows: np.ndarray) -> int:
    """``_rows_on_material``, compiled or in numpy: the same rows in the same order."""
    if compiled_loops():
        return int(compiled(_rows_on_material)(geom, geom_material, material, rows))
    surface = (geom >= 0) & (geom < len(geom_material))
    picked = np.flatnonzero(surface)
    picked = picked[geom_material[geom[picked]] == material]
    rows[:len(picked)] = picked
    return len(picked)


def place_rows(values: np.ndarray, rows: np.ndarray, out: np.ndarray) -> None:
    """``_place_rows``, compiled, or numpy's fancy-index store."""
    if compiled_loops():
        compiled(_place_rows)(values, rows, out)
    else:
        out[rows] = values


def compile_row_loops() -> None:
    """Compile (or load from numba's cache) both loops for the argument types their callers pass, on
    no rows: a render does this on a render thread as it starts (``runner.compile_pass_loops``)."""
    rows, picked = np.empty((0, 3), np.float32), np.empty(0, np.int32)
    compiled(_rows_on_material)(picked, np.empty(0, np.int64), 0, picked)
    compiled(_place_rows)(rows, picked, rows)
