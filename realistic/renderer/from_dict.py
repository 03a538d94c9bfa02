"""A scene and its camera from one plain description: ``load_dict``, the Python API's short door.

The description is a dict of plain values (numbers, strings, lists, dicts), in the spirit of
Mitsuba's ``load_dict`` but with this renderer's own names: pbrt's material types and parameters,
and a camera with a real lens. Lengths are scene units (metres unless the camera says otherwise)
except the lens's, which are millimetres as everywhere::

    {"shapes": [{"type": "sphere", "radius": 0.5, "center": [0, 0.5, 0],
                 "material": {"type": "conductor", "roughness": 0.05}},
                {"type": "rectangle", "width": 10, "height": 10, "normal": [0, 1, 0], "material": "floor"},
                {"type": "disk", "radius": 0.5, "center": [0, 3, 0], "normal": [0, -1, 0], "emission": 20}],
     "materials": {"floor": {"type": "diffuse", "reflectance": [0.6, 0.6, 0.6]}},
     "lights": [{"type": "distant", "direction": [1, 2, 1], "irradiance": 2}],
     "camera": {"type": "lens", "lens": "dgauss", "eye": [0, 1, 4], "target": [0, 0.5, 0],
                "focus": 4, "fstop": 4, "film_diagonal": 43.27, "width": 320, "height": 240, "spp": 16}}

- ``shapes``: ``sphere`` (``radius``, ``center``), ``disk`` (``radius``), ``rectangle`` or ``quad``
  (``width``, ``height``, in its plane's x and y), each of these two facing ``normal`` from
  ``center``; ``mesh`` (``filename``, a mesh file placed as the file places it). Any shape takes a
  ``transform`` (4x4 object-to-world rows, applied last), a ``material`` (a dict, or the name of one
  in ``materials``; matte grey without) and an ``emission`` (RGB or grey radiance: an area light;
  ``two_sided``; an emitting disk or rectangle reflects by its ``material`` when it names one, else
  it only emits).
- ``materials``: name -> a material dict: ``type`` is a pbrt material (``diffuse``, ``conductor``,
  ``dielectric``, ``coateddiffuse``, ``mix`` with ``materials`` naming two, ...), the other keys its
  pbrt parameters (numbers, RGB lists, bools, named spectra such as ``"metal-Au-eta"``), read as a
  pbrt-v4 file would be (``realistic.scene.pbrt.materials``).
- ``lights``: ``point`` (``position``, ``intensity``), ``distant`` (``direction``: from the scene
  toward the light; ``irradiance``), ``infinite`` (``radiance``, from every direction).
- ``camera``: ``lens`` (``lens``: a bundled name or a file; ``eye``, ``target``, ``focus`` from the
  film, default the target's distance; ``fstop`` or ``aperture_mm``; ``film_diagonal`` in mm;
  ``mm_per_unit``, default 1000; ``dispersion``), or ``thinlens``/``perspective`` (``fov`` in
  degrees across the shorter side, ``eye``, ``target``, ``lens_radius``, ``focus``); both
  ``width``, ``height``, ``spp``. Both look as ``LensCamera.looking_at`` does, with pbrt's ``LookAt``
  (a left-handed view: from +z toward the origin with +y up, world +x is on the image's left, where
  right-handed Mitsuba shows it on the right).
- ``integrator`` (``directlighting`` or ``path``), ``max_depth``, ``light_samples``, ``background``.

Every value is checked once where it enters, by the check the CLI and the pbrt importer use
(``realistic.core.validation`` and the constructors that call it); an error is one line that
starts with the value's key path, such as ``shapes[2].radius: sphere radius must be a positive
finite number, got -1``. Unknown keys are errors, so a misspelt key is not silently ignored.
"""

from __future__ import annotations

import math
import numbers
import os
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.lens_camera import MM_PER_METRE, LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import validation
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.core.transforms import look_at, translate
from realistic.errors import LensFileError, UserError
from realistic.optics.formats import load_lens
from realistic.optics.paraxial import stop_diameter_for_f_number
from realistic.renderer.integrators import INTEGRATORS
from realistic.scene.lights import DistantLight, EmissiveInstance, InfiniteLight, PointLight, sphere_in_world
from realistic.scene.materials import SurfaceMaterial
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import RGB, AreaLight, Material, Mesh, Scene
from realistic.scene.pbrt.importer import MAX_PLACEMENT_CONDITION
from realistic.scene.pbrt.materials import build_material
from realistic.scene.pbrt.parser import Declaration, Param, ParamDict, Params
from realistic.scene.pbrt.values import MAX_WORLD_COORDINATE
from realistic.scene.shapes import disk, quad, sphere

T = TypeVar("T")

SCENE_KEYS = ("shapes", "materials", "lights", "camera", "integrator", "max_depth", "light_samples", "background")
SHAPE_KEYS = {"sphere": ("radius", "center"), "disk": ("radius", "center", "normal"),
              "rectangle": ("width", "height", "center", "normal"), "quad": ("width", "height", "center", "normal"),
              "mesh": ("filename",)}
SHAPE_COMMON = ("type", "transform", "material", "emission", "two_sided")
LIGHT_KEYS = {"point": ("position", "intensity"), "distant": ("direction", "irradiance"), "infinite": ("radiance",)}
CAMERA_KEYS = {"lens": ("lens", "eye", "target", "focus", "fstop", "aperture_mm", "film_diagonal", "mm_per_unit",
                        "dispersion"),
               "thinlens": ("fov", "eye", "target", "lens_radius", "focus"),
               "perspective": ("fov", "eye", "target", "lens_radius", "focus")}
CAMERA_COMMON = ("type", "width", "height", "spp")
#: Material parameters whose value is a string (file and material names); a string anywhere else must
#: be a named spectrum ("metal-Au-eta"), and a bool is a flag only in ``MATERIAL_FLAGS``.
MATERIAL_STRINGS = ("filename", "materials", "namedmaterial1", "namedmaterial2")
MATERIAL_FLAGS = ("remaproughness",)
DEFAULT_WIDTH, DEFAULT_HEIGHT, DEFAULT_SPP = 300, 300, 16


@contextmanager
def _at(path: str) -> Iterator[None]:
    """Prefix ``path`` (a key path) to a UserError that does not start with it already."""
    try:
        yield
    except LensFileError:  # names its file and line
        raise
    except UserError as err:
        message = str(err)
        if message.startswith(f"{path}:") or message.startswith(f"{path}."):
            raise
        raise UserError(f"{path}: {message}") from None


def _type_name(value: object) -> str:
    return type(value).__name__


class _Entry:
    """One dict of the description at key path ``path``: its keys checked against ``known``, its
    values read one by one, each error naming its key path."""

    def __init__(self, value: object, path: str, known: Sequence[str]) -> None:
        where = f"{path}: " if path else "the description: "
        if not isinstance(value, Mapping):
            raise UserError(f"{where}must be a dict, got {_type_name(value)}")
        for key in value:
            if key not in known:
                raise UserError(f"{where}unknown key {key!r} (known: {', '.join(known)})")
        self.values: Mapping[str, Any] = value
        self.path = path

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        return name in self.values

    def read(self, name: str, check: Callable[[Any], T], default: T) -> T:
        """``check(value)`` of key ``name`` (``default`` when absent), its errors prefixed with the key path."""
        if name not in self.values:
            return default
        with _at(self.key(name)):
            return check(self.values[name])

    def kind(self, kinds: Mapping[str, Sequence[str]] | Sequence[str]) -> str:
        """The entry's ``type``, one of ``kinds``."""
        kind = self.values.get("type")
        if not isinstance(kind, str) or kind not in kinds:
            raise UserError(f"{self.key('type')}: must be one of {', '.join(kinds)}, got {kind!r}")
        return kind


def _vector(value: object, limit: float = MAX_WORLD_COORDINATE) -> np.ndarray:
    """Three finite numbers, each within +-``limit``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)) or len(value) != 3:
        raise UserError(f"must be a list of three numbers, got {value!r}")
    vector = np.array([validation.finite(v, "each coordinate") for v in value])
    if np.max(np.abs(vector)) > limit:
        raise UserError(f"coordinates must be within +-{limit:g}, got {value!r}")
    return vector


def _direction(value: object) -> np.ndarray:
    """A direction: three numbers, not all zero; returned unit."""
    vector = _vector(value)
    vector = vector / np.max(np.abs(vector)) if np.any(vector) else vector  # scaled first: 1e-300 stays finite
    length = float(np.linalg.norm(vector))
    if not length > 0:
        raise UserError(f"a direction must not be zero, got {value!r}")
    return vector / length


def _colour(value: object) -> tuple[float, float, float]:
    """An RGB list, or one number for grey."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        value = (value, value, value)
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise UserError(f"must be an RGB list or one number, got {value!r}")
    return validation.emission(value, "colour")


def _flag(value: object) -> bool:
    if not isinstance(value, bool):
        raise UserError(f"must be true or false, got {value!r}")
    return value


def _matrix(value: object) -> np.ndarray:
    """A 4x4 object-to-world matrix (rows): affine, invertible, within the renderer's coordinates."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)) or len(value) != 4:
        raise UserError(f"must be 4 rows of 4 numbers, got {value!r}")
    rows = [_vector_of(row, 4) for row in value]
    matrix = np.array(rows)
    if not np.array_equal(matrix[3], [0.0, 0.0, 0.0, 1.0]):
        raise UserError(f"the last row must be 0 0 0 1 (an affine transform), got {matrix[3].tolist()}")
    if np.max(np.abs(matrix)) > MAX_WORLD_COORDINATE or not np.linalg.cond(matrix[:3, :3]) < MAX_PLACEMENT_CONDITION:
        raise UserError("must be invertible and within the renderer's coordinates (a scale by 0, or beyond "
                        f"{MAX_WORLD_COORDINATE:g})")
    return matrix


def _vector_of(value: object, count: int) -> list[float]:
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)) or len(value) != count:
        raise UserError(f"must be 4 rows of 4 numbers, got a row {value!r}")
    return [validation.finite(v, "each entry") for v in value]


def _file_name(value: object) -> str:
    """A file name (a string or a path) or a bundled lens's name."""
    name = os.fspath(value) if isinstance(value, os.PathLike) else value
    if not isinstance(name, str):
        raise UserError(f"must be a string or a path, got {value!r}")
    return name


class _Materials:
    """The description's materials, built through the pbrt importer's material builder as a pbrt-v4
    file's would be (``MaterialContext``), its warnings issued as ``UserWarning``s."""

    dialect_name = "v4"

    def __init__(self, named: object) -> None:
        entry = named if named is not None else {}
        if not isinstance(entry, Mapping):
            raise UserError(f"materials: must be a dict of name -> material, got {_type_name(entry)}")
        for name in entry:
            if not isinstance(name, str):
                raise UserError(f"materials: names must be strings, got {name!r}")
        self.named: Mapping[str, Any] = entry
        self.built: dict[str, SurfaceMaterial] = {}

    def warn(self, where: str, message: str) -> None:
        warnings.warn(f"{where}: {message}", stacklevel=4)

    def texture_material(self, name: str, where: str) -> Material:
        raise UserError(f"{where}: textures are not described by load_dict (use a pbrt file)")

    def find(self, name: str, directory: Path, where: str, what: str) -> Path:
        path = Path(name)
        if not path.is_file():
            raise UserError(f'{where}: {what} "{name}" not found')
        return path

    def named_material(self, name: str) -> Declaration | None:
        if name not in self.named:
            return None
        return _declaration(self.named[name], f"materials.{name}")

    def material(self, value: object, path: str) -> SurfaceMaterial:
        """A shape's ``material``: a dict, or the name of one in ``materials``."""
        if isinstance(value, str):
            if value not in self.named:
                known = ", ".join(self.named) or "none are described"
                raise UserError(f"{path}: no material named {value!r} in materials ({known})")
            if value not in self.built:
                self.built[value] = self.material(self.named[value], f"materials.{value}")
            return self.built[value]
        with _at(path):
            return build_material(_declaration(value, path), self)


def _declaration(value: object, path: str) -> Declaration:
    """A material dict as the pbrt declaration it stands for (its values typed as pbrt's would be)."""
    if not isinstance(value, Mapping):
        raise UserError(f"{path}: a material must be a dict or the name of one, got {_type_name(value)}")
    kind = value.get("type")
    if not isinstance(kind, str):
        raise UserError(f"{path}.type: a material needs its pbrt type as a string, got {kind!r}")
    params = {}
    for name, given in value.items():
        if name == "type":
            continue
        if not isinstance(name, str):
            raise UserError(f"{path}: parameter names must be strings, got {name!r}")
        with _at(f"{path}.{name}"):
            params[name] = _param(name, given, f"{path}.{name}")
    return Declaration(kind, Params(ParamDict(params)), path)


def _param(name: str, value: object, where: str) -> Param:
    """A material parameter: strings where pbrt takes a name, else numbers, RGB lists, flags or spectra."""
    if name in MATERIAL_STRINGS:
        strings = [value] if isinstance(value, str) else value
        if not (isinstance(strings, (list, tuple)) and strings and all(isinstance(s, str) for s in strings)):
            raise UserError(f"must be a string (or, for materials, two), got {value!r}")
        return Param("string", name, tuple(strings), where)
    if isinstance(value, bool):
        if name not in MATERIAL_FLAGS:
            raise UserError(f"must be a number or an RGB list, got {value!r}")
        return Param("bool", name, (value,), where)
    if isinstance(value, str):
        if not value.startswith("metal-"):
            raise UserError(f'must be a number, an RGB list or a named metal spectrum ("metal-Au-eta"), got {value!r}')
        return Param("spectrum", name, (value,), where)
    if name in MATERIAL_FLAGS:
        raise UserError(f"must be true or false, got {value!r}")
    if isinstance(value, numbers.Real):
        return Param("float", name, (validation.finite(value, "value"),), where)
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 3:
        return Param("rgb", name, tuple(validation.finite(v, "each component") for v in value), where)
    raise UserError(f"must be a number or an RGB list, got {value!r}")


def _placement(shape: _Entry, oriented: bool) -> np.ndarray:
    """Object to world: ``transform`` after the move to ``center`` and the turn of +z to ``normal``."""
    matrix = shape.read("transform", _matrix, np.eye(4))
    centre = shape.read("center", _vector, np.zeros(3))
    turn = np.eye(4)
    if oriented:
        turn = look_at(np.zeros(3), shape.read("normal", _direction, np.array([0.0, 0.0, 1.0])))
    return matrix @ translate(*centre) @ turn


def _shape(scene: Scene, value: object, path: str, materials: _Materials) -> None:
    """Add one shape (and its area light) to ``scene``."""
    entry = _Entry(value, path, SHAPE_COMMON + tuple({k for keys in SHAPE_KEYS.values() for k in keys}))
    kind = entry.kind(SHAPE_KEYS)
    for key in entry.values:
        if key not in SHAPE_COMMON and key not in SHAPE_KEYS[kind]:
            raise UserError(f"{entry.key(key)}: a {kind} has no {key!r} (it takes {', '.join(SHAPE_KEYS[kind])})")
    material = materials.material(entry.values["material"], entry.key("material")) if entry.has("material") else None
    emission = entry.read("emission", _colour, None)
    two_sided = entry.read("two_sided", _flag, False)
    if kind in ("disk", "rectangle", "quad"):
        placement = _placement(entry, oriented=True)
        if kind == "disk":
            radius = entry.read("radius", _length("disk radius"), 1.0)
            size, mesh, shape_name = (radius, radius), disk(radius), "disk"
        else:
            size = (entry.read("width", _length(f"{kind} width"), 2.0),
                    entry.read("height", _length(f"{kind} height"), 2.0))
            mesh, shape_name = quad(*size), "quad"
        if emission is not None:
            with _at(path):
                light = AreaLight(shape_name, size, emission, placement, two_sided=two_sided, material=material)
                if not 0 < light.area() < math.inf:
                    raise UserError(f"an emitter of area {light.area():.3g} cannot be sampled")
            scene.lights.append(light)
            return
        scene.add(mesh, placement, material or Material())
        return
    analytic_sphere = None
    if kind == "sphere":
        radius = entry.read("radius", _length("sphere radius"), 1.0)
        placed: list[tuple[Mesh, np.ndarray, RGB | None]] = [(sphere(radius), _placement(entry, oriented=False), None)]
        analytic_sphere = sphere_in_world(placed[0][1], radius)
    else:
        filename = entry.read("filename", _file_name, None)
        if filename is None:
            raise UserError(f"{path}: a mesh needs its filename")
        with _at(entry.key("filename")):
            objects = load_mesh_file(filename)
        transform = entry.read("transform", _matrix, np.eye(4))
        placed = [(obj.mesh, transform @ obj.transform, obj.colour) for obj in objects]
    for mesh, transform, colour in placed:
        _place(scene, mesh, transform, material or (Material(colour) if colour else Material()), path)
        if emission is not None:
            scene.lights.append(EmissiveInstance(len(scene.instances) - 1, emission, two_sided, analytic_sphere))


def _place(scene: Scene, mesh: Mesh, transform: np.ndarray, material: SurfaceMaterial, path: str) -> None:
    """An instance of ``mesh``, refused when it reaches beyond the renderer's single precision."""
    corners = mesh.vertices @ transform[:3, :3].T + transform[:3, 3]
    if not np.max(np.abs(corners)) <= MAX_WORLD_COORDINATE:
        raise UserError(f"{path}: placed beyond {MAX_WORLD_COORDINATE:g} from the origin, more than the "
                        f"renderer's single precision holds")
    scene.add(mesh, transform, material)


def _length(name: str) -> Callable[[Any], float]:
    """The check of a shape's size ``name``: a positive length within the renderer's coordinates."""
    def check(value: Any) -> float:
        return validation.positive_length(value, name, MAX_WORLD_COORDINATE)

    return check


def _light(value: object, path: str) -> PointLight | DistantLight | InfiniteLight:
    entry = _Entry(value, path, ("type", *{k for keys in LIGHT_KEYS.values() for k in keys}))
    kind = entry.kind(LIGHT_KEYS)
    for key in entry.values:
        if key != "type" and key not in LIGHT_KEYS[kind]:
            raise UserError(f"{entry.key(key)}: a {kind} light has no {key!r} (it takes {', '.join(LIGHT_KEYS[kind])})")
    if kind == "point":
        return PointLight(entry.read("intensity", _colour, (1.0, 1.0, 1.0)),
                          entry.read("position", _vector, np.zeros(3)))
    if kind == "distant":
        return DistantLight(entry.read("irradiance", _colour, (1.0, 1.0, 1.0)),
                            entry.read("direction", _direction, np.array([0.0, 0.0, 1.0])))
    return InfiniteLight(entry.read("radiance", _colour, (1.0, 1.0, 1.0)))


def _camera(value: object) -> Camera:
    """The camera a ``camera`` dict describes, looking from ``eye`` at ``target`` (+y up)."""
    entry = _Entry(value, "camera", CAMERA_COMMON + tuple({k for keys in CAMERA_KEYS.values() for k in keys}))
    kind = entry.kind(CAMERA_KEYS)
    for key in entry.values:
        if key not in CAMERA_COMMON and key not in CAMERA_KEYS[kind]:
            raise UserError(f"{entry.key(key)}: a {kind} camera has no {key!r} (it takes "
                            f"{', '.join(CAMERA_KEYS[kind])})")
    width = entry.read("width", lambda v: validation.resolution(v, 1)[0], DEFAULT_WIDTH)
    height = entry.read("height", lambda v: validation.resolution(1, v)[1], DEFAULT_HEIGHT)
    with _at("camera"):
        validation.resolution(width, height)
    spp = entry.read("spp", validation.samples_per_pixel, DEFAULT_SPP)
    eye = entry.read("eye", _vector, np.array([0.0, 0.0, 5.0]))
    target = entry.read("target", _vector, np.zeros(3))
    if np.allclose(eye, target):
        raise UserError(f"camera: eye and target coincide at {eye.tolist()}")
    distance = float(np.linalg.norm(target - eye))
    focus = entry.read("focus", lambda v: validation.positive_length(v, "focus distance"), distance)
    if kind in ("thinlens", "perspective"):
        fov = entry.read("fov", lambda v: validation.finite(v, "field of view (degrees)"), 40.0)
        radius = entry.read("lens_radius", lambda v: validation.finite(v, "lens radius"), 0.0)
        with _at("camera"):
            return ThinLensCamera(fov, radius, focus, width, height, spp, look_at(eye, target))
    lens = entry.read("lens", lambda v: load_lens(_file_name(v)), None) or load_lens("dgauss")
    if entry.has("fstop") and entry.has("aperture_mm"):
        raise UserError("camera: fstop and aperture_mm both size the stop: give one")
    lens = entry.read("aperture_mm", lambda v: lens.with_stop_diameter(validation.stop_diameter_mm(v)), lens)
    lens = entry.read("fstop", lambda v: lens.with_stop_diameter(stop_diameter_for_f_number(lens, v)), lens)
    diagonal = entry.read("film_diagonal", validation.film_diagonal_mm, FULL_FRAME_DIAGONAL_MM)
    mm_per_unit = entry.read("mm_per_unit", lambda v: validation.positive_length(v, "mm per scene unit", 1e12),
                             MM_PER_METRE)
    dispersion = entry.read("dispersion", _flag, False)
    with _at("camera.focus" if entry.has("focus") else "camera"):
        camera = LensCamera.looking_at(lens, eye, target, focus, diagonal, width, height, spp,
                                       mm_per_unit=mm_per_unit)
    return camera.with_dispersion(dispersion)


def load_dict(description: Mapping[str, Any]) -> Scene:
    """The scene (with ``Scene.camera`` when the description has a ``camera``) that ``description``
    describes; the module docstring lists the keys. Bad values are a one-line UserError naming the
    key path; what a material cannot honour is a ``UserWarning``, as for pbrt files."""
    top = _Entry(description, "", SCENE_KEYS)
    scene = Scene()
    materials = _Materials(top.values.get("materials"))
    shapes = top.values.get("shapes", [])
    lights = top.values.get("lights", [])
    for name, given in (("shapes", shapes), ("lights", lights)):
        if not isinstance(given, (list, tuple)):
            raise UserError(f"{name}: must be a list, got {_type_name(given)}")
    for index, shape in enumerate(shapes):
        _shape(scene, shape, f"shapes[{index}]", materials)
    for index, light in enumerate(lights):
        with _at(f"lights[{index}]"):
            scene.lights.append(_light(light, f"lights[{index}]"))
    scene.integrator = top.read("integrator", _integrator, scene.integrator)
    scene.max_depth = top.read("max_depth", validation.max_depth, scene.max_depth)
    scene.light_samples = top.read("light_samples", validation.light_samples, scene.light_samples)
    scene.background = top.read("background", _colour, scene.background)
    if top.has("camera"):
        scene.camera = _camera(top.values["camera"])
    scene.metadata = {"scene": "load_dict"}
    return scene


def _integrator(value: object) -> str:
    if not isinstance(value, str) or value not in INTEGRATORS:
        raise UserError(f"must be one of {', '.join(INTEGRATORS)}, got {value!r}")
    return str(value)
