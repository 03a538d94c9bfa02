"""pbrt's Camera directive as our camera: ``realistic`` as the file's dialect writes it
(``dialect.RealisticCameraConvention``: the classic homework's ``specfile``, ``filmdistance``,
``aperture_diameter``, ``filmdiag`` in mm from the front lens vertex, or pbrt-v3/v4's ``lensfile``,
``aperturediameter``, ``focusdistance`` in metres from the film centre with ``Film "diagonal"``, and
pbrt-v4's ``aperture`` shape), and ``perspective`` (pinhole or thin lens)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import validation
from realistic.core.image_files import read_linear_rgb
from realistic.core.transforms import scale
from realistic.errors import UserError
from realistic.optics.formats import BUNDLED_LENSES, load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus
from realistic.optics.stop_shape import StopShape, transmission_stop
from realistic.scene.pbrt.dialect import (
    DEFAULT_FILM_DIAGONAL_MM,
    PBRT3_DEFAULT_APERTURE_MM,
    PBRT3_DEFAULT_FOCUS_M,
    V4_BUILTIN_APERTURES,
    Dialect,
    v4_builtin_aperture,
)
from realistic.scene.pbrt.parser import Directive, Params, PbrtScene, resolve_file
from realistic.scene.pbrt.values import MAX_WORLD_COORDINATE, located

#: Camera parameters pbrt honours and we do not, with what is rendered instead (pbrt-v3
#: src/core/camera.cpp and src/cameras/perspective.cpp, pbrt-v4 src/pbrt/cameras.cpp).
NOT_HONOURED = {
    "screenwindow": "ignored: the image spans the film's full field",
    "frameaspectratio": "ignored: the aspect ratio is the resolution's",
}
#: Camera parameters pbrt reads that change nothing in our image: the shutter times matter only to
#: moving transforms (reported where a file moves one: ``ActiveTransform``), and the homework's
#: realistic camera (the pbrt-v2 assignment) takes clipping distances ``hither`` and ``yon`` that clip
#: nothing its scenes hold. They are read so that they are not reported as unused parameters.
WITHOUT_EFFECT = ("shutteropen", "shutterclose", "hither", "yon")


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


def camera_directive(parsed: PbrtScene) -> Directive:
    """The file's Camera directive; a file without one is an error."""
    if parsed.camera is None:
        raise UserError(f"{parsed.path}: no Camera directive")
    return parsed.camera


def import_camera(parsed: PbrtScene, dialect: Dialect, width: int, height: int, spp: int,
                  search_paths: list[Path] | None = None) -> LensCamera | ThinLensCamera:
    """The camera the file's Camera directive describes, at the given resolution and sample count."""
    search_paths = list(search_paths or [])
    directive = camera_directive(parsed)
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

    for name in sorted(name for name in NOT_HONOURED if params.has(name)):
        parsed.warn(directive.where, f'Camera "{name}" ({NOT_HONOURED[name]})')
    for name in WITHOUT_EFFECT:
        params.has(name)
    if directive.type == "perspective":  # another parameter is reported as unused (PbrtScene)
        with located(directive.where):
            return ThinLensCamera(params.get_float("fov", 90.0), params.get_float("lensradius", 0.0),
                                  params.get_float("focaldistance", 1e6), width, height, spp, world_from_camera)
    if directive.type != "realistic":
        raise UserError(f'{directive.where}: Camera "{directive.type}" is not supported (use realistic or perspective)')
    convention = dialect.realistic_camera
    with located(directive.where):  # errors about the camera's parameters name its line
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
        match convention.film_distance, convention.focus_distance:
            case None, str(focus_name):  # pbrt-v3/v4: focused by distance, with their default stop
                lens = _v3_stop(lens, params.get_float(convention.stop_diameter, PBRT3_DEFAULT_APERTURE_MM), parsed,
                                directive.where)
                if convention.stop_shape is not None and params.has(convention.stop_shape):
                    lens = lens.with_stop_shape(_v4_aperture(params.get_string(convention.stop_shape), lens, parsed,
                                                             directive.where, search_paths))
                focus = params.get_float(focus_name, PBRT3_DEFAULT_FOCUS_M)
                if not focus > 0:
                    raise UserError(f"{focus_name} must be a positive number of metres, got {focus:g}")
                film_distance = film_distance_for_focus(lens, focus * convention.camera_units_mm)
            case str(film_distance_name), _:  # the classic camera: the film where the file puts it
                film_distance = validation.film_distance_mm(params.get_required_float(film_distance_name))
                if params.has(convention.stop_diameter):  # else the lens's own stop
                    lens = lens.with_stop_diameter(params.get_required_float(convention.stop_diameter))
        world_from_camera = world_from_camera @ scale(1.0 / convention.camera_units_mm)
    if convention.film_diagonal_on_camera is not None:
        film_diagonal_where, film_diagonal_params = directive.where, params
        film_diagonal_name = convention.film_diagonal_on_camera
    else:
        film_diagonal_where = parsed.film.where if parsed.film else directive.where
        film_diagonal_params = parsed.film.params if parsed.film else Params()
        film_diagonal_name = "diagonal"
    with located(film_diagonal_where):
        film_diagonal = validation.film_diagonal_mm(film_diagonal_params.get_float(film_diagonal_name,
                                                                                   DEFAULT_FILM_DIAGONAL_MM))
    with located(directive.where):
        return LensCamera(lens, film_distance, film_diagonal, width, height, spp, world_from_camera, convention.origin)


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
