"""pbrt scenes (v1/v2/v3 subset) turned into our Scene and camera.

Cameras: ``realistic`` with the classic homework parameters (``specfile``, ``filmdistance``,
``aperture_diameter``, ``filmdiag``; camera space in mm with its origin at the front lens vertex)
or pbrt-v3's (``lensfile``, ``aperturediameter``, ``focusdistance``; camera space in metres with
its origin at the film centre), and ``perspective`` (pinhole or thin lens). Everything the renderer
cannot honour is reported once with file and line, and the render goes on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.image_files import read_linear_rgb
from realistic.core.transforms import scale, translate
from realistic.errors import UserError
from realistic.optics.formats import BUNDLED_LENSES, load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import AreaLight, CheckerTexture, ImageTexture, Material, Mesh, Scene
from realistic.scene.pbrt.parser import Declaration, Params, PbrtScene, ShapeRecord, parse_pbrt, resolve_file
from realistic.scene.shapes import cone, disk, sphere

GREY = (0.5, 0.5, 0.5)


@dataclass
class ImportedScene:
    """What a pbrt file describes, ready to render: the scene (with its camera and light samples),
    the output file the Film names, and what could not be honoured."""

    scene: Scene
    output_name: str | None
    warnings: list[str] = field(default_factory=list)


def _rgb(params: Params, name: str, default: tuple | None) -> tuple | None:
    p = params.items.get(name)
    if p is None:
        return default
    if p.type in ("spectrum", "blackbody", "xyz") or len(p.values) not in (1, 3):
        return None
    values = [float(v) for v in p.values]
    return tuple(values * 3 if len(values) == 1 else values)


class _Importer:
    def __init__(self, parsed: PbrtScene, search_paths: list[Path]):
        self.parsed = parsed
        self.search_paths = search_paths
        self.scene = Scene()
        self.materials: dict[int, Material] = {}
        self.stored: dict[int, list[tuple[int, np.ndarray]]] = {}  # shape record -> (mesh index, local)

    def warn(self, where: str, message: str) -> None:
        self.parsed.warn(where, message)

    def find(self, name: str, directory: Path, where: str, what: str) -> Path:
        path = resolve_file(name, directory, self.search_paths)
        if path is None:
            raise UserError(f'{where}: {what} "{name}" not found in {directory} or the search paths '
                            f"(add one with --search-path)")
        return path

    # ---- materials and textures ---------------------------------------------------------------
    def material(self, declaration: Declaration) -> Material:
        key = id(declaration)
        if key not in self.materials:
            self.materials[key] = self._material(declaration)
        return self.materials[key]

    def _material(self, declaration: Declaration) -> Material:
        if declaration.type not in ("matte", "plastic", "uber", "substrate", "translucent"):
            self.warn(declaration.where, f'Material "{declaration.type}", rendered as matte grey')
            return Material(GREY)
        if declaration.type != "matte":
            self.warn(declaration.where, f'Material "{declaration.type}", rendered as matte with its Kd')
        kd = declaration.params.items.get("Kd")
        if kd is not None and kd.type == "texture":
            return self.texture_material(str(kd.values[0]), declaration.where)
        colour = _rgb(declaration.params, "Kd", GREY)
        if colour is None:
            self.warn(declaration.where, f"a spectral Kd in {declaration.type}, rendered grey")
            colour = GREY
        return Material(colour)

    def texture_material(self, name: str, where: str) -> Material:
        """A Kd texture as colour x texture (pbrt's scale of an image by a constant included)."""
        tex = self.parsed.textures.get(name)
        if tex is None:
            raise UserError(f'{where}: texture "{name}" is not defined')
        p = tex.params
        if tex.cls == "constant":
            return Material(_rgb(p, "value", (1.0, 1.0, 1.0)) or GREY)
        if tex.cls == "imagemap":
            filename = p.get_string("filename")
            if not filename:
                raise UserError(f'{tex.where}: imagemap texture "{name}" has no filename')
            pixels = read_linear_rgb(self.find(filename, tex.directory, tex.where, "texture file"))
            if p.has("udelta") or p.has("vdelta") or p.get_string("mapping", "uv") != "uv":
                self.warn(tex.where, "imagemap mapping other than plain uv scaling (ignored)")
            repeats = (p.get_float("uscale", 1.0), p.get_float("vscale", 1.0))
            return Material((1.0, 1.0, 1.0), ImageTexture(pixels, repeats))
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
            base = self.texture_material(str(textures[0].values[0]), tex.where) if textures else Material((1, 1, 1))
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
    def meshes(self, shape: ShapeRecord) -> list[tuple[Mesh, np.ndarray]]:
        """The shape tessellated, with the transform from its object space to the record's space."""
        p = shape.params
        if shape.type == "trianglemesh":
            return [(self.triangle_mesh(shape), np.eye(4))]
        if shape.type == "plymesh":
            filename = p.get_string("filename")
            if not filename:
                raise UserError(f"{shape.where}: plymesh has no filename")
            path = self.find(filename, shape.directory, shape.where, "plymesh file")
            return [(obj.mesh, obj.transform) for obj in load_mesh_file(path)]
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
        p = shape.params
        points = np.asarray(p.get_floats("P", []), dtype=np.float64)
        indices = np.asarray(p.get_floats("indices", []), dtype=np.float64)
        if len(points) == 0 or len(points) % 3 or len(indices) == 0 or len(indices) % 3:
            raise UserError(f'{shape.where}: trianglemesh needs "point P" (3 values per point) and '
                            f'"integer indices" (3 per triangle)')
        vertices = points.reshape(-1, 3)
        faces = indices.astype(np.int64).reshape(-1, 3)
        if faces.min() < 0 or faces.max() >= len(vertices) or not np.all(np.isfinite(vertices)):
            raise UserError(f"{shape.where}: trianglemesh indices out of range or non-finite points")
        uv = p.get_floats("uv") or p.get_floats("st")
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2) if uv else None
        if uv is not None and len(uv) != len(vertices):
            self.warn(shape.where, "trianglemesh uv count differs from point count (uv ignored)")
            uv = None
        normals = p.get_floats("N")
        normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3) if normals else None
        if normals is not None:
            unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
            normals = unit if len(normals) == len(vertices) else None
        return Mesh(vertices, faces, normals, uv, "trianglemesh")

    def cylinder(self, params: Params, segments: int = 256) -> Mesh:
        radius, z0, z1 = params.get_float("radius", 1.0), params.get_float("zmin", -1.0), params.get_float("zmax", 1.0)
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
        if shape.area_light is not None and self.add_area_light(shape, world):
            return
        material = self.material(shape.material)
        if id(shape) not in self.stored:  # tessellate or load once, however often it is instanced
            self.stored[id(shape)] = [(self.scene.add_mesh(mesh), local) for mesh, local in self.meshes(shape)]
        for index, local in self.stored[id(shape)]:
            self.scene.add(index, world @ shape.transform @ local, material)

    def add_area_light(self, shape: ShapeRecord, world: np.ndarray) -> bool:
        light = shape.area_light
        if light.type not in ("area", "diffuse"):
            self.warn(light.where, f'AreaLightSource "{light.type}" (shape rendered unlit)')
            return False
        radiance = _rgb(light.params, "L", (1.0, 1.0, 1.0))
        if radiance is None:
            self.warn(light.where, "spectral area light L (rendered white)")
            radiance = (1.0, 1.0, 1.0)
        light_scale = _rgb(light.params, "scale", (1.0, 1.0, 1.0)) or (1.0, 1.0, 1.0)
        radiance = tuple(a * b for a, b in zip(radiance, light_scale))
        self.scene.light_samples = max(self.scene.light_samples, int(light.params.get_float("nsamples", 1) or 1))
        if shape.type != "disk":
            self.warn(light.where, f'area light on a "{shape.type}" (only disks emit; shape rendered unlit)')
            return False
        transform = world @ shape.transform @ translate(0, 0, shape.params.get_float("height", 0.0))
        two_sided = bool(light.params.items.get("twosided", None) and light.params.items["twosided"].values[0])
        self.scene.lights.append(AreaLight("disk", (shape.params.get_float("radius", 1.0),) * 2, radiance, transform,
                                           shape.reverse_orientation, two_sided))
        return True

    def run(self) -> Scene:
        for shape in self.parsed.shapes:
            self.add_shape(shape, np.eye(4))
        for name, world, _ in self.parsed.instances:
            for shape in self.parsed.objects[name]:
                self.add_shape(shape, world)
        for light in self.parsed.lights:
            self.warn(light.where, f'LightSource "{light.type}" (not lit; only area lights are)')
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


def import_camera(parsed: PbrtScene, width: int, height: int, spp: int, lens_sampling: str = "pupil",
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
    params = directive.params
    if directive.type == "perspective":
        if lens_edit is not None or focus_scene_units is not None:
            raise UserError(f"{directive.where}: the stop and focus options apply to realistic cameras, not "
                            f'Camera "perspective"')
        return ThinLensCamera(params.get_float("fov", 90.0), params.get_float("lensradius", 0.0),
                              params.get_float("focaldistance", 1e6), width, height, spp, world_from_camera)
    if directive.type != "realistic":
        raise UserError(f'{directive.where}: Camera "{directive.type}" is not supported (use realistic or perspective)')
    if params.has("specfile"):  # the classic homework: camera space in mm, origin at the front lens vertex
        lens = load_lens(find_lens_file(params.get_string("specfile"), parsed.path.parent, search_paths,
                                        directive.where))
        film_distance = params.get_float("filmdistance")
        if film_distance is None:
            raise UserError(f'{directive.where}: Camera "realistic" needs "float filmdistance"')
        if params.has("aperture_diameter"):
            lens = lens.with_stop_diameter(params.get_float("aperture_diameter"))
        origin = "front_vertex"
    elif params.has("lensfile"):  # pbrt-v3: camera space in metres, origin at the film centre
        lens = load_lens(find_lens_file(params.get_string("lensfile"), parsed.path.parent, search_paths,
                                        directive.where))
        lens = lens.with_stop_diameter(params.get_float("aperturediameter", 1.0))
        film_distance = film_distance_for_focus(lens, params.get_float("focusdistance", 10.0) * 1000.0)
        world_from_camera = world_from_camera @ scale(1e-3)
        origin = "film"
    else:
        raise UserError(f'{directive.where}: Camera "realistic" needs "string specfile" or "string lensfile"')
    if lens_edit is not None:
        lens = lens_edit(lens)
    camera = LensCamera(lens, film_distance, params.get_float("filmdiag", 35.0), width, height, spp,
                        world_from_camera, origin, lens_sampling)
    if focus_scene_units is not None:
        camera = camera.refocused(focus_scene_units * camera.mm_per_unit)
    return camera


def import_world(path: str | Path, search_paths: list[Path] | None = None) -> tuple[Scene, PbrtScene]:
    """A pbrt file's world (its light samples in ``Scene.light_samples``) and its parsed records
    (camera, film, warnings)."""
    search_paths = list(search_paths or [])
    parsed = parse_pbrt(path, search_paths)
    return _Importer(parsed, search_paths).run(), parsed


def import_pbrt(path: str | Path, width: int | None = None, height: int | None = None, spp: int | None = None,
                lens_sampling: str = "pupil", lens_edit: Callable[[LensSystem], LensSystem] | None = None,
                focus_scene_units: float | None = None, search_paths: list[Path] | None = None) -> ImportedScene:
    """Read a pbrt scene and its camera (``Scene.camera``); resolution and samples default to the
    file's (``Film`` and ``Sampler``)."""
    search_paths = list(search_paths or [])
    scene, parsed = import_world(path, search_paths)
    film = parsed.film.params if parsed.film else Params()
    if parsed.film and parsed.film.params.has("cropwindow"):
        parsed.warn(parsed.film.where, "Film cropwindow (the whole image is rendered)")
    width = width or int(film.get_float("xresolution", 640))
    height = height or int(film.get_float("yresolution", 480))
    spp = spp or int(parsed.sampler.params.get_float("pixelsamples", 16) if parsed.sampler else 16)
    scene.camera = import_camera(parsed, width, height, spp, lens_sampling, lens_edit, focus_scene_units,
                                 search_paths)
    return ImportedScene(scene, film.get_string("filename"), parsed.warnings)
