"""Which pbrt a scene file was written for, and the conventions that differ between versions.

Every convention that depends on the pbrt version is decided here, once per scene, and read by the
importer; nowhere else asks which version a file is: the realistic camera's parameter names,
units, frame and film size (``RealisticCameraConvention``), and the image-texture orientation:

- pbrt-v1 and pbrt-v2 look textures up with v = 0 at the first (top) row of the image file
  (pbrt-v2 ``src/textures/imagemap.cpp`` builds its MIPMap from ``ReadImage`` as read);
- pbrt-v3 and pbrt-v4 flip the image on load, so v = 0 is the bottom row (pbrt-v3
  ``src/textures/imagemap.cpp``: "Flip image in y; texture coordinate space has (0,0) at the lower
  left corner").

and the imagemap parameters (``ImagemapConventions``): pbrt-v1/v2 (``src/textures/imagemap.cpp``)
choose the filter with ``bool trilinear`` (default false: EWA) and raise texels to ``float gamma``
(default 1); pbrt-v3 (``src/textures/imagemap.cpp``) has the same ``trilinear`` but a ``bool
gamma`` (sRGB decoding, default true for .png and .tga files); pbrt-v4 (``src/pbrt/textures.cpp``)
names the filter in ``string filter`` (default "bilinear") and the colour encoding in ``string
encoding`` (default sRGB for .png, else linear), and adds ``bool invert``. All: ``maxanisotropy`` 8,
``wrap`` "repeat", ``scale`` 1. The trilinear filter blends levels 0 and 1 for a continuous level
in [0, 1) in pbrt-v1/v2/v3 (pbrt-v3 ``src/core/mipmap.h``, ``MIPMap::Lookup``) and reads level 0
alone there in pbrt-v4 (``src/pbrt/util/mipmap.cpp``, ``MIPMap::Filter``: ``if (iLevel == 0) return
Bilerp<T>(0, st)``), blending from level 1 up (``ImageTexture.trilinear_blend_from``).

The pixel filter (``PixelFilter``; the maths in ``realistic.core.pixel_filter``):

- the default when a scene names none: pbrt-v1 ``mitchell`` (its ``core/api.cpp``
  ``RenderOptions``: FilterName = "mitchell"); pbrt-v2 ``box`` (``src/core/api.cpp``
  ``RenderOptions::RenderOptions``: FilterName = "box"); pbrt-v3 ``box`` (``src/core/api.cpp``
  ``RenderOptions``: FilterName = "box"); pbrt-v4 ``gaussian`` (``src/pbrt/scene.cpp``,
  ``BasicSceneBuilder``'s scene defaults: filter.name = "gaussian");
- radii: ``xwidth``/``ywidth`` in pbrt-v1/v2/v3 (half-widths despite the name), ``xradius``/
  ``yradius`` in pbrt-v4 (``src/pbrt/filters.cpp``), defaults per filter as each version's
  ``Create...Filter`` sets them (the same numbers in all four: box 0.5, triangle 2, mitchell 2,
  sinc 4; gaussian 2 before v4, 1.5 in v4);
- gaussian falloff: ``alpha`` (default 2) before v4, ``sigma`` (default 0.5, alpha = 1 / (2 sigma^2))
  in v4;
- sinc: pbrt-v1/v2 ``src/filters/sinc.h`` measure both sincs in units of the radius,
  sinc(tau x / r) sinc(x / r); pbrt-v3/v4 in pixels, sinc(x) sinc(x / tau) (``WindowedSinc``).
  pbrt names it ``sinc`` in every version; ``lanczos`` is accepted as another name for it.

Lights (``LightConventions``; the mapping in ``realistic.scene.pbrt.lights``): pbrt-v1/v2/v3 scale
a light by ``spectrum scale`` (default 1; pbrt-v2 ``src/lights/point.cpp``, pbrt-v3
``src/lights/spot.cpp``: I * sc), fall a spot light off as delta^4 between the cone angles
(pbrt-v3 ``SpotLight::Falloff``) and read an infinite light's lat-long map from ``mapname``
(pbrt-v3 ``src/lights/infinite.cpp``). pbrt-v4 (``src/pbrt/lights.cpp``) has ``float scale``,
normalises point and spot lights to ``power`` (k_e = 4 pi, and 2 pi ((1 - cos_start) + (cos_start -
cos_end) / 2)) and distant and infinite lights to ``illuminance`` (k_e = pi for a constant light;
the map's upper-hemisphere illuminance for an image), uses smoothstep between the cone angles and
reads an equal-area map from ``filename``. RGB values render as given in every version (pbrt-v4
divides an RGB illuminant by its illuminant's luminance, D65's, which its film records as RGB (1, 1,
1)). Spectral values (``blackbody``, ``spectrum``) render as the RGB each version's film records
(``Dialect.spectra``; the conversions in ``realistic.core.pbrt_spectra``): pbrt-v4 normalises them to
the luminance of RGB (1, 1, 1); pbrt-v2 and pbrt-v3 integrate them unnormalised and convert with the
unadapted sRGB matrix, their blackbodies normalised at 555 nm (v2) or at their peak (v3).

Integrators: the scene's ``Integrator`` (v3/v4) or ``SurfaceIntegrator`` (v1/v2) with ``integer
maxdepth`` (default 5 in every version). A file with none renders with direct lighting, as
pbrt-v1/v2 did by default (pbrt-v2 ``src/core/api.cpp``: SurfIntegratorName "directlighting"), also
for v3/v4 files whose pbrt would path-trace: the renderer's own scenes keep their images and cost,
and ``--integrator path`` asks for the rest.

``auto`` decides from what the file uses: v4-only directives (``ColorSpace``, ``Option``,
``Attribute``, ``Import``), ``Film "rgb"``, the realistic camera's ``aperture``, v4's materials
(``diffuse``, ``conductor``, ``coateddiffuse``, a ``measured`` .bsdf, ...) or its ``scale`` texture's
``tex``/``scale`` mean v4; the classic homework camera (``specfile``, ``filmdistance``, ``filmdiag``,
``aperture_diameter``), v2-only directives (``SurfaceIntegrator``, ``VolumeIntegrator``,
``Renderer``), ``shinymetal`` or a ``measured`` .brdf/.merl table mean v2; pbrt-v3's realistic
camera parameters (``lensfile``, ``aperturediameter``, ``focusdistance``), ``disney``, ``fourier``,
an area light's ``samples``, or ``Integrator``/``MakeNamedMedium`` mean v3 (or v4). Parameters
whose names differ between versions are listed in ``ParameterNames``. A file with no signal is read as v3; one with
signals of two versions is read as the newest, with a warning (v3's signals are v4's too, so they do
not clash with v4's). v1 is never chosen automatically: nothing in a file tells it from v2, and v1
and v2 share their conventions.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from realistic.core import validation
from realistic.core.pbrt_spectra import CONVERSION_OF_DIALECT
from realistic.core.pixel_filter import PixelFilter, filter_name
from realistic.errors import UserError
from realistic.optics.stop_shape import StopShape, bladed_stop, polygon_stop, transmission_stop
from realistic.scene.pbrt.parser import Declaration, Params, PbrtScene, ShapeRecord

DIALECTS = ("auto", "v1", "v2", "v3", "v4")
_V4_DIRECTIVES: tuple[str, ...] = ("ColorSpace", "Option", "Attribute", "Import")
_V2_DIRECTIVES: tuple[str, ...] = ("SurfaceIntegrator", "VolumeIntegrator", "Renderer")
_V3_DIRECTIVES: tuple[str, ...] = ("Integrator", "MakeNamedMedium")
_HOMEWORK_CAMERA: tuple[str, ...] = ("specfile", "filmdistance", "filmdiag", "aperture_diameter")
_V3_CAMERA: tuple[str, ...] = ("lensfile", "aperturediameter", "focusdistance")
_V4_CAMERA: tuple[str, ...] = ("aperture",)
#: Materials only one version's files name (each version's src/materials/ or src/pbrt/materials.cpp):
#: pbrt-v1/v2's shinymetal, pbrt-v3's disney and fourier, pbrt-v4's renamed and layered ones; the
#: measured material is pbrt-v2's for its .brdf/.merl tables and pbrt-v4's for RGL .bsdf files.
_MATERIAL_VERSION = {"shinymetal": "v2", "disney": "v3", "fourier": "v3", "diffuse": "v4", "conductor": "v4",
                     "dielectric": "v4", "thindielectric": "v4", "coateddiffuse": "v4", "coatedconductor": "v4",
                     "diffusetransmission": "v4"}
#: Each filter's default radius (pixels), as every version's ``Create...Filter`` sets it.
_DEFAULT_RADIUS = {"box": 0.5, "triangle": 2.0, "gaussian": 2.0, "mitchell": 2.0, "sinc": 4.0}
#: A gaussian wider than this is flat over any allowed radius (1 / (2 sigma^2) stays normal).
MAX_SIGMA = 1e6


@dataclass(frozen=True)
class RealisticCameraConvention:
    """How one pbrt version's ``Camera "realistic"`` is written and what its camera space is.

    The classic assignment (pbrt-v1/v2 era, Stanford CS348B) names ``specfile``, ``filmdistance``
    (mm from the rear vertex), ``aperture_diameter`` and ``filmdiag`` on the camera; its camera
    space is in millimetres with the front lens vertex at the origin (the seed report). pbrt-v3
    (``src/cameras/realistic.cpp``: ``lensfile``, ``aperturediameter`` default 1, ``focusdistance``
    default 10) and pbrt-v4 (``src/pbrt/cameras.cpp``, the same names) focus by distance, put the
    film centre at the origin of a camera space in metres (lens lengths are scaled by 0.001), and
    take the film's diagonal from ``Film "diagonal"`` (mm, default 35: pbrt-v3
    ``src/core/film.cpp``).
    """

    lens_file: str
    stop_diameter: str
    film_distance: str | None  # mm from the rear vertex (classic), or None: focused by focus_distance
    focus_distance: str | None  # metres (pbrt-v3/v4)
    film_diagonal_on_camera: str | None  # the camera's parameter, or None: Film "diagonal"
    origin: str  # "front_vertex" or "film" (LensCamera.origin)
    camera_units_mm: float  # millimetres per camera-space unit
    stop_shape: str | None = None  # pbrt-v4's "aperture": a built-in shape's name or an image file

    @property
    def required(self) -> tuple[tuple[str, str], ...]:
        """The (type, name) of each parameter a file must give: ("string", "specfile")."""
        return (("string", self.lens_file),) + ((("float", self.film_distance),) if self.film_distance else ())

    @property
    def names(self) -> frozenset[str]:
        return frozenset(name for name in (self.lens_file, self.stop_diameter, self.film_distance,
                                           self.focus_distance, self.film_diagonal_on_camera, self.stop_shape)
                         if name)


CLASSIC_REALISTIC = RealisticCameraConvention("specfile", "aperture_diameter", "filmdistance", None, "filmdiag",
                                              "front_vertex", 1.0)
PBRT3_REALISTIC = RealisticCameraConvention("lensfile", "aperturediameter", None, "focusdistance", None, "film",
                                            1000.0)
#: pbrt-v4 (src/pbrt/cameras.cpp, RealisticCamera::Create) adds ``aperture`` to pbrt-v3's parameters.
PBRT4_REALISTIC = dataclasses.replace(PBRT3_REALISTIC, stop_shape="aperture")
#: pbrt-v3's default aperture diameter (mm) and focus distance (m), src/cameras/realistic.cpp.
PBRT3_DEFAULT_APERTURE_MM, PBRT3_DEFAULT_FOCUS_M = 1.0, 10.0
#: The film diagonal (mm) when a file gives none: pbrt-v3 ``src/core/film.cpp``; the classic camera's
#: ``filmdiag`` takes the same default.
DEFAULT_FILM_DIAGONAL_MM = 35.0


@dataclass(frozen=True)
class ImagemapConventions:
    """How a pbrt version spells an imagemap's filter and colour encoding, and their defaults."""

    filter_parameter: str  # "trilinear" (a bool: trilinear or EWA) or "filter" (a name)
    default_filter: str
    encoding_parameter: str  # "gamma exponent", "gamma sRGB" (a bool) or "encoding" (a name)
    max_anisotropy: float = 8.0
    wrap: str = "repeat"
    scale: float = 1.0
    trilinear_blend_from: int = 0  # the level the trilinear blend starts from (``ImageTexture``'s)


@dataclass(frozen=True)
class LightConventions:
    """How one pbrt version scales lights, falls spot lights off and maps environment images."""

    scale_is_spectrum: bool  # "spectrum scale" (v1-v3) or "float scale" (v4)
    photometric: bool  # v4's "power" and "illuminance"
    spot_falloff: str  # "quartic" (v1-v3) or "smoothstep" (v4)
    map_parameter: str  # "mapname" (v1-v3) or "filename" (v4)
    mapping: str  # "latlong" (v1-v3) or "equal-area" (v4)


CLASSIC_LIGHTS = LightConventions(True, False, "quartic", "mapname", "latlong")
PBRT4_LIGHTS = LightConventions(False, True, "smoothstep", "filename", "equal-area")


@dataclass(frozen=True)
class ParameterNames:
    """Parameters whose names differ between pbrt versions (each read from that version's source):

    - the ``scale`` texture's two factors: ``tex1`` and ``tex2`` in pbrt-v1/v2/v3
      (pbrt-v3 ``src/textures/scale.cpp``, CreateScaleFloatTexture/CreateScaleSpectrumTexture),
      ``tex`` and ``scale`` in pbrt-v4 (``src/pbrt/textures.cpp``, SpectrumScaledTexture::Create and
      FloatScaledTexture::Create); a factor not given is 1;
    - an area light's sample count: ``nsamples`` in pbrt-v1/v2 (pbrt-v2 ``src/lights/diffuse.cpp``,
      CreateAreaLight), ``samples`` in pbrt-v3, which still reads ``nsamples`` when ``samples`` is
      not given (pbrt-v3 ``src/lights/diffuse.cpp``: FindOneInt("samples", FindOneInt("nsamples",
      1))); pbrt-v4's lights take none (its integrators sample one light per bounce);
    - loopsubdiv's number of levels (default 3 in all): ``nlevels`` in pbrt-v1/v2 (pbrt-v2
      ``src/shapes/loopsubdiv.cpp``, CreateLoopSubdivShape), ``levels`` in pbrt-v3, which still reads
      ``nlevels`` when ``levels`` is not given (pbrt-v3 ``src/shapes/loopsubdiv.cpp``, CreateLoopSubdiv:
      FindOneInt("levels", FindOneInt("nlevels", 3))), ``levels`` alone in pbrt-v4 (``src/pbrt/shapes.cpp``,
      Shape::Create; its ``--upgrade`` renames ``nlevels``, ``src/pbrt/parser.cpp``).
    """

    scale_factors: tuple[str, str]
    light_samples: tuple[str, ...]  # the names read, first match wins
    subdivision_levels: tuple[str, ...]  # the names read, first match wins


CLASSIC_NAMES = ParameterNames(("tex1", "tex2"), ("nsamples",), ("nlevels",))
PBRT3_NAMES = ParameterNames(("tex1", "tex2"), ("samples", "nsamples"), ("levels", "nlevels"))
PBRT4_NAMES = ParameterNames(("tex", "scale"), (), ("levels",))


_IMAGEMAP = {"v1": ImagemapConventions("trilinear", "ewa", "gamma exponent"),
             "v2": ImagemapConventions("trilinear", "ewa", "gamma exponent"),
             "v3": ImagemapConventions("trilinear", "ewa", "gamma sRGB"),
             "v4": ImagemapConventions("filter", "bilinear", "encoding", trilinear_blend_from=1)}


@dataclass(frozen=True)
class Dialect:
    """A pbrt version and its conventions; ``reason`` says why it was chosen."""

    name: str
    reason: str

    @property
    def texture_v_origin(self) -> str:
        """The image row at v = 0: "top" for pbrt-v1/v2, "bottom" for pbrt-v3/v4."""
        return "top" if self.name in ("v1", "v2") else "bottom"

    @property
    def realistic_camera(self) -> RealisticCameraConvention:
        """The realistic camera's parameter names, units and frame in this version."""
        return {"v1": CLASSIC_REALISTIC, "v2": CLASSIC_REALISTIC, "v3": PBRT3_REALISTIC}.get(self.name,
                                                                                          PBRT4_REALISTIC)

    @property
    def foreign_camera_parameters(self) -> frozenset[str]:
        """Realistic-camera parameters of the other versions that this one ignores."""
        return (CLASSIC_REALISTIC.names | PBRT4_REALISTIC.names) - self.realistic_camera.names

    @property
    def imagemap(self) -> ImagemapConventions:
        """The imagemap texture's parameter names and defaults in this version."""
        return _IMAGEMAP[self.name]

    @property
    def lights(self) -> LightConventions:
        """The light parameters' conventions in this version."""
        return PBRT4_LIGHTS if self.is_v4 else CLASSIC_LIGHTS

    @property
    def names(self) -> ParameterNames:
        """The parameter names that differ between versions, as this version spells them."""
        return {"v1": CLASSIC_NAMES, "v2": CLASSIC_NAMES, "v3": PBRT3_NAMES}.get(self.name, PBRT4_NAMES)

    @property
    def spectra(self) -> str:
        """Whose spectrum-to-RGB conversion this version's light spectra follow: "v2" (pbrt-v1 and v2,
        ``src/core/spectrum.h``), "v3" or "v4" (``realistic.core.pbrt_spectra``)."""
        return CONVERSION_OF_DIALECT[self.name]

    @property
    def differential_floor(self) -> float:
        """The least fraction of a pixel a camera ray's texture footprint keeps at high spp
        (``renderer.footprint.differential_scale``): pbrt-v4's 1/8, none before."""
        return 0.125 if self.is_v4 else 0.0

    @property
    def is_v4(self) -> bool:
        return self.name == "v4"

    @property
    def default_integrator(self) -> str:
        """The integrator pbrt uses when the scene names none: pbrt-v1/v2's ``SurfIntegratorName =
        "directlighting"`` (core/api.cpp), pbrt-v3's ``IntegratorName = "path"`` (src/core/api.cpp),
        pbrt-v4's ``integrator.name = "volpath"`` (src/pbrt/scene.cpp), which renders here as path."""
        return "directlighting" if self.name in ("v1", "v2") else "path"

    @property
    def default_filter_name(self) -> str:
        """The pixel filter pbrt uses when the scene names none."""
        return {"v1": "mitchell", "v4": "gaussian"}.get(self.name, "box")

    def pixel_filter(self, name: str | None = None, params: Params | None = None) -> PixelFilter:
        """The filter ``name`` (None: this version's default) with ``params`` read under this
        version's parameter names and defaults; UserError for a name pbrt does not know."""
        params = params or Params()
        name = filter_name(name) if name else self.default_filter_name
        radius = 1.5 if self.is_v4 and name == "gaussian" else _DEFAULT_RADIUS[name]
        x_name, y_name = ("xradius", "yradius") if self.is_v4 else ("xwidth", "ywidth")
        rx, ry = params.get_float(x_name, radius), params.get_float(y_name, radius)
        validation.filter_radius(rx, f"filter {x_name} (pixels)")
        validation.filter_radius(ry, f"filter {y_name} (pixels)")
        tau = validation.positive_length(params.get_float("tau", 3.0), "sinc filter tau")
        if self.is_v4:
            alpha = 1.0 / (2.0 * validation.positive_length(params.get_float("sigma", 0.5), "gaussian filter sigma",
                                                            MAX_SIGMA) ** 2)
        else:
            alpha = params.get_float("alpha", 2.0)
        if self.name in ("v1", "v2"):
            sinc_scale, window_scale = tau / rx, 1.0 / rx
        else:
            sinc_scale, window_scale = 1.0, 1.0 / tau
        return PixelFilter(name, rx, ry, alpha, params.get_float("B", 1.0 / 3.0), params.get_float("C", 1.0 / 3.0),
                           sinc_scale, window_scale)

    def describe(self) -> str:
        return f"pbrt-{self.name} ({self.reason})"


def _signals(parsed: PbrtScene) -> dict[str, list[str]]:
    """Per version, the signals the file gives for it (each as 'what at file:line')."""
    found: dict[str, list[str]] = {"v2": [], "v3": [], "v4": []}
    for version, names in (("v4", _V4_DIRECTIVES), ("v2", _V2_DIRECTIVES), ("v3", _V3_DIRECTIVES)):
        found[version] += [f"{name} at {parsed.directives[name]}" for name in names if name in parsed.directives]
    if parsed.film is not None and parsed.film.type == "rgb":
        found["v4"].append(f'Film "rgb" at {parsed.film.where}')
    for declaration in _materials(parsed):
        made_for = _MATERIAL_VERSION.get(declaration.type)
        if declaration.type == "measured":
            given = declaration.params.items.peek("filename")
            filename = given.values[0] if given is not None and given.values else ""
            made_for = "v4" if isinstance(filename, str) and filename.lower().endswith(".bsdf") else "v2"
        if made_for is not None:
            found[made_for].append(f'Material "{declaration.type}" at {declaration.where}')
    for texture in parsed.textures.values():
        if texture.cls == "scale" and any(texture.params.items.peek(name) for name in ("tex", "scale")):
            found["v4"].append(f'scale texture\'s "tex"/"scale" at {texture.where}')
    for light in {id(shape.area_light): shape.area_light for shape in _shapes(parsed) if shape.area_light}.values():
        if light.params.items.peek("samples"):
            found["v3"].append(f'area light "samples" at {light.where}')
    camera = parsed.camera
    if camera is not None and camera.type == "realistic":
        for version, names in (("v2", _HOMEWORK_CAMERA), ("v3", _V3_CAMERA), ("v4", _V4_CAMERA)):
            used = [name for name in names if camera.params.has(name)]
            if used:
                found[version].append(f"realistic camera's {', '.join(used)} at {camera.where}")
    return found


def _shapes(parsed: PbrtScene) -> list[ShapeRecord]:
    return parsed.shapes + [shape for shapes in parsed.objects.values() for shape in shapes]


def _materials(parsed: PbrtScene) -> list[Declaration]:
    """Every material the file declares: by Material, and named ones (each once)."""
    declared = {id(material): material for material in parsed.materials}
    declared.update((id(material), material) for material in parsed.named_materials.values())
    return list(declared.values())


def choose_dialect(parsed: PbrtScene, requested: str = "auto") -> Dialect:
    """The dialect to read ``parsed`` in: ``requested`` unless it is "auto"; a warning on ``parsed``
    when the file mixes versions' signals."""
    if requested not in DIALECTS:
        raise UserError(f"unknown pbrt dialect {requested!r} (choose {', '.join(DIALECTS)})")
    if requested != "auto":
        return Dialect(requested, "as asked")
    found = {version: signals for version, signals in _signals(parsed).items() if signals}
    if not found:
        return Dialect("v3", "no version-specific directive or parameter; v3 assumed")
    chosen = max(found)  # "v4" > "v3" > "v2": the newest version signalled
    # pbrt-v4 kept every v3 signal (Integrator, MakeNamedMedium, lensfile, ...): only v2's mix
    clashing = [version for version in sorted(found) if version != chosen and (chosen, version) != ("v4", "v3")]
    if clashing:
        others = "; ".join(f"{version}: {found[version][0]}" for version in clashing)
        parsed.warn(str(parsed.path), f"the file mixes pbrt versions ({others}); read as pbrt-{chosen}")
    return Dialect(chosen, found[chosen][0])


#: pbrt-v4's built-in ``aperture`` shapes (src/pbrt/cameras.cpp, RealisticCamera::Create).
V4_BUILTIN_APERTURES = ("gaussian", "square", "pentagon", "star")
_BUILTIN_SIDE = 256  # pbrt-v4 rasterises its built-in apertures at 256 x 256 over the stop's square


def v4_builtin_aperture(name: str) -> StopShape:
    """pbrt-v4's built-in aperture ``name`` as a stop shape, placed as pbrt-v4 places it.

    pbrt-v4 draws each shape on a 256 x 256 image spanning the stop's square [-r, r]^2 with row 0 at
    -r, flips the image in y (``FlipY``) and looks the stop point (x, y) up at row (y / r + 1) / 2:
    so a shape drawn at (x, y) lands at (x, -y) on the stop. The shapes, in units of r:

    - ``gaussian``: transmission max(0, exp(-r^2) - exp(-1)) (dithered into our binary mask);
    - ``square``: the pixels from 1/4 to 3/4 of each side, a square of half-side 1/2 (vertices on
      the circle of 0.5 sqrt 2, at 45 degrees);
    - ``pentagon``: the regular pentagon with a vertex at (0, 1), scaled by 0.8, so after the flip
      its vertex points to -y;
    - ``star``: five outer vertices at radius 1 and angles 36 + 72 k degrees, five inner ones at
      radius cos 72 / cos 36 between them (symmetric in y, so the flip leaves it).

    pbrt-v4 then rescales every aperture image so the stop passes as much light as the full circle
    of the same diameter; here brightness follows the open area (``realistic.optics.stop_shape``).
    """
    if name == "gaussian":
        g = (np.arange(_BUILTIN_SIDE) + 0.5) / _BUILTIN_SIDE * 2 - 1
        x, y = np.meshgrid(g, g)
        return transmission_stop(np.maximum(0.0, np.exp(-(x * x + y * y)) - math.exp(-1.0)), "pbrt-v4 gaussian")
    if name == "square":
        return bladed_stop(4, 45.0, 0.0, math.sqrt(0.5))
    if name == "pentagon":
        return bladed_stop(5, -90.0, 0.0, 0.8)
    if name == "star":
        inner = math.cos(math.radians(72)) / math.cos(math.radians(36))
        angle = np.pi * np.arange(10) / 5
        radius = np.where(np.arange(10) % 2 == 1, 1.0, inner)
        drawn = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
        return polygon_stop(drawn * [1.0, -1.0], "pbrt-v4 star")
    raise UserError(f'unknown built-in aperture "{name}" (pbrt-v4 has {", ".join(V4_BUILTIN_APERTURES)})')
