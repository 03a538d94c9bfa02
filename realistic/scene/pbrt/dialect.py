"""Which pbrt a scene file was written for, and the conventions that differ between versions.

Every convention that depends on the pbrt version is decided here, once per scene, and read by the
importer; nowhere else asks which version a file is. The image-texture orientation:

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
``wrap`` "repeat", ``scale`` 1.

``auto`` decides from what the file uses: v4-only directives (``ColorSpace``, ``Option``,
``Attribute``, ``Import``) or ``Film "rgb"`` mean v4; the classic homework camera (``specfile``,
``filmdistance``, ``filmdiag``, ``aperture_diameter``) or v2-only directives (``SurfaceIntegrator``,
``VolumeIntegrator``, ``Renderer``) mean v2; pbrt-v3's realistic camera parameters (``lensfile``,
``aperturediameter``, ``focusdistance``) or ``Integrator``/``MakeNamedMedium`` mean v3 (or v4). A
file with no signal is read as v3; one with signals of two versions is read as the newest, with a
warning. v1 is never chosen automatically: nothing in a file tells it from v2, and v1 and v2 share
their conventions.
"""

from __future__ import annotations

from dataclasses import dataclass

from realistic.errors import UserError
from realistic.scene.pbrt.parser import PbrtScene

DIALECTS = ("auto", "v1", "v2", "v3", "v4")
_V4_DIRECTIVES = ("ColorSpace", "Option", "Attribute", "Import")
_V2_DIRECTIVES = ("SurfaceIntegrator", "VolumeIntegrator", "Renderer")
_V3_DIRECTIVES = ("Integrator", "MakeNamedMedium")
_HOMEWORK_CAMERA = ("specfile", "filmdistance", "filmdiag", "aperture_diameter")
_V3_CAMERA = ("lensfile", "aperturediameter", "focusdistance")


@dataclass(frozen=True)
class ImagemapConventions:
    """How a pbrt version spells an imagemap's filter and colour encoding, and their defaults."""

    filter_parameter: str  # "trilinear" (a bool: trilinear or EWA) or "filter" (a name)
    default_filter: str
    encoding_parameter: str  # "gamma exponent", "gamma sRGB" (a bool) or "encoding" (a name)
    max_anisotropy: float = 8.0
    wrap: str = "repeat"
    scale: float = 1.0


_IMAGEMAP = {"v1": ImagemapConventions("trilinear", "ewa", "gamma exponent"),
             "v2": ImagemapConventions("trilinear", "ewa", "gamma exponent"),
             "v3": ImagemapConventions("trilinear", "ewa", "gamma sRGB"),
             "v4": ImagemapConventions("filter", "bilinear", "encoding")}


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
    def imagemap(self) -> ImagemapConventions:
        """The imagemap texture's parameter names and defaults in this version."""
        return _IMAGEMAP[self.name]

    def describe(self) -> str:
        return f"pbrt-{self.name} ({self.reason})"


def _signals(parsed: PbrtScene) -> dict[str, list[str]]:
    """Per version, the signals the file gives for it (each as 'what at file:line')."""
    found: dict[str, list[str]] = {"v2": [], "v3": [], "v4": []}
    for version, names in (("v4", _V4_DIRECTIVES), ("v2", _V2_DIRECTIVES), ("v3", _V3_DIRECTIVES)):
        found[version] += [f"{name} at {parsed.directives[name]}" for name in names if name in parsed.directives]
    if parsed.film is not None and parsed.film.type == "rgb":
        found["v4"].append(f'Film "rgb" at {parsed.film.where}')
    camera = parsed.camera
    if camera is not None and camera.type == "realistic":
        for version, names in (("v2", _HOMEWORK_CAMERA), ("v3", _V3_CAMERA)):
            used = [name for name in names if camera.params.has(name)]
            if used:
                found[version].append(f"realistic camera's {', '.join(used)} at {camera.where}")
    return found


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
    if len(found) > 1:
        others = "; ".join(f"{version}: {found[version][0]}" for version in sorted(found) if version != chosen)
        parsed.warn(str(parsed.path), f"the file mixes pbrt versions ({others}); read as pbrt-{chosen}")
    return Dialect(chosen, found[chosen][0])
