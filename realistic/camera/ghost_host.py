"""OpenCL host of ghost tracing: ``kernels/ghost.cl`` on a ``Device``, for one lens.

The float64 reference is ``realistic.optics.ghosts`` (``trace_ghost``, ``trace_direct``); a
``GhostKernel`` traces the same paths in float32 and returns the same ``GhostTrace``. A path is a
table of steps (``STEPS``), one row per surface met in the order ``ghosts.path_steps`` gives, packed
per launch for the path, film distance and wavelength: the program is built once per lens (its stop's
shape is compiled in, as ``kernels/lens.cl`` has it), and every path, focus and wavelength reuses it.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from realistic.camera.opencl_host import stop_lines
from realistic.device.opencl import LOCAL_SIZE, Device, cl, kernel_source, whole_groups
from realistic.device.tables import Table, constant_defines
from realistic.optics.asphere import COEFFICIENT_COUNT
from realistic.optics.coating import DESIGN_WAVELENGTH_NM, IDEAL, LAYER, MGF2_INDEX, mgf2_index
from realistic.optics.ghosts import GHOST_WAVELENGTH_NM, GhostPath, GhostTrace, path_steps
from realistic.optics.lens import LensSystem

KERNEL_FILE = "ghost.cl"
#: One row per surface a path meets, in order (float32): its shape (``kind``: ``KINDS``; ``radius``
#: of a sphere; base ``curvature``, ``conic`` and the coefficients A4 .. A20 of an asphere), its clear
#: aperture (``ap2``, the squared semi-diameter; ``stop`` 1 at the aperture stop, whose opening is
#: ``STOP_INSIDE``), ``ahead`` (0 where it touches the surface met before, as in ``lens.cl``), what the
#: ray does there (``action``: ``ACTIONS``), the coating model (``realistic.optics.coating``), the
#: media on the ray's side and the far side (rows of ``media_table``: 0 the air in front of the lens,
#: k + 1 the medium behind surface k), and the axial distance from this vertex to the next one's (to
#: the film plane after the last), + toward the scene.
STEPS = Table("STEP", np.float32, (("kind", 1), ("radius", 1), ("curvature", 1), ("conic", 1),
                                   ("asphere", COEFFICIENT_COUNT), ("ap2", 1), ("stop", 1), ("ahead", 1),
                                   ("action", 1), ("model", 1), ("medium_from", 1), ("medium_to", 1),
                                   ("shift", 1)))
KINDS = ("plane", "sphere", "asphere")
ACTIONS = ("pass", "refract", "reflect")
#: Newton steps on an asphere, and the largest |F| (mm) accepted as a hit: ``kernels/lens.cl``'s.
ASPHERE_ITERATIONS = 6
ASPHERE_TOLERANCE_MM = 1e-4
#: Rays each work item traces side by side (``kernels/ghost.cl``, ``trace_path``).
RAYS_PER_ITEM = 4
#: Rows of the kernel's input (origin x, y, w; direction; wavelength) and output (film x, y; direction;
#: weight; passed).
IN_ROWS, OUT_ROWS = 7, 7
#: Spacing (nm) of the media's indices tabulated for a launch (``media_table``): linear interpolation
#: between nodes this close is off by under 1e-7 in n for the glasses' formulas (n'' ~ 1e-6 per nm^2).
INDEX_SPACING_NM = 0.5


def _c_float(value: float) -> str:
    """A float32 C literal holding exactly np.float32(value)."""
    return repr(float(np.float32(value))) + "f"


def ghost_header(lens: LensSystem) -> str:
    """The ``#define``s that ``ghost.cl`` needs for ``lens``: the table's offsets, the enumerations,
    the coating layer's row of the media table, the asphere iteration, whether the lens has aspheres and
    layer coatings at all (``ASPHERES``, ``LAYERS``: the kernel compiles only the shapes and coatings it
    meets), and the stop's opening (``stop_lines``; a round stop's squared radius is its row's ``ap2``)."""
    lines = [STEPS.defines(), constant_defines("KIND", KINDS), constant_defines("ACTION", ACTIONS),
             "#define MODEL_IDEAL 0\n#define MODEL_BARE 1\n#define MODEL_LAYER 2\n",
             f"#define LAYER_MEDIUM {lens.surface_count + 1}\n",
             f"#define PI_LAMBDA0_OVER_NL0 {_c_float(math.pi * DESIGN_WAVELENGTH_NM / MGF2_INDEX)}\n",
             f"#define ASPHERE_ITERATIONS {ASPHERE_ITERATIONS}\n#define ASPHERE_TERMS {COEFFICIENT_COUNT}\n",
             f"#define ASPHERE_TOLERANCE_MM {_c_float(ASPHERE_TOLERANCE_MM)}\n",
             f"#define ASPHERES {int(np.any(lens.aspheric))}\n",
             f"#define LAYERS {int(np.any(lens.interface_models == LAYER))}\n",
             "#define STOP_R2 (s[STEP_AP2])\n", "\n".join(stop_lines(lens)) + "\n"]
    return "".join(lines)


def media_table(lens: LensSystem, wavelengths_nm: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Each medium's index (rows: air in front, the medium behind each surface, then the coating
    layer's MgF2, ``LAYER_MEDIUM``) at nodes
    ``INDEX_SPACING_NM`` apart covering ``wavelengths_nm`` (at least two), with the first node's
    wavelength and the spacing: the kernel interpolates each ray's index linearly between them."""
    low, high = float(np.min(wavelengths_nm)), float(np.max(wavelengths_nm))
    nodes = max(2, math.ceil((high - low) / INDEX_SPACING_NM) + 1)
    wavelengths = low + INDEX_SPACING_NM * np.arange(nodes)
    behind = np.broadcast_to(lens.index_at(wavelengths).reshape(lens.surface_count, -1), (lens.surface_count, nodes))
    return np.concatenate([np.ones((1, nodes)), behind, mgf2_index(wavelengths)[None]]), low, INDEX_SPACING_NM


def step_table(lens: LensSystem, film_distance_mm: float, path: GhostPath | None, media: np.ndarray) -> np.ndarray:
    """``STEPS`` rows (float32) of ``path`` (None: the direct path), for the indices ``media``
    (``media_table``: a surface between media that are the same at every node, with no coating, is
    passed straight through)."""
    steps = path_steps(lens, path)
    surfaces = np.array([surface for surface, _ in steps])
    reflects = np.array([reflects for _, reflects in steps])
    # the ray travels toward the film before the first reflection and after the second
    toward_film = (np.cumsum(reflects) - reflects) % 2 == 0
    medium_from = np.where(toward_film, surfaces, surfaces + 1)
    medium_to = np.where(toward_film, surfaces + 1, surfaces)
    models = lens.interface_models[surfaces]
    same = np.all(media[medium_from] == media[medium_to], axis=1)
    action = np.where(reflects, ACTIONS.index("reflect"),
                      np.where(same & (models == IDEAL), ACTIONS.index("pass"), ACTIONS.index("refract")))
    radius = lens.radius_mm[surfaces]
    flat = (radius == 0) | ~np.isfinite(radius)
    kind = np.where(lens.aspheric[surfaces], KINDS.index("asphere"), np.where(flat, 0, KINDS.index("sphere")))
    vertex_z = np.concatenate([lens.vertex_z_mm(film_distance_mm)[surfaces], [0.0]])
    previous = np.concatenate([[-1], surfaces[:-1]])
    gaps = lens.thickness_mm[np.minimum(np.maximum(previous, 0), surfaces)]
    return STEPS.pack(len(steps), kind=kind, radius=np.where(flat, 0.0, radius),
                      curvature=np.where(flat, 0.0, 1.0 / np.where(flat, 1.0, radius)),
                      conic=lens.conic[surfaces], asphere=lens.aspheric_coefficients[surfaces],
                      ap2=(lens.aperture_mm[surfaces] / 2) ** 2, stop=surfaces == lens.stop,
                      ahead=(previous < 0) | (gaps != 0), action=action, model=models, medium_from=medium_from,
                      medium_to=medium_to, shift=vertex_z[:-1] - vertex_z[1:])


class GhostKernel:
    """``ghost.cl`` built for one lens on ``device``; ``trace`` is ``ghosts.trace_ghost`` in float32.
    Safe to call from several threads (launches are serialised on one lock)."""

    def __init__(self, lens: LensSystem, device: Device | None = None, rays_per_item: int = RAYS_PER_ITEM):
        """``device``: where to build and launch (None: ``Device.for_spec()``, the default device);
        ``rays_per_item``: rays each work item traces side by side (``kernels/ghost.cl``)."""
        self.lens, self.device, self.rays_per_item = lens, device or Device.for_spec(), rays_per_item
        self.queue = self.device.queue()
        program = self.device.build_program(f"#define RAYS_PER_ITEM {rays_per_item}\n" + ghost_header(lens)
                                            + kernel_source(KERNEL_FILE), KERNEL_FILE)
        self._kernel = cl.Kernel(program, "trace_path")
        self._lock = threading.Lock()

    def trace(self, film_distance_mm: float, path: GhostPath | None, origins: np.ndarray, directions: np.ndarray,
              wavelength_nm: float | np.ndarray = GHOST_WAVELENGTH_NM) -> GhostTrace:
        """Rays (lens frame, float64 or float32, N x 3 each) along ``path`` (None: the direct path)
        onto the film, at one wavelength or one per ray (N,), as ``ghosts.trace_ghost`` traces them."""
        lens = self.lens
        origins = np.asarray(origins, np.float64).reshape(-1, 3)
        directions = np.asarray(directions, np.float64).reshape(-1, 3)
        count = len(origins)
        if count == 0:
            return GhostTrace(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, bool))
        wavelengths = np.broadcast_to(np.asarray(wavelength_nm, np.float64), (count,))
        media, first_nm, spacing_nm = media_table(lens, wavelengths)
        steps = step_table(lens, film_distance_mm, path, media)
        stride = self.rays_per_item * whole_groups(-(-count // self.rays_per_item))
        rays = np.zeros((IN_ROWS, stride), np.float32)
        rays[0:2, :count] = origins[:, :2].T
        # the axial position relative to the front vertex (every path meets the front surface first), in float64
        rays[2, :count] = origins[:, 2] - lens.vertex_z_mm(film_distance_mm)[0]
        rays[3:6, :count] = (directions / np.linalg.norm(directions, axis=1, keepdims=True)).T
        rays[6] = first_nm  # (the padding's too)
        rays[6, :count] = wavelengths
        out = np.empty((OUT_ROWS, stride), np.float32)
        with self._lock:
            table = self.device.copied_buffer(steps, np.float32)
            indices = self.device.copied_buffer(media, np.float32)
            given = self.device.copied_buffer(rays, np.float32)
            self.device.run_into(self.queue, self._kernel, (stride // self.rays_per_item,), (LOCAL_SIZE,),
                                 (np.uint32(count), np.uint32(len(steps)), table, indices, np.uint32(media.shape[1]),
                                  np.float32(first_nm), np.float32(1.0 / spacing_nm), np.uint32(stride), given),
                                 (out,))
        passed = out[6, :count] > 0
        film = np.where(passed[:, None], out[0:2, :count].T, np.nan)
        direction = np.where(passed[:, None], out[2:5, :count].T, np.nan)
        return GhostTrace(film.astype(np.float64), direction.astype(np.float64),
                          out[5, :count].astype(np.float64), passed)
