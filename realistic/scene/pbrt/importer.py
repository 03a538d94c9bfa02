"""pbrt scenes (v1 to v4 subset) turned into our Scene and camera.

Cameras: ``realistic`` as the file's dialect writes it (``dialect.RealisticCameraConvention``: the
classic homework's ``specfile``, ``filmdistance``, ``aperture_diameter``, ``filmdiag`` in mm from
the front lens vertex, or pbrt-v3/v4's ``lensfile``, ``aperturediameter``, ``focusdistance`` in
metres from the film centre with ``Film "diagonal"``, and pbrt-v4's ``aperture`` shape), and
``perspective`` (pinhole or thin lens). Shapes: pbrt's analytic shapes tessellated, trianglemesh,
plymesh and pbrt-v4's bilinearmesh (two triangles per patch).
Everything the renderer cannot honour is reported once with file and line, and the render goes on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import validation
from realistic.core.image_files import read_image, read_linear_rgb
from realistic.core.pixel_filter import PixelFilter, filter_name
from realistic.core.transforms import scale, translate
from realistic.core.validation import MAX_LIGHT_SAMPLES
from realistic.errors import LensFileError, UserError
from realistic.optics.formats import BUNDLED_LENSES, load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus
from realistic.optics.stop_shape import StopShape, transmission_stop
from realistic.scene.lights import EmissiveInstance
from realistic.scene.materials import SurfaceMaterial
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import AreaLight, CheckerTexture, Material, Mesh, Scene
from realistic.scene.pbrt.dialect import (
    DEFAULT_FILM_DIAGONAL_MM,
    PBRT3_DEFAULT_APERTURE_MM,
    PBRT3_DEFAULT_FOCUS_M,
    V4_BUILTIN_APERTURES,
    Dialect,
    choose_dialect,
    v4_builtin_aperture,
)
from realistic.scene.pbrt.imagemap import imagemap_texture
from realistic.scene.pbrt.lexer import PbrtSyntaxError
from realistic.scene.pbrt.lights import import_integrator, import_lights
from realistic.scene.pbrt.materials import build_material
from realistic.scene.pbrt.parser import Declaration, Params, PbrtScene, ShapeRecord, parse_pbrt, resolve_file
from realistic.scene.shapes import cone, disk, sphere

GREY = (0.5, 0.5, 0.5)
#: Shapes pbrt defines by an equation, whose front is their object-space outside.
QUADRICS = ("sphere", "cone", "cylinder")
#: Farthest a shape or the camera may reach from the world origin: the renderer intersects in single
#: precision, where products of larger coordinates overflow (float32 holds up to 3.4e38).
MAX_WORLD_COORDINATE = 1e18


def _corners(vertices: np.ndarray) -> np.ndarray:
    """The 8 corners of the bounding box of (N, 3) points, as (8, 4) homogeneous points."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def _sound(mesh: Mesh) -> bool:
    """Whether a tessellated or loaded mesh has finite points, faces, unit normals and finite uv."""
    if not (len(mesh.vertices) and len(mesh.faces) and np.all(np.isfinite(mesh.vertices))):
        return False
    if mesh.normals is not None and not np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0):
        return False
    return mesh.uv is None or bool(np.all(np.isfinite(mesh.uv)))


def _reach(transform: np.ndarray, corners: np.ndarray) -> float:
    """How far from the origin a box (its corners) reaches once transformed; inf on overflow."""
    with np.errstate(over="ignore", invalid="ignore"):
        reach = float(np.max(np.abs(corners @ transform.T)[:, :3]))
    return reach if np.isfinite(reach) else np.inf


@dataclass
class ImportedScene:
    """What a pbrt file describes, ready to render: the scene (with its camera and light samples),
    the output file the Film names, and what could not be honoured."""

    scene: Scene
    output_name: str | None
    warnings: list[str] = field(default_factory=list)
    dialect: Dialect | None = None  # the pbrt version the file was read as, and why


def _rgb(params: Params, name: str, default: tuple | None) -> tuple | None:
    """An RGB triple (one value: grey); None for what we cannot read as RGB (spectra, other counts)."""
    p = params.items.get(name)
    if p is None:
        return default
    if p.type in ("spectrum", "blackbody", "xyz") or len(p.values) not in (1, 3):
        return None
    values = params.get_floats(name)  # a syntax error naming the parameter when they are not numbers
    return tuple(values * 3 if len(values) == 1 else values)


def _texture_name(params: Params, name: str, where: str) -> str:
    """The texture a ``"texture name"`` parameter names."""
    value = params.get_string(name)
    if not value:
        raise UserError(f'{where}: "texture {name}" needs the name of a texture')
    return value


def _whole_number(params: Params, name: str, default: float, where: str) -> int:
    """An integer parameter, which must hold a whole number."""
    value = params.get_float(name, default)
    if value != int(value):
        raise UserError(f'{where}: "{name}" must be a whole number, got {value:g}')
    return int(value)


@contextmanager
def _located(where: str):
    """Prefix ``where`` (a scene file:line) to a UserError that does not already name a file and line."""
    try:
        yield
    except (LensFileError, PbrtSyntaxError):
        raise
    except UserError as err:
        message = str(err)
        if message.startswith(f"{where}:"):
            raise
        raise UserError(f"{where}: {message}") from None


class _Importer:
    def __init__(self, parsed: PbrtScene, search_paths: list[Path], dialect: Dialect):
        self.parsed = parsed
        self.search_paths = search_paths
        self.dialect = dialect
        self.scene = Scene()
        self.materials: dict[int, SurfaceMaterial] = {}
        # shape record -> (mesh index, local transform, object-space box corners)
        self.stored: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
        # a mesh file named by several shapes is loaded and stored once (the intersector then builds
        # it once for all its instances): path -> its objects, mesh identity -> scene mesh index
        self.loaded: dict[Path, list[tuple[Mesh, np.ndarray]]] = {}
        self.mesh_index: dict[int, int] = {}

    def warn(self, where: str, message: str) -> None:
        self.parsed.warn(where, message)

    def find(self, name: str, directory: Path, where: str, what: str) -> Path:
        path = resolve_file(name, directory, self.search_paths)
        if path is None:
            raise UserError(f'{where}: {what} "{name}" not found in {directory} or the search paths '
                            f"(add one with --search-path)")
        return path

    # ---- materials and textures ---------------------------------------------------------------
    def material(self, declaration: Declaration) -> SurfaceMaterial:
        key = id(declaration)
        if key not in self.materials:
            self.materials[key] = self._material(declaration)
        return self.materials[key]

    def _material(self, declaration: Declaration) -> SurfaceMaterial:
        """pbrt's material types as scene materials (``realistic.scene.pbrt.materials``)."""
        with _located(declaration.where):
            return build_material(declaration, self)

    @property
    def dialect_name(self) -> str:
        return self.dialect.name

    def named_material(self, name: str) -> Declaration | None:
        return self.parsed.named_materials.get(name)

    def texture_material(self, name: str, where: str, using: tuple[str, ...] = ()) -> Material:
        """A Kd texture as colour x texture (pbrt's scale of an image by a constant included)."""
        tex = self.parsed.textures.get(name)
        if tex is None:
            raise UserError(f'{where}: texture "{name}" is not defined')
        if name in using:
            chain = " -> ".join(f'"{n}"' for n in (*using[using.index(name):], name))
            raise UserError(f'{where}: texture "{name}" is made of itself ({chain})')
        p = tex.params
        if tex.cls == "constant":
            return Material(_rgb(p, "value", (1.0, 1.0, 1.0)) or GREY)
        if tex.cls == "imagemap":
            filename = p.get_string("filename")
            if not filename:
                raise UserError(f'{tex.where}: imagemap texture "{name}" has no filename')
            path = self.find(filename, tex.directory, tex.where, "texture file")
            if p.get_string("mapping", "uv") != "uv":
                self.warn(tex.where, "imagemap mapping other than uv (uv used)")
            texture = imagemap_texture(p, *read_image(path), filename, self.dialect, tex.where)
            return Material((1.0, 1.0, 1.0), texture)
        if tex.cls == "checkerboard":
            if p.get_float("uscale", 1.0) != p.get_float("vscale", 1.0):
                self.warn(tex.where, "checkerboard with different uscale and vscale (uscale used)")
            even, odd = (self._constant_of(p, k, tex.where) for k in ("tex1", "tex2"))
            return Material((1.0, 1.0, 1.0), CheckerTexture(even, odd, p.get_float("uscale", 1.0)))
        if tex.cls == "scale":
            parts = [p.items.get(k) for k in ("tex1", "tex2")]
            textures = [q for q in parts if q is not None and q.type == "texture"]
            constants = [(_rgb(p, q.name, None) or GREY) for q in parts if q is not None and q.type != "texture"]
            if len(textures) > 1:
                self.warn(tex.where, "scale texture of two textures (the second is ignored)")
            base = (self.texture_material(_texture_name(p, textures[0].name, textures[0].where), tex.where,
                                          (*using, name)) if textures else Material((1, 1, 1)))
            colour = np.prod([base.diffuse] + constants, axis=0)
            return Material(tuple(float(c) for c in colour), base.texture)
        self.warn(tex.where, f'Texture "{tex.cls}", rendered as grey')
        return Material(GREY)

    def _constant_of(self, params: Params, key: str, where: str) -> tuple:
        q = params.items.get(key)
        if q is not None and q.type == "texture":
            self.warn(where, f"checkerboard {key} given as a texture (grey used)")
            return GREY
        return _rgb(params, key, (1.0, 1.0, 1.0) if key == "tex1" else (0.0, 0.0, 0.0)) or GREY

    # ---- shapes -------------------------------------------------------------------------------
    def usable(self, shape: ShapeRecord) -> bool:
        """False (with a warning) for an analytic shape whose sizes leave nothing we can render."""
        p = shape.params
        sizes = {"sphere": ["radius"], "disk": ["radius"], "cone": ["radius", "height"],
                 "cylinder": ["radius"]}.get(shape.type, [])
        defaults = {"radius": 1.0, "height": 1.0}
        for name in sizes:
            value = p.get_float(name, defaults[name])
            if not value > 0:
                self.warn(shape.where, f'{shape.type} {name} {value:g} (only positive sizes are rendered; '
                                       f"shape skipped)")
                return False
        if shape.type == "cylinder" and p.get_float("zmin", -1.0) == p.get_float("zmax", 1.0):
            self.warn(shape.where, "cylinder with zmin = zmax (no height; shape skipped)")
            return False
        return True

    def meshes(self, shape: ShapeRecord) -> list[tuple[Mesh, np.ndarray]]:
        """The shape tessellated, with the transform from its object space to the record's space."""
        p = shape.params
        if shape.type == "trianglemesh":
            return [(self.triangle_mesh(shape), np.eye(4))]
        if shape.type == "bilinearmesh":
            return [(self.bilinear_mesh(shape), np.eye(4))]
        if shape.type == "loopsubdiv":  # pbrt-v3/v4: "indices" and "P" of a triangle control mesh, "levels"
            vertices, indices = self._indexed_points(shape, 3, "triangle")
            self.warn(shape.where, "loopsubdiv (rendered as its control mesh, not subdivided)")
            return [(Mesh(vertices, indices.reshape(-1, 3), None, None, shape.type), np.eye(4))]
        if shape.type == "plymesh":
            filename = p.get_string("filename")
            if not filename:
                raise UserError(f"{shape.where}: plymesh has no filename")
            if p.has("displacement"):  # pbrt-v4 src/pbrt/shapes.cpp tessellates and displaces along N
                self.warn(shape.where, 'plymesh "displacement" (the mesh is rendered undisplaced)')
            path = self.find(filename, shape.directory, shape.where, "plymesh file").resolve()
            if path not in self.loaded:
                self.loaded[path] = [(obj.mesh, obj.transform) for obj in load_mesh_file(path)]
            return self.loaded[path]
        if shape.type == "disk":
            if p.get_float("innerradius", 0.0):
                self.warn(shape.where, "disk innerradius (rendered as a full disk)")
            return [(disk(p.get_float("radius", 1.0)), translate(0, 0, p.get_float("height", 0.0)))]
        if shape.type == "sphere":
            if p.has("zmin") or p.has("zmax") or p.get_float("phimax", 360.0) != 360.0:
                self.warn(shape.where, "partial sphere (zmin, zmax, phimax; rendered whole)")
            return [(sphere(p.get_float("radius", 1.0)), np.eye(4))]
        if shape.type == "cone":
            if p.get_float("phimax", 360.0) != 360.0:
                self.warn(shape.where, "partial cone (phimax; rendered whole)")
            return [(cone(p.get_float("radius", 1.0), p.get_float("height", 1.0)), np.eye(4))]
        if shape.type == "cylinder":
            return [(self.cylinder(p), np.eye(4))]
        self.warn(shape.where, f'Shape "{shape.type}" (skipped)')
        return []

    def triangle_mesh(self, shape: ShapeRecord) -> Mesh:
        """pbrt's trianglemesh: bad points or indices are errors; uv or N that do not fit are dropped
        with a warning, as pbrt does."""
        vertices, indices = self._indexed_points(shape, 3, "triangle")
        return self._mesh_with_attributes(shape, vertices, indices.reshape(-1, 3))

    def bilinear_mesh(self, shape: ShapeRecord) -> Mesh:
        """pbrt-v4's bilinearmesh (src/pbrt/shapes.cpp, BilinearPatch::CreateMesh): each patch's four
        indices are its corners p00, p10, p01, p11 (default [0 1 2 3] for four points). Each patch is
        split into the triangles (p00, p10, p11) and (p00, p11, p01), which face the way pbrt's
        dp/du x dp/dv does and are exact for planar patches; a warped patch is approximated."""
        vertices, indices = self._indexed_points(shape, 4, "patch")
        p00, p10, p01, p11 = indices.reshape(-1, 4).T
        faces = np.column_stack([p00, p10, p11, p00, p11, p01]).reshape(-1, 3)
        self.warn(shape.where, "bilinearmesh (each bilinear patch is rendered as two triangles)")
        return self._mesh_with_attributes(shape, vertices, faces)

    def _indexed_points(self, shape: ShapeRecord, corners: int, unit: str) -> tuple[np.ndarray, np.ndarray]:
        """A mesh shape's "P" as (N, 3) points and its "indices" (``corners`` per ``unit``), checked."""
        p, where, kind = shape.params, shape.where, shape.type
        points = np.asarray(p.get_floats("P", []), dtype=np.float64)
        if len(points) == 0 or len(points) % 3:
            raise UserError(f'{where}: {kind} "point P" needs 3 values per point, got {len(points)} values')
        vertices = points.reshape(-1, 3)
        if not np.all(np.isfinite(vertices)):
            raise UserError(f'{where}: {kind} "point P" has a value that is not a finite number')
        default = [float(i) for i in range(corners)] if len(vertices) == corners else []  # pbrt's default
        indices = p.get_floats("indices", default)
        if len(indices) == 0 or len(indices) % corners:
            raise UserError(f'{where}: {kind} "integer indices" needs {corners} per {unit}, got {len(indices)} '
                            f"values")
        indices = np.asarray(indices, dtype=np.float64)
        bad = (indices != np.floor(indices)) | (indices < 0) | (indices >= len(vertices))
        if np.any(bad):
            raise UserError(f"{where}: {kind} index {indices[np.argmax(bad)]:g} is not a point number (0 to "
                            f'{len(vertices) - 1} for the {len(vertices)} points of "P")')
        return vertices, indices.astype(np.int64)

    def _mesh_with_attributes(self, shape: ShapeRecord, vertices: np.ndarray, faces: np.ndarray) -> Mesh:
        """The mesh with the shape's per-point uv and unit normals where they fit the points."""
        uv = self._per_point(shape, ("uv", "st"), 2, len(vertices))
        normals = self._per_point(shape, ("N",), 3, len(vertices))
        if normals is not None:
            length = np.linalg.norm(normals, axis=1, keepdims=True)
            if np.all(length > 0):
                normals = normals / length
            else:
                self.warn(shape.where, f'{shape.type} "N" with a zero-length normal (normals ignored)')
                normals = None
        return Mesh(vertices, faces, normals, uv, shape.type)

    def _per_point(self, shape: ShapeRecord, names: tuple[str, ...], width: int, points: int) -> np.ndarray | None:
        """A per-point array (uv or normals) of a trianglemesh, or None (with a warning when it does
        not fit the points: pbrt discards it too)."""
        for name in names:
            values = shape.params.get_floats(name)
            if values:
                break
        else:
            return None
        if len(values) != width * points:
            self.warn(shape.where, f'{shape.type} "{name}" has {len(values)} values, not {width} for each of '
                                   f"the {points} points ({name} ignored)")
            return None
        return np.asarray(values, dtype=np.float64).reshape(-1, width)

    def cylinder(self, params: Params, segments: int = 256) -> Mesh:
        radius, z0, z1 = params.get_float("radius", 1.0), params.get_float("zmin", -1.0), params.get_float("zmax", 1.0)
        z0, z1 = min(z0, z1), max(z0, z1)  # as pbrt
        phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
        ring = np.column_stack([np.cos(phi), np.sin(phi)])
        vertices = np.vstack([np.column_stack([ring * radius, np.full(segments, z)]) for z in (z0, z1)])
        normals = np.vstack([np.column_stack([ring, np.zeros(segments)])] * 2)
        i = np.arange(segments)
        j = (i + 1) % segments
        faces = np.concatenate([np.column_stack([i, j, j + segments]),
                                np.column_stack([i, j + segments, i + segments])])
        return Mesh(vertices, faces, normals, None, "cylinder")

    def add_shape(self, shape: ShapeRecord, world: np.ndarray) -> None:
        if not self.usable(shape):
            return
        if shape.area_light is not None and self.add_area_light(shape, world):
            return
        self.add_instances(shape, world)

    def add_instances(self, shape: ShapeRecord, world: np.ndarray) -> None:
        """Instances of the shape's meshes under ``world`` (meshes tessellated or loaded once)."""
        material = self.material(shape.material)
        if id(shape) not in self.stored:  # tessellate or load once, however often it is instanced
            with np.errstate(all="ignore"):  # extreme sizes: judged by _sound
                meshes = self.meshes(shape)
            if not all(_sound(mesh) for mesh, _ in meshes):
                self.warn(shape.where, f'Shape "{shape.type}" whose sizes are too extreme for its triangles, '
                                       f"normals or uv to be computed (skipped)")
                meshes = []
            self.stored[id(shape)] = [(self._mesh_index(mesh), local, _corners(mesh.vertices))
                                      for mesh, local in meshes]
        for index, local, corners in self.stored[id(shape)]:
            transform = world @ shape.transform @ local
            reach = _reach(transform, corners)
            if reach > MAX_WORLD_COORDINATE:
                self.warn(shape.where, f'Shape "{shape.type}" reaching {reach:.3g} from the origin, beyond the '
                                       f"{MAX_WORLD_COORDINATE:g} the renderer's single precision holds (skipped)")
                continue
            self.scene.add(index, transform, material)

    def _mesh_index(self, mesh: Mesh) -> int:
        """The scene's index of ``mesh``, stored on first use (a mesh file's meshes are shared by shapes)."""
        if id(mesh) not in self.mesh_index:
            self.mesh_index[id(mesh)] = self.scene.add_mesh(mesh)
        return self.mesh_index[id(mesh)]

    def add_area_light(self, shape: ShapeRecord, world: np.ndarray) -> bool:
        """Add the shape's area light; False when the shape is to be drawn as an ordinary shape instead."""
        declaration = shape.area_light
        where = declaration.where
        if declaration.type not in ("area", "diffuse"):
            self.warn(where, f'AreaLightSource "{declaration.type}" (shape rendered unlit)')
            return False
        radiance = _rgb(declaration.params, "L", (1.0, 1.0, 1.0))
        if radiance is None:
            self.warn(where, "spectral area light L (rendered white)")
            radiance = (1.0, 1.0, 1.0)
        for name in ("filename", "power"):  # pbrt-v4 DiffuseAreaLight: image emission, photometric power
            if declaration.params.has(name):
                self.warn(where, f'area light "{name}" (ignored; L and scale set its radiance)')
        light_scale = _rgb(declaration.params, "scale", (1.0, 1.0, 1.0)) or (1.0, 1.0, 1.0)
        radiance = tuple(a * b for a, b in zip(radiance, light_scale))
        samples = _whole_number(declaration.params, "nsamples", 1, where)
        if samples > MAX_LIGHT_SAMPLES:
            self.warn(where, f"nsamples {samples} (at most {MAX_LIGHT_SAMPLES} are taken)")
            samples = MAX_LIGHT_SAMPLES
        self.scene.light_samples = max(self.scene.light_samples, samples)
        twosided = declaration.params.items.get("twosided")
        two_sided = bool(twosided and twosided.values and twosided.values[0] is True)
        if shape.type != "disk":  # any other shape emits from its faces and reflects by its material
            first = len(self.scene.instances)
            self.add_instances(shape, world)
            for index in range(first, len(self.scene.instances)):
                area = self._face_front(index, shape)
                if not 0 < area < np.inf:
                    self.warn(where, f"area light of area {area:.3g} (too small or too large to sample; the "
                                     f"shape is drawn unlit)")
                    continue
                self.scene.lights.append(EmissiveInstance(index, radiance, two_sided))
            return True
        transform = world @ shape.transform @ translate(0, 0, shape.params.get_float("height", 0.0))
        if not (np.all(np.isfinite(transform)) and abs(np.linalg.det(transform[:3, :3])) > 0):
            self.warn(where, "area light whose transform flattens it (a Scale by 0, say; skipped)")
            return True
        radius = shape.params.get_float("radius", 1.0)
        if _reach(transform, _corners(np.array([[-radius, -radius, 0.0], [radius, radius, 0.0]]))) > \
                MAX_WORLD_COORDINATE:
            self.warn(where, f"area light reaching beyond {MAX_WORLD_COORDINATE:g} from the origin, more than the "
                             f"renderer's single precision holds (skipped)")
            return True
        light = AreaLight("disk", (radius, radius), radiance, transform, shape.reverse_orientation, two_sided)
        with np.errstate(all="ignore"):
            area, normal = light.area(), light.frame()[3]
        if not (0 < area < np.inf and np.all(np.isfinite(normal))):
            self.warn(where, f"area light of area {area:.3g} (too small or too large to sample; skipped)")
            return True
        self.scene.lights.append(light)
        return True

    def _face_front(self, index: int, shape: ShapeRecord) -> float:
        """Rewind instance ``index``'s faces so that each one's counter-clockwise normal in the world
        is the side pbrt emits from (``EmissiveInstance`` emits on that side); returns its world area.

        pbrt-v3 ``src/core/interaction.cpp`` and ``src/shapes/triangle.cpp``, pbrt-v4
        ``src/pbrt/shapes.h``: a triangle's normal faces its shading normals where the mesh has them
        (reversed by ReverseOrientation, as pbrt-v4's ``TriangleMesh`` does), else it is its world
        winding's normal flipped by ReverseOrientation xor a handedness-swapping transform; quadric
        shapes (sphere, cone, cylinder) face outward in object space, flipped by ReverseOrientation
        xor the swap, which is the world winding of our outward-wound tessellations flipped by
        ReverseOrientation alone.
        """
        inst = self.scene.instances[index]
        mesh = self.scene.meshes[inst.mesh]
        linear = np.asarray(inst.transform, np.float64)[:3, :3]
        with np.errstate(all="ignore"):
            corners = (mesh.vertices @ linear.T)[mesh.faces]
            winding = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            area = float(np.linalg.norm(winding, axis=1).sum() / 2)
        if mesh.normals is not None and shape.type not in QUADRICS and np.linalg.det(linear) != 0:
            with np.errstate(all="ignore"):
                shading = (mesh.normals @ np.linalg.inv(linear))[mesh.faces].sum(axis=1)
            flip = np.einsum("ij,ij->i", winding, shading) < 0
        else:
            swaps = shape.type not in QUADRICS and np.linalg.det(linear) < 0
            flip = np.full(len(mesh.faces), bool(swaps))
        flip ^= shape.reverse_orientation
        if np.any(flip):
            faces = np.where(flip[:, None], mesh.faces[:, ::-1], mesh.faces)
            rewound = self.scene.add_mesh(dataclasses.replace(mesh, faces=faces))
            self.scene.instances[index] = dataclasses.replace(inst, mesh=rewound)
        return area if np.isfinite(area) else np.inf

    def run(self) -> Scene:
        for shape in self.parsed.shapes:
            self.add_shape(shape, np.eye(4))
        for name, world, _ in self.parsed.instances:
            for shape in self.parsed.objects[name]:
                self.add_shape(shape, world)
        self.scene.lights.extend(import_lights(self.parsed, self.dialect, self.find))
        self.scene.integrator, self.scene.max_depth = import_integrator(self.parsed, self.dialect.default_integrator)
        return self.scene


def find_lens_file(name: str, scene_dir: Path, search_paths: list[Path], where: str) -> str:
    """A lens named by a scene: next to the scene or in a search path, else a bundled lens of that name."""
    path = resolve_file(name, scene_dir, search_paths)
    if path is not None:
        return str(path)
    for short, filename in BUNDLED_LENSES.items():
        if filename == Path(name).name:
            return short
    raise UserError(f'{where}: lens file "{name}" not found next to the scene ({scene_dir}) nor among the '
                    f'bundled lenses ({", ".join(BUNDLED_LENSES.values())})')


def import_camera(parsed: PbrtScene, dialect: Dialect, width: int, height: int, spp: int,
                  lens_sampling: str = "pupil",
                  lens_edit: Callable[[LensSystem], LensSystem] | None = None,
                  focus_scene_units: float | None = None,
                  search_paths: list[Path] | None = None) -> LensCamera | ThinLensCamera:
    """The scene's camera at the given resolution and sample count, with optional overrides.

    ``focus_scene_units`` refocuses a realistic camera (thick-lens model) on the plane that far
    from the film; ``lens_edit`` changes the scene's lens (its stop's size or shape) before focusing.
    """
    search_paths = list(search_paths or [])
    directive = parsed.camera
    if directive is None:
        raise UserError(f"{parsed.path}: no Camera directive")
    world_from_camera = np.linalg.inv(directive.transform)
    if not np.max(np.abs(world_from_camera[:3, 3])) <= MAX_WORLD_COORDINATE:
        raise UserError(f"{directive.where}: the camera sits beyond {MAX_WORLD_COORDINATE:g} from the origin, more "
                        f"than the renderer's single precision holds")
    params = directive.params

    def scene_lens(parameter: str) -> LensSystem:
        """The lens file the camera names; a bundled prescription of that file name stands in, with a
        note, when the file is neither beside the scene nor on the search path."""
        name = _lens_name(params, parameter)
        found = find_lens_file(name, parsed.path.parent, search_paths, directive.where)
        if found in BUNDLED_LENSES:
            parsed.warn(directive.where, f'lens file "{name}" is not beside the scene or on the search path '
                                         f'(the bundled "{found}" prescription stands in for it)')
        return load_lens(found)

    if directive.type == "perspective":
        if lens_edit is not None or focus_scene_units is not None:
            raise UserError(f"{directive.where}: the stop and focus options apply to realistic cameras, not "
                            f'Camera "perspective"')
        with _located(directive.where):
            return ThinLensCamera(params.get_float("fov", 90.0), params.get_float("lensradius", 0.0),
                                  params.get_float("focaldistance", 1e6), width, height, spp, world_from_camera)
    if directive.type != "realistic":
        raise UserError(f'{directive.where}: Camera "{directive.type}" is not supported (use realistic or perspective)')
    convention = dialect.realistic_camera
    with _located(directive.where):  # errors about the camera's parameters name its line
        missing = [(kind, name) for kind, name in convention.required if not params.has(name)]
        if missing:
            quoted = " and ".join(f'"{kind} {name}"' for kind, name in missing)
            raise UserError(f'Camera "realistic" read as {dialect.describe()} needs {quoted} '
                            f"(--pbrt-dialect reads another version's parameter names)")
        for name in sorted(dialect.foreign_camera_parameters):
            if params.has(name):
                parsed.warn(directive.where, f'"{name}" is not a realistic-camera parameter in pbrt-{dialect.name} '
                                             f"(ignored)")
        lens = scene_lens(convention.lens_file)
        if convention.film_distance is None:  # pbrt-v3/v4: focused by distance, with their default stop
            lens = _v3_stop(lens, params.get_float(convention.stop_diameter, PBRT3_DEFAULT_APERTURE_MM), parsed,
                            directive.where)
            if convention.stop_shape is not None and params.has(convention.stop_shape):
                lens = lens.with_stop_shape(_v4_aperture(params.get_string(convention.stop_shape), lens, parsed,
                                                         directive.where, search_paths))
            focus = params.get_float(convention.focus_distance, PBRT3_DEFAULT_FOCUS_M)
            if not focus > 0:
                raise UserError(f"{convention.focus_distance} must be a positive number of metres, got {focus:g}")
            film_distance = film_distance_for_focus(lens, focus * convention.camera_units_mm)
        else:  # the classic camera: the film where the file puts it, the lens's own stop unless given
            film_distance = params.get_float(convention.film_distance)
            if params.has(convention.stop_diameter):
                lens = lens.with_stop_diameter(params.get_float(convention.stop_diameter))
        world_from_camera = world_from_camera @ scale(1.0 / convention.camera_units_mm)
    if convention.film_diagonal_on_camera is not None:
        film_diagonal_where, film_diagonal_params = directive.where, params
        film_diagonal_name = convention.film_diagonal_on_camera
    else:
        film_diagonal_where = parsed.film.where if parsed.film else directive.where
        film_diagonal_params = parsed.film.params if parsed.film else Params()
        film_diagonal_name = "diagonal"
    with _located(film_diagonal_where):
        film_diagonal = validation.film_diagonal_mm(film_diagonal_params.get_float(film_diagonal_name,
                                                                                   DEFAULT_FILM_DIAGONAL_MM))
    if lens_edit is not None:
        lens = lens_edit(lens)
    with _located(directive.where):
        camera = LensCamera(lens, film_distance, film_diagonal, width, height, spp, world_from_camera,
                            convention.origin, lens_sampling)
    if focus_scene_units is not None:
        camera = camera.refocused(focus_scene_units * camera.mm_per_unit)
    return camera


def _v3_stop(lens: LensSystem, diameter_mm: float, parsed: PbrtScene, where: str) -> LensSystem:
    """The lens with its stop set to ``aperturediameter``: pbrt-v3 (src/cameras/realistic.cpp) and
    pbrt-v4 (src/pbrt/cameras.cpp, RealisticCamera's constructor) clamp a diameter wider than the
    lens file's stop to that stop, with a warning; so do we."""
    widest = lens.stop_diameter_mm
    if diameter_mm > widest:
        parsed.warn(where, f'"aperturediameter" {diameter_mm:g} mm is wider than the lens file\'s stop '
                           f"({widest:g} mm; clamped to it, as pbrt does)")
        diameter_mm = widest
    return lens.with_stop_diameter(diameter_mm)


def _v4_aperture(name: str | None, lens: LensSystem, parsed: PbrtScene, where: str,
                 search_paths: list[Path]) -> StopShape | None:
    """pbrt-v4's ``aperture``: a built-in shape (``dialect.v4_builtin_aperture``) or an image file
    (the average of its channels, file's top row at +y, as pbrt-v4 flips it on load) whose levels
    are the stop's transmission; "" keeps the circle. Each differs from pbrt-v4 in brightness,
    which pbrt-v4 rescales to the full circle's, and that is said once with the file and line."""
    if not name:
        return None
    if name in V4_BUILTIN_APERTURES:
        shape = v4_builtin_aperture(name)
    else:
        path = resolve_file(name, parsed.path.parent, search_paths)
        if path is None:
            raise UserError(f'aperture image "{name}" not found next to the scene ({parsed.path.parent}) nor on '
                            f"the search paths (pbrt-v4's built-in apertures: {', '.join(V4_BUILTIN_APERTURES)})")
        shape = transmission_stop(read_linear_rgb(path).mean(axis=2), str(path))
    ratio = shape.open_area_mm2(1.0) / (np.pi / 4)  # the shape scales with the stop: any diameter will do
    parsed.warn(where, f'aperture "{name}" passes {ratio:.0%} of the full stop\'s light here (pbrt-v4 rescales '
                       f"its aperture image to the full circle's brightness)")
    return shape


def _lens_name(params: Params, name: str) -> str:
    value = params.get_string(name)
    if not value:
        raise UserError(f'"string {name}" needs a lens file name')
    return value


def import_world(path: str | Path, search_paths: list[Path] | None = None,
                 dialect: str = "auto") -> tuple[Scene, PbrtScene, Dialect]:
    """A pbrt file's world (its light samples in ``Scene.light_samples``), its parsed records
    (camera, film, warnings) and the pbrt dialect it was read in (``dialect``: "auto" or v1-v4)."""
    search_paths = list(search_paths or [])
    parsed = parse_pbrt(path, search_paths)
    chosen = choose_dialect(parsed, dialect)
    if chosen.is_v4 and "TransformBegin" in parsed.directives:  # v4 blocks keep the whole state: read again
        parsed = parse_pbrt(path, search_paths, transform_blocks_keep_all=True)
        chosen = choose_dialect(parsed, dialect)
        parsed.warn(parsed.directives["TransformBegin"], "TransformBegin/End (deprecated in pbrt-v4, which reads "
                                                         "them as AttributeBegin/End; so do we)")
    if parsed.world_begin is not None and parsed.world_end is None and not chosen.is_v4:  # v4 has no WorldEnd
        parsed.warn(str(parsed.path), f"no WorldEnd after the WorldBegin at {parsed.world_begin} (pbrt-v3 would "
                    f"render nothing; the world is rendered as read, but the file may be cut short)")
    return _Importer(parsed, search_paths, chosen).run(), parsed, chosen


def import_pixel_filter(parsed: PbrtScene, dialect: Dialect, override: str | None = None) -> PixelFilter:
    """The scene's ``PixelFilter`` read in ``dialect`` (its default when the scene names none);
    ``override`` (a filter name) replaces the scene's with that filter at the dialect's defaults.

    A filter name pbrt does not know is a warning and the dialect's default, not an error: pbrt-v2
    itself warns and goes on, and this importer renders what it can of a scene everywhere else
    (unknown shapes, materials and lights are warnings too); bad parameters of a known filter are
    one-line errors naming the file and line."""
    if override is not None:
        return dialect.pixel_filter(override)
    directive = parsed.pixel_filter
    if directive is None:
        return dialect.pixel_filter()
    try:
        filter_name(directive.type)
    except UserError:
        parsed.warn(directive.where, f'PixelFilter "{directive.type}" (the pbrt-{dialect.name} default, '
                                     f'{dialect.default_filter_name}, is used)')
        return dialect.pixel_filter()
    with _located(directive.where):
        return dialect.pixel_filter(directive.type, directive.params)


#: Film types read as an RGB image: pbrt-v1/v2/v3's "image" and pbrt-v4's "rgb" (src/pbrt/film.cpp).
RGB_FILMS = ("image", "rgb")
#: pbrt-v4's other films: what we render of them is their RGB image.
V4_OTHER_FILMS = ("gbuffer", "spectral")
#: pbrt-v4's sensor model (src/pbrt/film.cpp, PixelSensor::Create) and its neutral values: ISO 100,
#: no white balance and the CIE 1931 sensor leave the image as the film's radiance.
V4_SENSOR_DEFAULTS = {"iso": 100.0, "whitebalance": 0.0, "sensor": "cie1931"}


def _check_film(parsed: PbrtScene) -> None:
    """Warn, with the Film's file and line, about a film type or sensor setting we do not model."""
    film = parsed.film
    if film.type in V4_OTHER_FILMS:
        parsed.warn(film.where, f'Film "{film.type}" (its RGB image is rendered; the other channels are not)')
    elif film.type not in RGB_FILMS:
        parsed.warn(film.where, f'Film "{film.type}" (rendered as an RGB image film)')
    for name, neutral in V4_SENSOR_DEFAULTS.items():
        given = film.params.get_string(name) if isinstance(neutral, str) else film.params.get_float(name)
        if given is not None and given != neutral:
            parsed.warn(film.where, f'Film "{name}" {given} (the image is the film\'s radiance, as with pbrt-v4\'s '
                                    f"{name} {neutral})")


def import_pbrt(path: str | Path, width: int | None = None, height: int | None = None, spp: int | None = None,
                lens_sampling: str = "pupil", lens_edit: Callable[[LensSystem], LensSystem] | None = None,
                focus_scene_units: float | None = None, search_paths: list[Path] | None = None,
                dialect: str = "auto", pixel_filter: str | None = None) -> ImportedScene:
    """Read a pbrt scene and its camera (``Scene.camera``); resolution and samples default to the
    file's (``Film`` and ``Sampler``); ``dialect`` as ``realistic.scene.pbrt.dialect`` explains;
    ``pixel_filter`` names a filter that replaces the scene's (``import_pixel_filter``)."""
    search_paths = list(search_paths or [])
    scene, parsed, chosen = import_world(path, search_paths, dialect)
    film = parsed.film.params if parsed.film else Params()
    film_where = parsed.film.where if parsed.film else str(parsed.path)
    if parsed.film and parsed.film.params.has("cropwindow"):
        parsed.warn(parsed.film.where, "Film cropwindow (the whole image is rendered)")
    if parsed.film:
        _check_film(parsed)
    if not (width and height):  # the file's resolution is used
        with _located(film_where):
            width, height = validation.resolution(width or _whole_number(film, "xresolution", 640, film_where),
                                                  height or _whole_number(film, "yresolution", 480, film_where))
    if not spp and parsed.sampler:
        with _located(parsed.sampler.where):
            spp = validation.samples_per_pixel(_whole_number(parsed.sampler.params, "pixelsamples", 16,
                                                             parsed.sampler.where))
    spp = spp or 16
    scene.camera = dataclasses.replace(import_camera(parsed, chosen, width, height, spp, lens_sampling, lens_edit,
                                                     focus_scene_units, search_paths),
                                       pixel_filter=import_pixel_filter(parsed, chosen, pixel_filter))
    return ImportedScene(scene, film.get_string("filename"), parsed.warnings, chosen)
