"""pbrt's ``Material`` and ``MakeNamedMaterial`` types (v1/v2/v3 and v4 names) as scene materials.

Parameters and defaults per type as pbrt-v2 ``src/materials/*.cpp``, pbrt-v3 ``src/materials/*.cpp``
and pbrt-v4 ``src/pbrt/materials.cpp`` create them. Roughness follows the dialect
(``realistic.scene.materials``): pbrt-v1/v2 Blinn exponents 1 / r, pbrt-v3's ``RoughnessToAlpha``
polynomial and pbrt-v4's square root when ``remaproughness`` is true (the default), the value
itself when false. pbrt-v1/v2/v3 ``plastic`` (and pbrt-v1/v2 ``uber``) weight the coat by the
Fresnel reflectance of ``FresnelDielectric(1.5, 1)`` (pbrt-v3 ``src/materials/plastic.cpp``: index
1.5 outside, 1 inside, so the coat reflects totally beyond 41.8 degrees from the microfacet
normal), reproduced here as index 1 / 1.5; pbrt-v3 ``uber`` uses ``FresnelDielectric(1, eta)``.

Where a type has no exact counterpart, the closest material is rendered and a warning names the
file and line (once per message): ``uber`` as plastic, ``translucent`` as diffuse transmission,
pbrt-v4 ``coateddiffuse`` as a diffuse base under an infinitely thin coat, ``coatedconductor`` as its
conductor, the subsurface, ``hair`` and ``fourier`` types as matte. Bump maps and displacement are
ignored with a warning. Rough ``glass`` (pbrt-v3) and ``dielectric`` (pbrt-v4) are rendered with
pbrt-v4's rough ``DielectricBxDF``; pbrt-v1/v2 glass and ``thindielectric`` are smooth.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from realistic.core.pbrt_spectra import CONVERSION_OF_DIALECT, sampled_rgb
from realistic.core.validation import finite
from realistic.errors import UserError
from realistic.scene.materials import (
    CoatedDiffuse,
    Colour,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Measured,
    Mirror,
    Mix,
    Plastic,
    Scalar,
    ScaledTexture,
    Substrate,
    SurfaceMaterial,
)
from realistic.scene.measured import float_file_numbers, load_measured, spectrum_to_rgb
from realistic.scene.metals import TABLES, copper, named_metal
from realistic.scene.model import RGB, Material
from realistic.scene.pbrt.parser import Declaration, Params

#: Copper (``realistic.scene.metals``), the default metal of pbrt-v2/v3 ``metal`` and pbrt-v4
#: ``conductor``; pbrt-v4's named metal spectra ("metal-Au-eta", ...) are ``metals.TABLES``', and
#: those not tabulated there (brass, "metal-CuZn-...") fall back to copper with a warning.
COPPER_ETA, COPPER_K = copper()
MAX_MIX_DEPTH = 16


class MaterialContext(Protocol):
    """What the importer lends: warnings, textures as colour x texture, files, named materials."""

    @property
    def dialect_name(self) -> str: ...

    def warn(self, where: str, message: str) -> None: ...

    def texture_material(self, name: str, where: str) -> Material: ...

    def find(self, name: str, directory: Path, where: str, what: str) -> Path: ...

    def named_material(self, name: str) -> Declaration | None: ...


@dataclass
class _Reader:
    """One declaration's parameters read as colours and scalars (constants or textures)."""

    declaration: Declaration
    context: MaterialContext

    @property
    def where(self) -> str:
        return self.declaration.where

    @property
    def params(self) -> Params:
        return self.declaration.params

    def has(self, name: str) -> bool:
        return self.params.has(name)

    def colour(self, name: str, default: RGB) -> Colour:
        """The colour parameter ``name``: a constant, a texture or a spectrum as RGB; ``default`` when absent."""
        p = self.params.items.get(name)
        if p is None:
            return default
        if p.type == "texture":
            return self.texture(name)
        if p.type == "spectrum":
            return self.spectrum(name, default)
        if p.type in ("blackbody", "xyz") or len(p.values) not in (1, 3):
            self.context.warn(self.where, f'"{p.type} {name}" in Material "{self.declaration.type}" (the default used)')
            return default
        values = self.params.get_floats(name, [])
        return (values[0], values[0], values[0]) if len(values) == 1 else (values[0], values[1], values[2])

    def spectrum(self, name: str, default: RGB) -> RGB:
        """A "spectrum" parameter: (wavelength, value) pairs or a .spd file of them, as RGB."""
        p = self.params.items[name]
        if len(p.values) == 1 and isinstance(p.values[0], str):
            text = p.values[0]
            metal = re.fullmatch(r"metal-(\w+)-(eta|k)", text)
            if metal and metal.group(1) in TABLES:
                return named_metal(metal.group(1))[metal.group(2) == "k"]
            if text.startswith("metal-"):
                self.context.warn(self.where, f'named spectrum "{text}" (copper\'s used)')
                return COPPER_ETA if text.endswith("eta") else COPPER_K
            path = self.context.find(text, Path(self.where.rsplit(":", 1)[0]).parent, self.where, "spectrum file")
            try:
                values = list(float_file_numbers(path.read_bytes()))  # pbrt reads .spd files with ReadFloatFile
            except (OSError, ValueError) as err:
                raise UserError(f"{self.where}: spectrum file {path}: {err}") from None
        else:
            values = self.params.get_floats(name, [])
        if len(values) < 2 or len(values) % 2:
            raise UserError(f'{self.where}: "spectrum {name}" needs (wavelength, value) pairs, got {len(values)} '
                            f"numbers")
        pairs = np.asarray(values, np.float64).reshape(-1, 2)
        if not np.all(np.isfinite(pairs)) or np.any(np.diff(pairs[:, 0]) <= 0):
            raise UserError(f'{self.where}: "spectrum {name}" wavelengths must increase and values be finite')
        conversion = CONVERSION_OF_DIALECT[self.context.dialect_name]
        if conversion == "v4":  # evaluated spectrally by pbrt-v4; white balanced here (a flat 1 is white)
            rgb = spectrum_to_rgb(pairs[:, 0], pairs[None, :, 1])[0]
        else:  # pbrt-v1/v2/v3 files: their own RGBSpectrum::FromSampled
            rgb = sampled_rgb(pairs[:, 0], pairs[None, :, 1], conversion)[0]
        return float(rgb[0]), float(rgb[1]), float(rgb[2])

    def texture(self, name: str) -> Colour:
        """The texture parameter ``name`` as a colour: the texture, scaled by its colour unless white."""
        texture_name = self.params.get_string(name)
        if not texture_name:
            raise UserError(f'{self.where}: "texture {name}" needs the name of a texture')
        made = self.context.texture_material(texture_name, self.where)
        if made.texture is None:
            return made.diffuse
        return made.texture if made.diffuse == (1.0, 1.0, 1.0) else ScaledTexture(made.texture, made.diffuse)

    def scalar(self, name: str, default: Scalar) -> Scalar:
        """The scalar parameter ``name``: a number or a texture (a constant texture's mean); ``default`` when absent."""
        p = self.params.items.get(name)
        if p is None:
            return default
        if p.type == "texture":
            value = self.texture(name)
            return float(np.mean(value)) if isinstance(value, tuple) else value
        number = self.params.get_float(name)
        return default if number is None else finite(number, f'"{name}" of Material "{self.declaration.type}"')

    def flag(self, name: str, default: bool) -> bool:
        p = self.params.items.get(name)
        return default if p is None or not p.values else p.values[0] is True

    def rule(self) -> str:
        """How this dialect turns roughness into GGX alpha."""
        if self.context.dialect_name in ("v1", "v2"):
            return "blinn"
        if not self.flag("remaproughness", True):
            return "alpha"
        return "pbrt-v3" if self.context.dialect_name == "v3" else "sqrt"

    def roughness_pair(self, default: float) -> tuple[Scalar, Scalar]:
        r = self.scalar("roughness", default)
        return self.scalar("uroughness", r), self.scalar("vroughness", r)

    def approximate(self, what: str) -> None:
        self.context.warn(self.where, f'Material "{self.declaration.type}", rendered as {what}')


def _v4(context: MaterialContext) -> bool:
    return context.dialect_name == "v4"


def build_material(declaration: Declaration, context: MaterialContext, depth: int = 0) -> SurfaceMaterial:
    """The scene material a pbrt material declaration describes (warnings through ``context``)."""
    r = _Reader(declaration, context)
    kind = declaration.type
    for bump in ("bumpmap", "displacement", "normalmap"):
        if r.has(bump):
            context.warn(declaration.where, f'"{bump}" of Material "{kind}" (ignored)')
    if kind in ("matte", "diffuse"):
        return _matte(r, "Kd" if r.has("Kd") or kind == "matte" else "reflectance", 0.5)
    if kind in ("plastic", "uber"):
        eta = 1.0 / 1.5
        if kind == "uber":
            r.approximate("plastic (its Kr, Kt and opacity ignored)")
            if context.dialect_name == "v3":  # pbrt-v3 uber.cpp: FresnelDielectric(1, eta), eta default 1.5
                given = r.scalar("eta", r.scalar("index", 1.5))
                eta = given if isinstance(given, float) and given > 0 else 1.5
        rough = r.scalar("roughness", 0.1)
        return Plastic(r.colour("Kd", (0.25,) * 3), r.colour("Ks", (0.25,) * 3), rough, r.rule(), eta)
    if kind == "coateddiffuse":
        r.approximate("a diffuse base under a thin coat (the layer's thickness, albedo and g ignored)")
        ru, _ = r.roughness_pair(0.0)
        coat_eta = r.scalar("eta", 1.5)
        return CoatedDiffuse(r.colour("reflectance", (0.5,) * 3), ru, r.rule(),
                             coat_eta if isinstance(coat_eta, float) and coat_eta > 0 else 1.5)
    if kind in ("metal", "conductor", "coatedconductor", "shinymetal"):
        return _conductor(r)
    if kind == "mirror":
        return Mirror(r.colour("Kr", (0.9,) * 3))
    if kind in ("glass", "dielectric", "thindielectric"):
        given = r.scalar("eta", r.scalar("index", 1.5) if not _v4(context) else 1.5)
        if isinstance(given, float):
            eta = given
        else:
            context.warn(declaration.where, f'textured or spectral eta of Material "{kind}" (1.5 used)')
            eta = 1.5
        kr, kt = r.colour("Kr", (1.0,) * 3), r.colour("Kt", (1.0,) * 3)
        if kind == "thindielectric" or context.dialect_name in ("v1", "v2"):  # smooth only
            return Dielectric(eta, kr, kt, kind == "thindielectric")
        # pbrt-v4 DielectricMaterial::Create: u/vroughness default to roughness (0); pbrt-v3
        # CreateGlassMaterial (src/materials/glass.cpp): uroughness and vroughness only, default 0
        ru, rv = r.roughness_pair(0.0) if _v4(context) else (r.scalar("uroughness", 0.0), r.scalar("vroughness", 0.0))
        rule = r.rule()  # read (used) whatever the roughness, as pbrt reads it
        if ru == rv == 0.0:
            return Dielectric(eta, kr, kt)
        return Dielectric(eta, kr, kt, False, ru, rv, rule)
    if kind == "substrate":
        ru, rv = r.roughness_pair(0.1)
        return Substrate(r.colour("Kd", (0.5,) * 3), r.colour("Ks", (0.5,) * 3), ru, rv, r.rule())
    if kind == "diffusetransmission":
        scale = r.scalar("scale", 1.0)
        scale = scale if isinstance(scale, float) else 1.0
        refl, trans = r.colour("reflectance", (0.25,) * 3), r.colour("transmittance", (0.25,) * 3)
        return DiffuseTransmission(_times(refl, scale), _times(trans, scale))
    if kind == "translucent":
        r.approximate("diffuse transmission of Kd times reflect and transmit (its glossy Ks ignored)")
        kd = r.colour("Kd", (0.25,) * 3)
        reflect, transmit = r.colour("reflect", (0.5,) * 3), r.colour("transmit", (0.5,) * 3)
        if not isinstance(kd, tuple) and not (isinstance(reflect, tuple) and isinstance(transmit, tuple)):
            context.warn(declaration.where, 'textured "reflect" or "transmit" with a textured Kd in Material '
                                            '"translucent" (the Kd texture alone is used)')
        return DiffuseTransmission(_product(kd, reflect), _product(kd, transmit))
    if kind == "measured":
        return _measured(r)
    if kind == "mix":
        return _mix(r, depth)
    if kind in ("interface", "none", ""):
        r.approximate("a clear boundary of index 1 (light passes straight through)")
        return Dielectric(1.0)
    if kind in ("kdsubsurface", "subsurface", "hair", "fourier"):
        r.approximate("matte with its Kd or reflectance (grey when it has none)")
        return _matte(r, "reflectance" if r.has("reflectance") else "Kd", 0.5)
    context.warn(declaration.where, f'Material "{kind}", rendered as matte grey')
    return Material((0.5, 0.5, 0.5))


def _times(colour: Colour, scale: float) -> Colour:
    """``colour`` times a constant ``scale``."""
    if isinstance(colour, tuple):
        return _rgb_product(colour, (scale, scale, scale))
    if isinstance(colour, ScaledTexture):
        return ScaledTexture(colour.texture, _rgb_product(colour.scale, (scale, scale, scale)))
    return ScaledTexture(colour, (scale, scale, scale)) if scale != 1.0 else colour


def _product(a: Colour, b: Colour) -> Colour:
    """The product of two colours (a texture times a constant; of two textures only the first is kept)."""
    if isinstance(b, tuple):
        return _times_rgb(a, b)
    if isinstance(a, tuple):
        return _times_rgb(b, a)
    return a


def _times_rgb(colour: Colour, rgb: RGB) -> Colour:
    """``colour`` times the constant ``rgb``."""
    if isinstance(colour, tuple):
        return _rgb_product(colour, rgb)
    if isinstance(colour, ScaledTexture):
        return ScaledTexture(colour.texture, _rgb_product(colour.scale, rgb))
    return ScaledTexture(colour, rgb)


def _rgb_product(a: RGB, b: RGB) -> RGB:
    return a[0] * b[0], a[1] * b[1], a[2] * b[2]


def _matte(r: _Reader, name: str, default: float) -> Material:
    colour = r.colour(name, (default,) * 3)
    sigma = r.scalar("sigma", 0.0)
    if not isinstance(sigma, float):
        r.context.warn(r.where, "a textured Oren-Nayar sigma (its mean is not known here; 0 used)")
        sigma = 0.0
    sigma = min(abs(sigma), 90.0)
    if isinstance(colour, tuple):
        return Material(_albedo(r, name, colour), None, sigma)
    if isinstance(colour, ScaledTexture):
        return Material(colour.scale, colour.texture, sigma)
    return Material((1.0, 1.0, 1.0), colour, sigma)


def _albedo(r: _Reader, name: str, colour: RGB) -> RGB:
    """A constant diffuse reflectance clamped to [0, 1], with a warning when that changes it: pbrt-v4
    clamps it so (``src/pbrt/materials.h``, DiffuseMaterial::GetBxDF: Clamp(r, 0, 1)); pbrt-v3 clamps
    only below 0 (``src/materials/matte.cpp``: Kd->Evaluate(*si).Clamp()), which lets a surface reflect
    more light than it receives. A value that is not finite is refused."""
    for value in colour:
        finite(value, f'matte "{name}"')
    clamped = (min(max(colour[0], 0.0), 1.0), min(max(colour[1], 0.0), 1.0), min(max(colour[2], 0.0), 1.0))
    if clamped != tuple(colour):
        shown = " ".join(f"{c:g}" for c in colour)
        r.context.warn(r.where, f'matte "{name}" [{shown}] outside [0, 1] (clamped to it, as pbrt-v4 does)')
    return clamped


def _conductor(r: _Reader) -> Conductor:
    kind = r.declaration.type
    prefix = "conductor." if kind == "coatedconductor" else ""
    if kind == "coatedconductor":
        r.approximate("its conductor without the dielectric coat")
    if kind == "shinymetal" or r.has(prefix + "reflectance"):
        # pbrt-v1/v2 shinymetal (Ks) and pbrt-v4 conductor "reflectance": k from the reflectance R at
        # normal incidence with eta = 1, k = 2 sqrt(R) / sqrt(1 - R) (pbrt-v4 ``ConductorMaterial``).
        reflectance = r.colour("Ks" if kind == "shinymetal" else prefix + "reflectance", (1.0,) * 3)
        if not isinstance(reflectance, tuple):
            r.context.warn(r.where, f'a textured reflectance of Material "{kind}" (its mean 0.5 used)')
            reflectance = (0.5,) * 3
        rr = np.clip(np.asarray(reflectance, np.float64), 0.0, 0.9999)
        k_red, k_green, k_blue = (float(v) for v in 2 * np.sqrt(rr) / np.sqrt(1 - rr))
        ru, rv = r.roughness_pair(0.1 if kind == "shinymetal" else 0.0)
        return Conductor((1.0, 1.0, 1.0), (k_red, k_green, k_blue), ru, rv, r.rule())
    copper_eta, copper_k = _copper(r.context.dialect_name)
    eta = r.colour(prefix + "eta", copper_eta)
    k = r.colour(prefix + "k", copper_k)
    ru, rv = r.roughness_pair(0.0 if _v4(r.context) else 0.01)
    if kind == "coatedconductor":
        ru = r.scalar("conductor.uroughness", r.scalar("conductor.roughness", 0.0))
        rv = r.scalar("conductor.vroughness", r.scalar("conductor.roughness", 0.0))
    eta_metal, k_metal = _named_metal(r, prefix + "eta"), _named_metal(r, prefix + "k")
    spectra = (eta_metal, k_metal) if _v4(r.context) and eta_metal and k_metal else None
    return Conductor(eta, k, ru, rv, r.rule(), spectra=spectra)


def _named_metal(r: _Reader, name: str) -> str | None:
    """The metal of ``metals.TABLES`` whose spectrum the conductor parameter ``name`` ("eta" or "k",
    maybe prefixed) is: the one "spectrum <name>" "metal-<metal>-<eta|k>" names, copper when absent
    (pbrt-v4 ``ConductorMaterial::Create``'s default), None when given otherwise (RGB, texture, file)."""
    p = r.params.items.get(name)
    if p is None:
        return "Cu"
    which = name.rsplit(".", 1)[-1]
    if p.type == "spectrum" and len(p.values) == 1 and isinstance(p.values[0], str):
        metal = re.fullmatch(rf"metal-(\w+)-{which}", p.values[0])
        if metal and metal.group(1) in TABLES:
            return metal.group(1)
    return None


def _copper(dialect_name: str) -> tuple[RGB, RGB]:
    """The default metal, copper, as the dialect's pbrt turns its tables into RGB: pbrt-v2/v3
    ``metal.cpp`` by ``Spectrum::FromSampled(CopperWavelengths, CopperN, ...)``, pbrt-v4 spectrally
    (white balanced here)."""
    conversion = CONVERSION_OF_DIALECT[dialect_name]
    if conversion == "v4":
        return COPPER_ETA, COPPER_K
    nm, n, k = TABLES["Cu"]
    eta_rgb, k_rgb = sampled_rgb(np.asarray(nm), np.array([n, k]), conversion)
    return (float(eta_rgb[0]), float(eta_rgb[1]), float(eta_rgb[2])), (float(k_rgb[0]), float(k_rgb[1]),
                                                                        float(k_rgb[2]))


def _measured(r: _Reader) -> SurfaceMaterial:
    filename = r.params.get_string("filename")
    if not filename:
        raise UserError(f'{r.where}: Material "measured" has no "string filename"')
    if filename.lower().endswith(".bsdf"):
        r.approximate("matte grey (pbrt-v4's .bsdf measured format is not read)")
        return Material((0.5, 0.5, 0.5))
    path = r.context.find(filename, Path(r.where.rsplit(":", 1)[0]).parent, r.where, "measured BRDF file")
    try:
        load_measured(str(path))  # read now, so a bad file is an error naming the scene line
    except UserError as err:
        raise UserError(f"{r.where}: {err}") from None
    return Measured(str(path))


def _mix(r: _Reader, depth: int) -> SurfaceMaterial:
    if depth > MAX_MIX_DEPTH:
        raise UserError(f'{r.where}: Material "mix" nested more than {MAX_MIX_DEPTH} deep (a mix made of itself?)')
    p = r.params.items.get("materials")
    if p is not None:  # pbrt-v4: two names; amount is the chance of the second
        names: list[str | None] = [v for v in p.values if isinstance(v, str)]
        if len(names) != 2:
            raise UserError(f'{r.where}: Material "mix" needs two "materials", got {len(names)}')
        swap = False
    else:  # pbrt-v1/v2/v3: amount weights namedmaterial1
        names = [r.params.get_string("namedmaterial1"), r.params.get_string("namedmaterial2")]
        swap = True
    parts: list[SurfaceMaterial] = []
    for name in names:
        declaration = r.context.named_material(name) if name else None
        if declaration is None:
            raise UserError(f'{r.where}: Material "mix" names material "{name}", which is not defined')
        parts.append(build_material(declaration, r.context, depth + 1))
    amount = r.scalar("amount", 0.5)
    if isinstance(amount, float):
        amount = min(max(amount, 0.0), 1.0)
    if swap:
        return Mix(parts[1], parts[0], amount)
    return Mix(parts[0], parts[1], amount)
