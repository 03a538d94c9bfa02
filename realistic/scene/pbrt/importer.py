"""pbrt scenes (v1 to v4 subset) turned into our Scene and camera: the scene assembled from the
parsed records (materials and textures, shapes placed and instanced, area lights on shapes, light
sources, the integrator), with the camera (``camera``), the film (``film``) and the shapes' meshes
(``shapes``) each read by its own module.
Everything the renderer cannot honour is reported once with file and line, and the render goes on.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.core import validation
from realistic.core.image_files import read_image
from realistic.core.transforms import translate
from realistic.core.validation import MAX_LIGHT_SAMPLES
from realistic.errors import UserError
from realistic.scene.lights import EmissiveInstance, sphere_in_world
from realistic.scene.materials import SurfaceMaterial
from realistic.scene.model import RGB, AreaLight, CheckerTexture, Material, Mesh, Scene
from realistic.scene.pbrt.camera import camera_directive, import_camera
from realistic.scene.pbrt.dialect import Dialect, choose_dialect
from realistic.scene.pbrt.film import import_film, import_pixel_filter
from realistic.scene.pbrt.imagemap import imagemap_texture
from realistic.scene.pbrt.lights import import_integrator, import_lights
from realistic.scene.pbrt.lights import light_scale as light_scale_of
from realistic.scene.pbrt.materials import build_material
from realistic.scene.pbrt.parser import Declaration, Params, PbrtScene, ShapeRecord, parse_pbrt, resolve_file
from realistic.scene.pbrt.shapes import QUADRICS, ShapeMeshes, box_corners, is_sound, reach_of
from realistic.scene.pbrt.values import (
    GREY,
    MAX_WORLD_COORDINATE,
    SPECTRAL_TYPES,
    located,
    rgb,
    spectral_rgb,
    whole_number,
)


@dataclass
class ImportedScene:
    """What a pbrt file describes, ready to render: the scene (with its camera and light samples),
    the output file the Film names, what could not be honoured, and where the camera was set."""

    scene: Scene
    output_name: str | None
    warnings: list[str]
    dialect: Dialect  # the pbrt version the file was read as, and why
    camera_where: str  # the file and line of the Camera directive, for errors about the camera


#: The largest condition number of a shape's placement (its 3x3 part) that still has an inverse
#: in float64: beyond it the placement is singular for every purpose here.
MAX_PLACEMENT_CONDITION = 1e15


def _is_placeable(transform: np.ndarray) -> bool:
    """Whether a shape can be put in the world by ``transform``: affine (bottom row 0 0 0 1, as the
    intersector's 3x4 instance matrices are) and invertible (its normals are the inverse's transpose)."""
    with np.errstate(all="ignore"):
        return bool(np.array_equal(transform[3], [0.0, 0.0, 0.0, 1.0]) and np.all(np.isfinite(transform))
                    and np.linalg.cond(transform[:3, :3]) < MAX_PLACEMENT_CONDITION)  # False for inf and NaN


def _texture_name(params: Params, name: str, where: str) -> str:
    """The texture a ``"texture name"`` parameter names."""
    value = params.get_string(name)
    if not value:
        raise UserError(f'{where}: "texture {name}" needs the name of a texture')
    return value


class _Importer:
    def __init__(self, parsed: PbrtScene, search_paths: list[Path], dialect: Dialect):
        self.parsed = parsed
        self.search_paths = search_paths
        self.dialect = dialect
        self.scene = Scene()
        self.materials: dict[int, SurfaceMaterial] = {}
        self.shape_meshes = ShapeMeshes(self.warn, self.find, dialect.names)
        # shape record -> (mesh index, local transform, object-space box corners)
        self.stored: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
        # a mesh file's meshes are stored once (the intersector then builds each once for all its
        # instances): mesh identity -> scene mesh index
        self.mesh_index: dict[int, int] = {}
        # per mesh index: its object-space area
        self.object_areas: dict[int, float] = {}
        # mesh identity -> the mesh and its copy turned inside out (``_inside_out``), made once
        self.inside_out: dict[int, tuple[Mesh, Mesh]] = {}

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
        with located(declaration.where):
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
            return Material(rgb(p, "value", (1.0, 1.0, 1.0)) or GREY)
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
            parts = [p.items.get(k) for k in self.dialect.names.scale_factors]
            textures = [q for q in parts if q is not None and q.type == "texture"]
            constants = [(rgb(p, q.name, None) or GREY) for q in parts if q is not None and q.type != "texture"]
            if len(textures) > 1:
                self.warn(tex.where, "scale texture of two textures (the second is ignored)")
            base = (self.texture_material(_texture_name(p, textures[0].name, textures[0].where), tex.where,
                                          (*using, name)) if textures else Material((1, 1, 1)))
            colour = np.prod([base.diffuse] + constants, axis=0)
            return Material((float(colour[0]), float(colour[1]), float(colour[2])), base.texture)
        self.warn(tex.where, f'Texture "{tex.cls}", rendered as grey')
        return Material(GREY)

    def _constant_of(self, params: Params, key: str, where: str) -> RGB:
        q = params.items.get(key)
        if q is not None and q.type == "texture":
            self.warn(where, f"checkerboard {key} given as a texture (grey used)")
            return GREY
        return rgb(params, key, (1.0, 1.0, 1.0) if key == "tex1" else (0.0, 0.0, 0.0)) or GREY

    def add_shape(self, shape: ShapeRecord, world: np.ndarray) -> None:
        if not self.shape_meshes.usable(shape):
            return
        if shape.area_light is not None and self.add_area_light(shape, shape.area_light, world):
            return
        self.add_instances(shape, world)

    def add_instances(self, shape: ShapeRecord, world: np.ndarray) -> None:
        """Instances of the shape's meshes under ``world`` (meshes tessellated or loaded once), under
        ReverseOrientation of the meshes turned inside out (``_inside_out``), which is what glass
        tells inside from outside by (``PathIntegrator._outward_normals``)."""
        material = self.material(shape.material)
        if id(shape) not in self.stored:  # tessellate or load once, however often it is instanced
            with np.errstate(all="ignore"):  # extreme sizes: judged by is_sound
                meshes = self.shape_meshes.meshes(shape)
            if not all(is_sound(mesh) for mesh, _ in meshes):
                self.warn(shape.where, f'Shape "{shape.type}" whose sizes are too extreme for its triangles, '
                                       f"normals or uv to be computed (skipped)")
                meshes = []
            self.stored[id(shape)] = [(self._mesh_index(self._inside_out(mesh) if shape.reverse_orientation else mesh),
                                       local, box_corners(mesh.vertices))
                                      for mesh, local in meshes]
        placed = world @ shape.transform
        if not _is_placeable(placed):
            self.warn(shape.where, f'Shape "{shape.type}" under a transform that is singular (a Scale by 0, '
                                   f"say) or projective (skipped: it has no area, or no affine place)")
            return
        for index, local, corners in self.stored[id(shape)]:
            transform = placed @ local
            reach = reach_of(transform, corners)
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

    def add_area_light(self, shape: ShapeRecord, declaration: Declaration, world: np.ndarray) -> bool:
        """Add the shape's area light (``declaration``, its AreaLightSource); False when the shape is to be
        drawn as an ordinary shape instead."""
        where = declaration.where
        if declaration.type not in ("area", "diffuse"):
            self.warn(where, f'AreaLightSource "{declaration.type}" (shape rendered unlit)')
            return False
        if self.dialect.name == "v4" and shape.material.type in ("interface", "none", ""):
            # pbrt-v4 BasicScene::CreateLights (src/pbrt/scene.cpp) skips such a shape's light; pbrt-v3
            # keeps it, and its rays pass through the shape
            self.warn(where, f'area light on a shape of Material "{shape.material.type}" (ignored, as pbrt-v4 does)')
            return False
        emitted = declaration.params.items.get("L")
        radiance = rgb(declaration.params, "L", (1.0, 1.0, 1.0))
        if emitted is not None and emitted.type in SPECTRAL_TYPES:  # as the file's pbrt records it
            radiance = spectral_rgb(emitted, self.dialect.spectra, self.find, self.warn)
        elif radiance is None:
            self.warn(where, f"area light L of {len(emitted.values) if emitted else 0} values (rendered white)")
            radiance = (1.0, 1.0, 1.0)
        for name in ("filename", "power"):  # pbrt-v4 DiffuseAreaLight: image emission, photometric power
            if declaration.params.has(name):
                self.warn(where, f'area light "{name}" (ignored; L and scale set its radiance)')
        light_scale = light_scale_of(declaration.params, where, self.dialect, self.warn, self.find)
        radiance = (radiance[0] * light_scale[0], radiance[1] * light_scale[1], radiance[2] * light_scale[2])
        with located(where):
            radiance = validation.emission(radiance, "area light L (times its scale)")
        names = [name for name in self.dialect.names.light_samples if declaration.params.has(name)]
        samples = whole_number(declaration.params, names[0], 1, where) if names else 1
        if samples > MAX_LIGHT_SAMPLES:
            self.warn(where, f"{names[0]} {samples} (at most {MAX_LIGHT_SAMPLES} are taken)")
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
                sphere = (sphere_in_world(self.scene.instances[index].transform, shape.params.get_float("radius", 1.0))
                          if shape.type == "sphere" else None)
                self.scene.lights.append(EmissiveInstance(index, radiance, two_sided, sphere))
            return True
        transform = world @ shape.transform @ translate(0, 0, shape.params.get_float("height", 0.0))
        if not (np.all(np.isfinite(transform)) and abs(np.linalg.det(transform[:3, :3])) > 0):
            self.warn(where, "area light whose transform flattens it (a Scale by 0, say; skipped)")
            return True
        radius = shape.params.get_float("radius", 1.0)
        if reach_of(transform, box_corners(np.array([[-radius, -radius, 0.0], [radius, radius, 0.0]]))) > \
                MAX_WORLD_COORDINATE:
            self.warn(where, f"area light reaching beyond {MAX_WORLD_COORDINATE:g} from the origin, more than the "
                             f"renderer's single precision holds (skipped)")
            return True
        # pbrt-v3 pbrtShape (src/core/api.cpp) and pbrt-v4 BasicScene::CreateAggregate
        # (src/pbrt/scene.cpp) give the shape the material in effect, which its surface reflects by
        light = AreaLight("disk", (radius, radius), radiance, transform, shape.reverse_orientation, two_sided,
                          self.material(shape.material))
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
        ReverseOrientation alone. ``add_instances`` has already turned the mesh inside out under
        ReverseOrientation (``_inside_out``), so only the rest is left here.
        """
        inst = self.scene.instances[index]
        mesh = self.scene.meshes[inst.mesh]
        linear = np.asarray(inst.transform, np.float64)[:3, :3]
        if shape.type in QUADRICS:  # outward in object space: only ReverseOrientation turns them
            return self._area(inst.mesh, linear)
        with np.errstate(all="ignore"):
            corners = (mesh.vertices @ linear.T)[mesh.faces]
            winding = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            area = float(np.linalg.norm(winding, axis=1).sum() / 2)
        if mesh.normals is not None and np.linalg.det(linear) != 0:
            with np.errstate(all="ignore"):
                shading = (mesh.normals @ np.linalg.inv(linear))[mesh.faces].sum(axis=1)
            flip = np.einsum("ij,ij->i", winding, shading) < 0
        else:
            flip = np.full(len(mesh.faces), bool(np.linalg.det(linear) < 0))
        if np.any(flip):
            faces = np.where(flip[:, None], mesh.faces[:, ::-1], mesh.faces)
            rewound = self.scene.add_mesh(dataclasses.replace(mesh, faces=faces))
            self.scene.instances[index] = dataclasses.replace(inst, mesh=rewound)
        return area if np.isfinite(area) else np.inf

    def _area(self, mesh_index: int, linear: np.ndarray) -> float:
        """World area of mesh ``mesh_index`` under ``linear``: its object area times the square of the
        scale when ``linear`` is a rotation times a uniform scale (the common placement of a shape, and
        cheap for a thousand equal spheres), else summed over its transformed triangles; inf on overflow."""
        mesh = self.scene.meshes[mesh_index]
        with np.errstate(all="ignore"):
            gram = linear.T @ linear
            scale2 = float(np.trace(gram) / 3)
            if 0 < scale2 < np.inf and np.allclose(gram, scale2 * np.eye(3), rtol=0, atol=1e-12 * scale2):
                if mesh_index not in self.object_areas:
                    self.object_areas[mesh_index] = triangle_area(mesh.vertices, mesh.faces)
                area = self.object_areas[mesh_index] * scale2
            else:
                area = triangle_area(mesh.vertices @ linear.T, mesh.faces)
        return area if np.isfinite(area) else np.inf

    def _inside_out(self, mesh: Mesh) -> Mesh:
        """``mesh`` turned inside out, made once per mesh (a mesh file's meshes are shared by
        shapes): every face's winding reversed and its vertex normals negated, as ReverseOrientation
        turns a shape. pbrt-v3 and pbrt-v4 hand every shape the ``reverseOrientation`` in effect
        (``pbrtShape`` in ``src/core/api.cpp``, ``BasicScene::CreateAggregate`` in
        ``src/pbrt/scene.cpp``); a triangle's or a quadric's normal flips by it (pbrt-v3
        ``SurfaceInteraction``'s constructor in ``src/core/interaction.cpp``, pbrt-v4
        ``src/pbrt/shapes.h``), and pbrt-v4's ``TriangleMesh`` (``src/pbrt/util/mesh.cpp``) negates
        the vertex normals. pbrt-v3 keeps those and turns a triangle's normal toward them, so there
        ReverseOrientation does not turn a mesh with normals: both dialects follow pbrt-v4 here, as
        ``_face_front`` does."""
        if id(mesh) not in self.inside_out:  # the original kept too, so that its identity is not reused
            normals = None if mesh.normals is None else -mesh.normals
            self.inside_out[id(mesh)] = (mesh, dataclasses.replace(mesh, faces=mesh.faces[:, ::-1], normals=normals))
        return self.inside_out[id(mesh)][1]

    def run(self) -> Scene:
        for shape in self.parsed.shapes:
            self.add_shape(shape, np.eye(4))
        for name, world, where in self.parsed.instances:
            if not _is_placeable(world):
                self.warn(where, f'ObjectInstance "{name}" under a transform that is singular (a Scale by 0, say) '
                                 f"or projective (skipped)")
                continue
            for shape in self.parsed.objects[name]:
                self.add_shape(shape, world)
        self.scene.lights.extend(import_lights(self.parsed, self.dialect, self.find))
        self.scene.integrator, self.scene.max_depth = import_integrator(self.parsed, self.dialect.default_integrator)
        self.scene.differential_floor = self.dialect.differential_floor
        return self.scene


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
    if parsed.world_begin is None and (parsed.shapes or parsed.lights or parsed.instances):
        # pbrt-v3 (src/core/api.cpp) and pbrt-v4 (src/pbrt/scene.cpp) both check VERIFY_WORLD: v3 ignores
        # a world directive outside the world block, v4 stops; only WorldEnd is gone from v4 files
        parsed.warn(str(parsed.path), "no WorldBegin (pbrt ignores or refuses shapes and lights outside the "
                                      "world block; they are rendered as read, under the camera's transforms)")
    if parsed.world_begin is not None and parsed.world_end is None and not chosen.is_v4:  # v4 has no WorldEnd
        parsed.warn(str(parsed.path), f"no WorldEnd after the WorldBegin at {parsed.world_begin} (pbrt-v3 would "
                    f"render nothing; the world is rendered as read, but the file may be cut short)")
    return _Importer(parsed, search_paths, chosen).run(), parsed, chosen


def import_pbrt(path: str | Path, search_paths: list[Path] | None = None, dialect: str = "auto") -> ImportedScene:
    """Read a pbrt scene and its camera (``Scene.camera``) as the file says: resolution and samples
    from its ``Film`` and ``Sampler``, its pixel filter; ``dialect`` as ``realistic.scene.pbrt.dialect``
    explains. The user's overrides are applied afterwards (``realistic.renderer.inputs``)."""
    search_paths = list(search_paths or [])
    scene, parsed, chosen = import_world(path, search_paths, dialect)
    film = import_film(parsed)
    scene.camera = dataclasses.replace(import_camera(parsed, chosen, film.width, film.height, film.spp, search_paths),
                                       pixel_filter=import_pixel_filter(parsed, chosen))
    parsed.report_unused_parameters()
    return ImportedScene(scene, film.output_name, parsed.warnings, chosen, camera_directive(parsed).where)


def triangle_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The summed area of a mesh's triangles."""
    corners = vertices[faces]
    return float(np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum()
                 / 2)
