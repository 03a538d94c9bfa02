"""Scene materials beyond the Lambertian ``model.Material``: what each surface is, not how it is shaded.

Every parameter that pbrt lets a texture drive is a ``Colour`` or a ``Scalar``: a constant, a
texture (``model.Texture``) or a ``ScaledTexture`` (pbrt's ``scale`` texture of an image by a
constant); the renderer looks them up at the hits (``renderer.bsdf``). Microfacet roughness is
stored as written in the scene with the rule that turns it into the GGX alpha
(``ROUGHNESS_RULES``), because the rule differs between pbrt versions and a roughness texture must
be remapped per hit:

- ``"alpha"``: the value is alpha itself (pbrt-v3/v4 with ``remaproughness`` false);
- ``"pbrt-v3"``: pbrt-v3's ``TrowbridgeReitzDistribution::RoughnessToAlpha`` polynomial in log(r);
- ``"sqrt"``: pbrt-v4's ``RoughnessToAlpha``, alpha = sqrt(r);
- ``"blinn"``: pbrt-v1/v2, whose metal, plastic and substrate use a Blinn exponent e = 1 / r
  (anisotropic: 1 / u, 1 / v); alpha = sqrt(2 / (e + 2)), the Beckmann width matching that Blinn
  lobe (Walter et al. 2007, section 5.2), rendered with GGX: an approximation.

``Mix`` is a weighted sum of two materials' BSDFs with ``amount`` the weight of ``second`` (pbrt-v4's
meaning; pbrt-v1/v2/v3 weight the first material by amount, so their importer swaps the pair); the
renderer picks one lobe per sample in proportion to the weights, which has pbrt-v4's stochastic
choice per hit as its expectation.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from realistic.core import validation
from realistic.errors import UserError
from realistic.scene.metals import TABLES, copper
from realistic.scene.surfaces import RGB, CheckerTexture, GridTexture, ImageTexture, Material

ROUGHNESS_RULES = ("alpha", "pbrt-v3", "sqrt", "blinn")


@dataclass(frozen=True)
class ScaledTexture:
    """A texture times a constant colour (pbrt's ``scale`` texture of an image by a colour)."""

    texture: ImageTexture | GridTexture | CheckerTexture
    scale: RGB = (1.0, 1.0, 1.0)


Colour = RGB | ImageTexture | GridTexture | CheckerTexture | ScaledTexture
Scalar = float | ImageTexture | GridTexture | CheckerTexture | ScaledTexture
_TEXTURES = (ImageTexture, GridTexture, CheckerTexture, ScaledTexture)


def _colour(value: object, name: str, low: float = 0.0) -> None:
    """A colour constant has three finite components >= ``low``; textures are checked where built."""
    if isinstance(value, _TEXTURES):
        return
    if not (isinstance(value, tuple) and len(value) == 3):
        raise UserError(f"{name} must be an RGB triple or a texture, got {value!r}")
    for component in value:
        if validation.finite(component, name) < low:
            raise UserError(f"{name} must not be below {low:g}, got {component:g}")


def _scalar(value: object, name: str, low: float = 0.0, high: float = math.inf) -> None:
    if isinstance(value, _TEXTURES):
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise UserError(f"{name} must be a number or a texture, got {value!r}")
    if not low <= validation.finite(value, name) <= high:
        raise UserError(f"{name} must be between {low:g} and {high:g}, got {value:g}")


def _rule(rule: str) -> None:
    if rule not in ROUGHNESS_RULES:
        raise UserError(f"roughness rule must be one of {', '.join(ROUGHNESS_RULES)}, got {rule!r}")


@dataclass(frozen=True)
class Plastic:
    """A diffuse base under a glossy dielectric reflection (pbrt's ``plastic``, and the
    approximation used for ``uber``): Lambertian ``diffuse`` plus
    a GGX lobe scaled by ``specular`` with the Fresnel reflectance of ``eta``. The two lobes add, as
    in pbrt-v2/v3, so ``diffuse + specular`` <= 1 conserves energy."""

    diffuse: Colour = (0.25, 0.25, 0.25)
    specular: Colour = (0.25, 0.25, 0.25)
    roughness: Scalar = 0.1
    rule: str = "alpha"
    eta: float = 1.5

    def __post_init__(self) -> None:
        _colour(self.diffuse, "plastic Kd")
        _colour(self.specular, "plastic Ks")
        _scalar(self.roughness, "plastic roughness")
        _rule(self.rule)
        _scalar(self.eta, "plastic eta", 1e-3, 1e3)


@dataclass(frozen=True)
class CoatedDiffuse:
    """pbrt-v4's ``coateddiffuse`` without the layer's medium: a Lambertian base of ``reflectance``
    under a dielectric coat of index ``eta`` and GGX ``roughness`` (``renderer.bsdf.coated_diffuse``
    says how the base's light gets through the coat; the coat's roughness shapes its own reflection
    only). Conserves energy: a white base under a smooth coat reflects everything."""

    reflectance: Colour = (0.5, 0.5, 0.5)
    roughness: Scalar = 0.0
    rule: str = "alpha"
    eta: float = 1.5

    def __post_init__(self) -> None:
        _colour(self.reflectance, "coateddiffuse reflectance")
        _scalar(self.roughness, "coateddiffuse roughness")
        _rule(self.rule)
        _scalar(self.eta, "coateddiffuse eta", 1e-3, 1e3)


@dataclass(frozen=True)
class Conductor:
    """A metal: GGX microfacets (``roughness`` u and v) with the conductor Fresnel reflectance of a
    complex index ``eta`` + i ``k`` (RGB; copper by default); roughness 0 is a perfect mirror. ``scale`` tints it
    (pbrt-v1/v2 shinymetal's reflectance, 1 otherwise). ``spectra``: the named metals (``metals.TABLES``)
    whose eta and k spectra these are, for pbrt-v4's spectral Fresnel (``metals.reflectance_table``) in
    place of Fresnel of the RGB eta and k; None for RGB indices."""

    eta: Colour = copper()[0]
    k: Colour = copper()[1]
    roughness_u: Scalar = 0.01
    roughness_v: Scalar = 0.01
    rule: str = "alpha"
    scale: Colour = (1.0, 1.0, 1.0)
    spectra: tuple[str, str] | None = None

    def __post_init__(self) -> None:
        if self.spectra is not None and not set(self.spectra) <= set(TABLES):
            raise UserError(f"conductor spectra must name metals among {', '.join(sorted(TABLES))}, "
                            f"got {self.spectra!r}")
        _colour(self.eta, "conductor eta", 1e-4)
        _colour(self.k, "conductor k")
        _scalar(self.roughness_u, "conductor uroughness")
        _scalar(self.roughness_v, "conductor vroughness")
        _rule(self.rule)
        _colour(self.scale, "conductor reflectance")


@dataclass(frozen=True)
class Mirror:
    """Perfect specular reflection of ``reflectance`` (pbrt's ``mirror``, Kr)."""

    reflectance: Colour = (0.9, 0.9, 0.9)

    def __post_init__(self) -> None:
        _colour(self.reflectance, "mirror Kr")


@dataclass(frozen=True)
class Dielectric:
    """Glass: reflection and refraction weighted by the dielectric Fresnel equations for the index
    ``eta`` (outside 1), tinted by ``reflectance`` (Kr) and ``transmittance`` (Kt); smooth where
    ``roughness_u`` and ``roughness_v`` are 0, else GGX microfacets (pbrt-v4's ``DielectricBxDF``;
    the rule turns roughness into alpha as for the other materials). ``thin``: pbrt-v4's
    ``thindielectric``, a smooth slab whose inner reflections are summed and whose transmission
    goes straight through."""

    eta: float = 1.5
    reflectance: Colour = (1.0, 1.0, 1.0)
    transmittance: Colour = (1.0, 1.0, 1.0)
    thin: bool = False
    roughness_u: Scalar = 0.0
    roughness_v: Scalar = 0.0
    rule: str = "alpha"

    def __post_init__(self) -> None:
        _scalar(self.eta, "dielectric eta", 1e-3, 1e3)
        _colour(self.reflectance, "dielectric Kr")
        _colour(self.transmittance, "dielectric Kt")
        _scalar(self.roughness_u, "dielectric uroughness")
        _scalar(self.roughness_v, "dielectric vroughness")
        _rule(self.rule)
        if self.thin and not self.roughness_u == self.roughness_v == 0.0:
            raise UserError("a thin dielectric is smooth: its roughness must be 0")


@dataclass(frozen=True)
class Substrate:
    """pbrt's ``substrate``: Ashikhmin and Shirley's FresnelBlend of a diffuse base and a glossy
    coat of normal-incidence reflectance ``specular`` (GGX, roughness u and v)."""

    diffuse: Colour = (0.5, 0.5, 0.5)
    specular: Colour = (0.5, 0.5, 0.5)
    roughness_u: Scalar = 0.1
    roughness_v: Scalar = 0.1
    rule: str = "alpha"

    def __post_init__(self) -> None:
        _colour(self.diffuse, "substrate Kd")
        _colour(self.specular, "substrate Ks")
        _scalar(self.roughness_u, "substrate uroughness")
        _scalar(self.roughness_v, "substrate vroughness")
        _rule(self.rule)


@dataclass(frozen=True)
class DiffuseTransmission:
    """pbrt-v4's ``diffusetransmission`` (and the closest form of pbrt-v2/v3 ``translucent``):
    Lambertian reflection of ``reflectance`` and Lambertian transmission of ``transmittance``."""

    reflectance: Colour = (0.25, 0.25, 0.25)
    transmittance: Colour = (0.25, 0.25, 0.25)

    def __post_init__(self) -> None:
        _colour(self.reflectance, "diffusetransmission reflectance")
        _colour(self.transmittance, "diffusetransmission transmittance")


@dataclass(frozen=True)
class Measured:
    """A measured BRDF file (pbrt-v2's two formats; ``scene.measured`` reads them): ``path`` of a
    ``.brdf`` irregular isotropic sample file or a MERL half-angle table (any other suffix)."""

    path: str


@dataclass(frozen=True)
class Mix:
    """The weighted sum (1 - amount) first + amount second (see the module docstring)."""

    first: SurfaceMaterial
    second: SurfaceMaterial
    amount: Scalar = 0.5

    def __post_init__(self) -> None:
        _scalar(self.amount, "mix amount", 0.0, 1.0)


SurfaceMaterial = (Material | Plastic | CoatedDiffuse | Conductor | Mirror | Dielectric | Substrate
                   | DiffuseTransmission | Measured | Mix)
