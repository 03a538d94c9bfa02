"""Float64 numpy reference tracer: rays from the film through every surface into the scene.

Written for clarity; it is the oracle the OpenCL kernel is tested against, and the ``numpy``
backend. Lens frame as in ``realistic.optics.lens``: film at z = 0, +z toward the scene.

Rules (the kernel follows the same ones):

* Spherical surface: the ray-sphere root is chosen by direction, as the surface's vertex cap is
  met: for a ray travelling +z, the far root when R > 0 (centre on the film side), the near root
  when R < 0. A hit on the far hemisphere of the sphere is a miss.
* The stop and flat surfaces are planes z = vertex.
* An aspheric surface (``realistic.optics.asphere``) is met by Newton's method on
  F(t) = w(t) + sag(r(t)) (w: axial position relative to the vertex, + toward the scene), started
  from the nearer root ahead on the base conic's vertex branch (exact for a pure conic; the vertex
  plane's root when the ray misses that branch). Its normal is the sag's gradient (2 x s', 2 y s', 1). A ray the
  iteration does not bring to the surface (|F| above ``ASPHERE_TOLERANCE_MM``, or outside the
  conic's domain), or that meets it outside the clear aperture, is blocked with reason ``asphere``.
* A surface 0 mm from the one the ray left (``build_lens`` has checked that it nowhere lies behind
  it) is met wherever the ray meets it: rounding may put the hit a hair behind the ray's start near
  the vertex, so its hit is not required to be ahead (``ahead``).
* A hit farther from the axis than half the clear aperture blocks the ray (``stop`` at the stop,
  ``aperture`` elsewhere); a shaped stop (``realistic.optics.stop_shape``) blocks what falls outside its
  opening.
* Refraction in Heckbert's form T = eta I + (eta c1 - c2) N, N facing the incoming ray,
  c1 = -I.N, c2 = sqrt(1 - eta^2 (1 - c1^2)); a negative radicand is total internal reflection.
* A paraxial surface (``LensSystem.paraxial_power_per_mm``, powers p_x, p_y) is met as a plane; a ray
  at (x, y) with slopes (u_x, u_y) along its travel leaves with slopes (u_x - x p_x, u_y - y p_y)
  (``paraxial_deflect``), and loses no light.
* At each refracting surface the ray keeps the fraction (Ts + Tp) / 2 that its coating
  (``LensSystem.coating``, ``realistic.optics.coating``) transmits at its incidence cosine c1, its
  wavelength and the two media's indices: ``TraceResult.transmittance``, 1 under ``ideal``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from realistic.optics.asphere import conic_radicand, sag_and_slope, significant
from realistic.optics.coating import IDEAL, transmittance
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.lens import LensSystem

PASSED, MISS, APERTURE, STOP, TIR, ASPHERE = 0, 1, 2, 3, 4, 5
REASONS = {MISS: "miss", APERTURE: "aperture", STOP: "stop", TIR: "tir", ASPHERE: "asphere"}
#: Newton steps on an aspheric surface; the conic start leaves only the polynomial's correction,
#: which converges quadratically in a few steps.
ASPHERE_ITERATIONS = 16
#: Largest |w + sag| (mm) accepted as a hit on an aspheric surface.
ASPHERE_TOLERANCE_MM = 1e-9

#: Per-ray vectors as (x, y, z) arrays (structure of arrays, as in the kernel).
Vectors = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class TraceResult:
    """Per ray: the ray leaving the front surface (NaN when blocked) or where and why it stopped."""

    origin: np.ndarray  # (N, 3) hit on the front surface
    direction: np.ndarray  # (N, 3) unit direction into the scene
    blocked_surface: np.ndarray  # (N,) surface index from 0 at the front, -1 when the ray passed
    blocked_reason: np.ndarray  # (N,) PASSED, MISS, APERTURE, STOP, TIR or ASPHERE
    transmittance: np.ndarray  # (N,) product of the surfaces' Fresnel transmittances (1 under ``ideal``)

    @property
    def passed(self) -> np.ndarray:
        return self.blocked_reason == PASSED


def intersect_surface(o: Vectors, d: Vectors, vertex_z: float, radius: float,
                      ahead: bool = True) -> tuple[Vectors, Vectors, np.ndarray]:
    """Hit point, unit normal facing the incoming ray, and a miss mask for one surface.

    ``o`` and ``d`` are (x, y, z) tuples of arrays (structure of arrays, as in the kernel); ``ahead``
    False: a touching surface (module docstring), whose hit need not be ahead of ``o``.
    """
    ox, oy, oz = o
    dx, dy, dz = d
    if radius == 0 or not np.isfinite(radius):
        t = (vertex_z - oz) / dz
        miss = ~(t > 0) & ahead
        hit = (ox + t * dx, oy + t * dy, oz + t * dz)
        return hit, (np.zeros_like(dz), np.zeros_like(dz), -np.sign(dz)), miss
    centre_z = vertex_z - radius
    ocz = oz - centre_z
    b = ox * dx + oy * dy + ocz * dz
    c = ox * ox + oy * oy + ocz * ocz - radius * radius
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    use_near = (dz > 0) == (radius < 0)
    t = np.where(use_near, -b - root, -b + root)
    hx, hy, hz = ox + t * dx, oy + t * dy, oz + t * dz
    miss = (disc < 0) | (~(t > 0) & ahead) | ((hz - centre_z) * radius <= 0)
    # (hit - centre) / |R| is the outward unit normal; flip it to face the incoming ray.
    scale = np.where(hx * dx + hy * dy + (hz - centre_z) * dz > 0, -1.0, 1.0) / abs(radius)
    normal = (hx * scale, hy * scale, (hz - centre_z) * scale)
    return (hx, hy, hz), normal, miss


def intersect_asphere(o: Vectors, d: Vectors, vertex_z: float, radius: float, conic: float,
                      coefficients: np.ndarray, ahead: bool = True) -> tuple[Vectors, Vectors, np.ndarray]:
    """Hit point, unit normal facing the incoming ray, and a failure mask for an aspheric surface
    (``ahead`` as in ``intersect_surface``)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # judged by the failure mask
        return _asphere_hit(o, d, vertex_z, radius, conic, coefficients, ahead)


def _asphere_hit(o: Vectors, d: Vectors, vertex_z: float, radius: float, conic: float,
                 coefficients: np.ndarray, ahead: bool) -> tuple[Vectors, Vectors, np.ndarray]:
    ox, oy, oz = o
    dx, dy, dz = d
    coefficients = significant(coefficients)
    c = 1.0 / radius if radius != 0 and np.isfinite(radius) else 0.0
    w = oz - vertex_z
    # The base conic c rho + 2 w + (1 + k) c w^2 = 0 along the ray: a t^2 + 2 b t + g = 0, roots in the
    # cancellation-free form. The vertex branch is where 1 + (1 + k) c w >= 0 (there it equals the square
    # root in the sag); of the roots ahead on it the nearer is taken, else the vertex plane's root.
    ck = (1.0 + conic) * c
    a = c * (dx * dx + dy * dy) + ck * dz * dz
    b = c * (ox * dx + oy * dy) + dz + ck * w * dz
    g = c * (ox * ox + oy * oy) + 2.0 * w + ck * w * w
    disc = b * b - a * g
    q = -(b + np.where(b < 0, -1.0, 1.0) * np.sqrt(np.maximum(disc, 0.0)))
    roots = [q / a, g / q]
    usable = [(disc >= 0) & (t > 0) & (1.0 + ck * (w + t * dz) >= 0) for t in roots]
    t = np.where(usable[0] & ~(usable[1] & (roots[1] < roots[0])), roots[0],
                 np.where(usable[1], roots[1], -w / dz))
    for _ in range(ASPHERE_ITERATIONS):
        hx, hy = ox + t * dx, oy + t * dy
        rho2 = hx * hx + hy * hy
        sag, slope = sag_and_slope(rho2, c, conic, coefficients)
        f = w + t * dz + sag
        t = t - f / (dz + 2.0 * slope * (hx * dx + hy * dy))
    hx, hy, hz = ox + t * dx, oy + t * dy, oz + t * dz
    rho2 = hx * hx + hy * hy
    sag, slope = sag_and_slope(rho2, c, conic, coefficients)
    f = hz - vertex_z + sag
    fail = ~(np.abs(f) <= ASPHERE_TOLERANCE_MM) | ~(conic_radicand(rho2, c, conic) >= 0) | (~(t > 0) & ahead)
    slope2 = 2.0 * slope
    nx, ny = hx * slope2, hy * slope2
    scale = np.where(nx * dx + ny * dy + dz > 0, -1.0, 1.0) / np.sqrt(nx * nx + ny * ny + 1.0)
    return (hx, hy, hz), (nx * scale, ny * scale, scale), fail


def incidence_cosine(d: Vectors, normal: Vectors) -> np.ndarray:
    """cos of the angle between unit ``d`` and unit ``normal`` facing it."""
    return -(d[0] * normal[0] + d[1] * normal[1] + d[2] * normal[2])


def refract(d: Vectors, normal: Vectors, eta: float | np.ndarray) -> tuple[Vectors, np.ndarray]:
    """Heckbert refraction of unit ``d`` at unit ``normal`` (facing it); returns (T, tir mask)."""
    dx, dy, dz = d
    nx, ny, nz = normal
    c1 = incidence_cosine(d, normal)
    c2sq = 1.0 - eta * eta * (1.0 - c1 * c1)
    tir = c2sq < 0
    k = eta * c1 - np.sqrt(np.maximum(c2sq, 0.0))
    tx, ty, tz = eta * dx + k * nx, eta * dy + k * ny, eta * dz + k * nz
    inv = 1.0 / np.sqrt(tx * tx + ty * ty + tz * tz)
    return (tx * inv, ty * inv, tz * inv), tir


def paraxial_deflect(hit: tuple[np.ndarray, ...], d: Vectors, power: np.ndarray) -> Vectors:
    """The unit direction leaving an ideal thin lens of powers ``power`` (p_x, p_y) at ``hit`` ((x, y)
    or (x, y, z)): its slopes along the travel axis, d_x / |d_z| and d_y / |d_z|, less x p_x and y p_y."""
    dx, dy, dz = d
    along = np.abs(dz)
    ux = dx / along - hit[0] * power[0]
    uy = dy / along - hit[1] * power[1]
    inv = 1.0 / np.sqrt(ux * ux + uy * uy + 1.0)
    return ux * inv, uy * inv, np.sign(dz) * inv


def _rows(v: Vectors, keep: np.ndarray) -> Vectors:
    """The rays that the mask ``keep`` selects, of each component of ``v``."""
    return v[0][keep], v[1][keep], v[2][keep]


def trace_from_film(lens: LensSystem, film_distance_mm: float, origins: np.ndarray, directions: np.ndarray,
                    wavelength_nm: float | np.ndarray = D_LINE_NM, path: list[np.ndarray] | None = None
                    ) -> TraceResult:
    """Trace rays starting at or behind the rear element through the lens, rear surface first.

    ``wavelength_nm`` is one wavelength for all rays or one per ray (N,); each glass's index
    follows it (a catalogue glass's formula or Cauchy, ``LensSystem.index_at``); media without a V number or
    catalogue glass keep n_d.

    With ``path`` given, the hit point (N, 3) on each surface is appended to it, rear surface
    first (for drawing ray fans). Without it, a ray blocked at a surface is not traced further
    (every step is per ray, so the others' results are the same bit for bit): the exit-pupil
    search, whose grids send most rays into an aperture, then traces only what still passes.
    """
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    length = np.sqrt(np.sum(directions * directions, axis=1))
    o: Vectors = (origins[:, 0].copy(), origins[:, 1].copy(), origins[:, 2].copy())
    d: Vectors = (directions[:, 0] / length, directions[:, 1] / length, directions[:, 2] / length)
    count = len(origins)
    surface = np.full(count, -1, dtype=np.int64)
    reason = np.zeros(count, dtype=np.int8)
    live = np.arange(count)  # the rays o and d hold, in order
    vertex_z = lens.vertex_z_mm(film_distance_mm)
    if np.ndim(wavelength_nm):
        wavelength_nm = np.broadcast_to(wavelength_nm, (count,))
    index = lens.index_at(wavelength_nm)  # (media,) or (media, count)
    aspheric, paraxial = lens.aspheric, lens.paraxial
    models = lens.interface_models
    transmitted = np.ones(count)

    def block(mask: np.ndarray, i: int, why: int) -> None:
        fresh = live[mask & (reason[live] == PASSED)]
        surface[fresh] = i
        reason[fresh] = why

    with np.errstate(invalid="ignore", divide="ignore"):
        for i in range(lens.surface_count - 1, -1, -1):
            ahead = i == lens.surface_count - 1 or lens.thickness_mm[i] != 0
            if aspheric[i]:
                o, normal, fail = intersect_asphere(o, d, vertex_z[i], lens.radius_mm[i], lens.conic[i],
                                                    lens.aspheric_coefficients[i], ahead)
                block(fail, i, ASPHERE)
            else:
                o, normal, miss = intersect_surface(o, d, vertex_z[i], lens.radius_mm[i], ahead)
                block(miss, i, MISS)
            if path is not None:
                path.append(np.stack(o, axis=1))
            if i == lens.stop and lens.stop_shape is not None:
                block(~lens.stop_shape.inside(o[0], o[1], lens.aperture_mm[i]), i, STOP)
            else:
                r2 = o[0] * o[0] + o[1] * o[1]
                block(~(r2 <= (lens.aperture_mm[i] / 2) ** 2), i,
                      STOP if i == lens.stop else ASPHERE if aspheric[i] else APERTURE)
            if paraxial[i]:
                d = paraxial_deflect(o, d, lens.paraxial_power_per_mm[i])
            elif i != lens.stop or not lens.stop_is_flat_in_air:
                n_front = index[i - 1] if i > 0 else 1.0
                eta = index[i] / n_front
                if models[i] != IDEAL:
                    n_in, n_out = (np.asarray(n)[..., live] if np.ndim(n) else n for n in (index[i], n_front))
                    lam = np.asarray(wavelength_nm)[live] if np.ndim(wavelength_nm) else wavelength_nm
                    transmitted[live] *= transmittance(models[i], n_in, n_out, incidence_cosine(d, normal), lam)
                d, tir = refract(d, normal, eta[..., live] if np.ndim(eta) else eta)
                block(tir, i, TIR)
            going = reason[live] == PASSED
            if path is None and not going.all():
                live = live[going]
                o, d = _rows(o, going), _rows(d, going)
    origin = np.full((count, 3), np.nan)
    direction = np.full((count, 3), np.nan)
    passing = reason[live] == PASSED  # all of them, unless ``path`` kept every ray
    origin[live[passing]] = np.stack(o, axis=1)[passing]
    direction[live[passing]] = np.stack(d, axis=1)[passing]
    return TraceResult(origin, direction, surface, reason, transmitted)
