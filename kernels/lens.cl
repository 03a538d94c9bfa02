/* Camera ray generation through a real lens: sample id -> world-space ray, weight, pixel.
 *
 * OpenCL 1.2 C, float32, one work item per sample id. The float64 numpy reference is
 * realistic.camera.lens_camera.LensCamera.generate_rays; this kernel follows the same rules (its
 * tracer, realistic/optics/tracer.py):
 * root chosen by direction, far hemisphere = miss, clear-aperture and stop clipping, Heckbert
 * refraction, total internal reflection blocks, each coated surface's Fresnel transmittance, the
 * paraxial (ideal thin lens) surfaces' slope change.
 *
 * Written so that PoCL's work-group vectoriser turns the work-item loop into SIMD code
 * (../shared/DESIGN.md, "Facts measured on this machine"): no calls to OpenCL builtin math
 * functions (PoCL does not inline them and a call stops the vectoriser), plain float arithmetic
 * instead of float3 helpers, ternaries instead of fmax/select, an `alive` mask instead of early
 * exits, no loops in the body (fixed counts written out), no twin instruction chains that LLVM's
 * SLP vectoriser would pack into 2-wide vectors, and the surfaces unrolled with their constants
 * known at compile time. Check: POCL_VECTORIZER_REMARKS=1 prints "vectorized loop" per kernel, and
 * the built generate_rays.so (POCL_CACHE_DIR, POCL_LEAVE_KERNEL_COMPILER_TEMP_FILES=1) uses ymm.
 *
 * The host (realistic/camera/opencl_host.py) prepends a generated header that defines, per lens and
 * camera (the resolution, the film's size, the sample count and the settings, focus and the
 * diameter of a round stop, are kernel arguments instead, so a new --res, --spp, focus or f-stop
 * reuses PoCL's cached build rather than compiling for a second or more):
 *   LENS_SAMPLING_PUPIL           1: exit-pupil boxes, 0: rear-element disk
 *   PUPIL_INTERVALS               the exit-pupil table's radial intervals, when LENS_SAMPLING_PUPIL is 1
 *   SPECTRAL                      1: each sample is WAVELENGTHS_PER_SAMPLE (K) work items, one ray
 *                                 per wavelength (output row 7), sample-major; they share the
 *                                 sample's film and lens numbers, and ray j's wavelength number is
 *                                 (u + j) / K, u R5's fifth dimension (in fixed point
 *                                 bits / K + j LAMBDA_STRATUM_STEP, floor(2^32 / K);
 *                                 realistic.core.rng.spectral_rays; film and lens then use R5's
 *                                 first four), through the inverse CDF of a piecewise linear density: node
 *                                 LAMBDA_MIN_NM + k LAMBDA_STEP_NM, k = 0..LAMBDA_INTERVALS (64),
 *                                 tables LAMBDA_DENSITY[k] (per nm) and LAMBDA_CDF[k]
 *                                 (realistic.core.spectrum.wavelengths_nm)
 *   FILTER_KIND                   pixel filter sampling (realistic.core.pixel_filter): 0 box,
 *                                 1 triangle, 2 tabulated; FILTER_RX, FILTER_RY its radii (pixels);
 *                                 when 2, FILTER_BINS and tables FILTER_CDF_X/Y[FILTER_BINS + 1]
 *                                 (CDF of |f| per axis) and FILTER_WEIGHT_X/Y[FILTER_BINS]
 *                                 (sign(f) * integral|f| / integral f of each bin)
 *   RAYS_PER_ITEM                 rays each work item traces side by side (1 to 4; see
 *                                 "several rays per work item")
 *   SAMPLE_RAYS                   1: each work item traces one SPECTRAL sample's K rays
 *                                 (RAYS_PER_ITEM = K), which share its film and lens point; 0: rays
 *                                 i, i + n, ... of the launch
 *   SURFACE_k(r, il2)             surface k, rear first (k = 0), as a call to sphere()/plane()/
 *                                 asphere()/paraxial()/stop() with literal constants; when SPECTRAL, its
 *                                 index ratio is computed from each dispersive glass's index
 *                                 A + B il2 (il2 = 1 / lambda^2 in um^-2, A and B literal Cauchy
 *                                 coefficients), or a catalogue glass's Sellmeier or Schott formula
 *                                 written in il2 (realistic.optics.dispersion)
 *                                 followed, where the lens's coating loses light there, by
 *                                 transmit_bare() or transmit_layer() (see "coatings")
 *   TRACE_SURFACES(EACH)          EACH(SURFACE_0) EACH(SURFACE_1) ...: every surface, rear first
 *   COATED                        1: some surface loses light (the weight carries Ray.T)
 * The kernel argument `settings` holds what changes with the focus (the film distance) and the
 * stop's diameter, float32 at the SET_* offsets the generated header defines (declared once, with
 * what each holds, in realistic.camera.opencl_host.SETTINGS; packed by setting_values): SET_PLANE_Z,
 * SET_PLANE_Z2, SET_FRONT_VERTEX_Z, SET_REAR_W, SET_SAMPLING (three values), SET_STOP_R2, and from
 * SET_PUPIL the exit-pupil boxes and areas. Products and quotients of these values that were once
 * folded from literals come precomputed in float32, so every ray rounds as it did.
 */

#define PI_F 3.14159265358979f

/* ------------------------------------------------------------------ random numbers
 * Bit-identical to realistic/core/rng.py: lowbias32 hash, key chaining, a Kronecker sequence over
 * the pixel's sample index in 32-bit fixed point, shifted by a per-pixel hashed offset per
 * dimension (Cranley-Patterson rotation): R4 (film x, film y, lens u, lens v), or for a SPECTRAL
 * camera R5, whose fifth dimension is the wavelength. That is the stratification within a pixel.
 * uint arithmetic wraps modulo 2^32 as numpy's uint32 does.
 */
#define GOLDEN 0x9E3779B9u
#if SPECTRAL
#define KRONECKER_0 0xE19B01ABu
#define KRONECKER_1 0xC6D1D6C9u
#define KRONECKER_2 0xAF36D01Fu
#define KRONECKER_3 0x9A69443Fu
#define KRONECKER_4 0x881403B9u
#else
#define KRONECKER_0 0xDB4F0B91u
#define KRONECKER_1 0xBBE05633u
#define KRONECKER_2 0xA0F2EC76u
#define KRONECKER_3 0x89E18285u
#endif

#define CAMERA_SAMPLES  /* common.cl's sample addresses and pixel filter offsets */
#include "common.cl"  /* expanded by the host (realistic.device.opencl.kernel_source) */

/* The stratified uint32 values of one sample: film x, film y, lens u, lens v, and when SPECTRAL
 * the wavelength's in *b4 (realistic.core.rng.stratified4 / stratified5). */
inline void stratified(uint pixel, uint sample, uint seed, uint *b0, uint *b1, uint *b2, uint *b3, uint *b4) {
    uint h = hash32(hash32(seed + GOLDEN) ^ pixel);
    h = hash32(h ^ 0xFFFFFFFFu);  /* the per-pixel key: sample index 0xFFFFFFFF */
    *b0 = sample * KRONECKER_0 + hash32(h ^ 0u);
    *b1 = sample * KRONECKER_1 + hash32(h ^ 1u);
    *b2 = sample * KRONECKER_2 + hash32(h ^ 2u);
    *b3 = sample * KRONECKER_3 + hash32(h ^ 3u);
#if SPECTRAL
    *b4 = sample * KRONECKER_4 + hash32(h ^ 4u);
#else
    *b4 = 0u;
#endif
}

#if SPECTRAL
/* Wavelength (nm) from a uniform u in [0, 1): the node interval k by a 6-step binary search on the
 * CDF (LAMBDA_INTERVALS is 64), then the root of p0 t + (p1 - p0) t^2 / (2 step) = u - CDF[k] in
 * the form that stays stable when p1 = p0 (realistic.core.spectrum.wavelengths_nm). */
inline float wavelength_nm(float u) {
    int k = 0;
    k = LAMBDA_CDF[k + 32] <= u ? k + 32 : k;
    k = LAMBDA_CDF[k + 16] <= u ? k + 16 : k;
    k = LAMBDA_CDF[k + 8] <= u ? k + 8 : k;
    k = LAMBDA_CDF[k + 4] <= u ? k + 4 : k;
    k = LAMBDA_CDF[k + 2] <= u ? k + 2 : k;
    k = LAMBDA_CDF[k + 1] <= u ? k + 1 : k;
    float p0 = LAMBDA_DENSITY[k];
    float slope = (LAMBDA_DENSITY[k + 1] - p0) * (1.0f / LAMBDA_STEP_NM);
    float v = u - LAMBDA_CDF[k];
    float t = 2.0f * v / (p0 + __builtin_sqrtf(p0 * p0 + 2.0f * slope * v));
    return LAMBDA_MIN_NM + (float)k * LAMBDA_STEP_NM + t;
}
#endif

/* The sample id (within the launch) of work item gid and, when SPECTRAL, which of the sample's
 * WAVELENGTHS_PER_SAMPLE rays it is (its wavelength stratum; 0 otherwise). A constant divisor: the
 * compiler turns the division into a multiply and shift, which vectorises. */
inline void ray_of_sample(uint gid, uint *sample_gid, uint *stratum) {
#if SPECTRAL
    uint s = gid / WAVELENGTHS_PER_SAMPLE;
    *sample_gid = s;
    *stratum = gid - s * WAVELENGTHS_PER_SAMPLE;
#else
    *sample_gid = gid;
    *stratum = 0u;
#endif
}

/* ------------------------------------------------------------------ tracing
 * The ray state in the frame of the surface about to be met: (ox, oy) transverse position, w the
 * axial position relative to that surface's vertex (+ toward the scene). Keeping w local keeps
 * float32 precision at the scale of the surface sag instead of the lens-frame z.
 */
typedef struct {
    float ox, oy, w;
    float dx, dy, dz;
    int alive;
    float c1, c2;  /* cosines of incidence and refraction at the last refracting surface */
    float T;       /* product of the surfaces' transmittances so far (used when COATED) */
} Ray;

/* Heckbert refraction of the unit direction at the unit normal (nx, ny, nz), which faces it. */
inline __attribute__((always_inline)) void refract(Ray *r, float nx, float ny, float nz, const float eta) {
    float c1 = -(r->dx * nx + r->dy * ny + r->dz * nz);
    float c2sq = 1.0f - eta * eta * (1.0f - c1 * c1);
    r->alive = r->alive & (c2sq >= 0.0f);
    float c2 = __builtin_sqrtf(c2sq > 0.0f ? c2sq : 0.0f);
    float k = eta * c1 - c2;
    r->c1 = c1;
    r->c2 = c2;
    r->dx = eta * r->dx + k * nx;
    r->dy = eta * r->dy + k * ny;
    r->dz = eta * r->dz + k * nz;
}

/* ------------------------------------------------------------------ coatings
 * The fraction (Ts + Tp) / 2 of light a surface transmits (realistic.optics.coating, whose float64
 * formulas these are), from the cosines refract() left in the ray. The host writes a call after a
 * surface's only where the lens's coating makes the surface lose light (COATED is then 1). */

/* A bare interface of index ratio ETA (incident over transmitted): the Fresnel equations with
 * rs = (eta c1 - c2) / (eta c1 + c2), rp = (c1 - eta c2) / (c1 + eta c2). */
inline __attribute__((always_inline)) void transmit_bare(Ray *r, const float ETA) {
    float a = ETA * r->c1, b = ETA * r->c2;
    float rs = (a - r->c2) / (a + r->c2);
    float rp = (r->c1 - b) * (1.0f / (r->c1 + b));
    r->T = r->T * (1.0f - 0.5f * (rs * rs + rp * rp));
}

/* A quarter-wave layer (at lambda0) of index NL between media N0 (the ray's) and N2, at the phase
 * factor PHASE = pi (lambda0 / lambda) NL / n(lambda0) (2 delta = PHASE cos theta_layer); NL is MgF2's
 * index at the ray's wavelength (realistic.optics.coating.mgf2_index). With a, b the amplitude
 * reflection coefficients entering and leaving the film, the Airy sum gives
 * R = (a^2 + b^2 + 2 a b cos 2delta) / D and T = (1 - a^2)(1 - b^2) / D, D = 1 + a^2 b^2 + 2 a b cos 2delta
 * (lossless: R + T = 1). s takes T's form and p R's, and the four coefficients are written each in
 * its own form, on purpose: as twins, LLVM's SLP vectoriser packed s and p into 2-wide vectors,
 * which stops PoCL's work-group vectoriser ("instruction return type cannot be vectorized"). */
inline __attribute__((always_inline)) void transmit_layer(Ray *r, const float N0, const float N2, const float PHASE,
                                                         const float NL) {
    float c0 = r->c1, c2 = r->c2;
    float q = N0 * (1.0f / NL);
    float cl2 = 1.0f - q * q * (1.0f - c0 * c0);
    float cl = __builtin_sqrtf(cl2 > 0.0f ? cl2 : 0.0f);
    float n0c0 = N0 * c0, nlcl = NL * cl, n2c2 = N2 * c2;
    float as = (n0c0 - nlcl) / (n0c0 + nlcl);
    float bs = 1.0f - 2.0f * n2c2 / (nlcl + n2c2);
    float ap = (NL * c0 - N0 * cl) * (1.0f / (NL * c0 + N0 * cl));
    float bp = 2.0f * (N2 * cl) / (N2 * cl + NL * c2) - 1.0f;
    float cp = cos_phase(PHASE * cl);
    float as2 = as * as, bs2 = bs * bs;
    float ts = (1.0f - as2) * (1.0f - bs2) / (1.0f + as2 * bs2 + 2.0f * as * bs * cp);
    float abp = ap * bp;
    float rp = (ap * ap + bp * bp + 2.0f * abp * cp) / (1.0f + abp * abp + 2.0f * cp * abp);
    r->T = r->T * (0.5f * (ts + (1.0f - rp)));
}

/* A spherical surface of radius R (vertex at w = 0, centre at w = -R), clear semi-aperture
 * squared AP2, index ratio ETA (incident over transmitted; a literal, or per ray when SPECTRAL),
 * REFRACTS 0 when the ratio is exactly 1, then GAP mm on to the next surface. AHEAD 0 (here and in
 * asphere, plane and stop): the surface touches the one the ray left (0 mm apart, a shape the host
 * has checked never to lie behind it), so a hit is not required to be ahead (rounding puts the
 * vertex's own hits a hair behind).
 * The quadratic t^2 + 2 b t + c = 0 is written about the vertex, c = |o|^2 + 2 R w, so that c
 * does not cancel R^2, and its roots are taken in the cancellation-free form q, c / q. */
inline __attribute__((always_inline)) void sphere(Ray *r, const float R, const float AP2, const float ETA,
                                                 const int REFRACTS, const float GAP, const int AHEAD) {
    float b = r->ox * r->dx + r->oy * r->dy + (r->w + R) * r->dz;
    float c = r->ox * r->ox + r->oy * r->oy + r->w * (r->w + 2.0f * R);
    float disc = b * b - c;
    float root = __builtin_sqrtf(disc > 0.0f ? disc : 0.0f);
    /* Near root for a ray travelling +z when R < 0, far root when R > 0 (the vertex cap). */
    int use_near = (r->dz > 0.0f) == (R < 0.0f);
    float t = use_near ? -b - root : -b + root;
    float hx = r->ox + t * r->dx;
    float hy = r->oy + t * r->dy;
    float hw = r->w + t * r->dz;
    float cz = hw + R;  /* hit minus centre, axial */
    r->alive = r->alive & (disc >= 0.0f) & ((t > 0.0f) | !AHEAD) & (cz * R > 0.0f) & (hx * hx + hy * hy <= AP2);
    float s = (hx * r->dx + hy * r->dy + cz * r->dz > 0.0f ? -1.0f : 1.0f) * (1.0f / (R < 0.0f ? -R : R));
    if (REFRACTS) refract(r, hx * s, hy * s, cz * s, ETA);
    r->ox = hx;
    r->oy = hy;
    r->w = hw - GAP;
}

/* An even asphere (realistic.optics.asphere) of base curvature C, conic constant K and coefficients
 * A4 .. A20 (r^4 .. r^20), as the float64 tracer meets it (realistic.optics.tracer.intersect_asphere):
 * the nearer root ahead on the base conic's vertex branch (1 + (1 + K) C w >= 0), else the vertex plane's,
 * then six Newton steps on F(t) = w(t) + sag(rho(t)), a fixed count so that every work item runs
 * the same branch-free code. A ray whose final |F| exceeds ASPHERE_TOLERANCE_MM, that leaves the
 * conic's domain or the clear aperture, is blocked (the tracer's reason `asphere`). The normal is the
 * sag's gradient (2 x s', 2 y s', 1), turned to face the ray. */
#define ASPHERE_TOLERANCE_MM 1e-4f
#define ASPHERE_POLY(rho) ((rho) * (rho) * (A4 + (rho) * (A6 + (rho) * (A8 + (rho) * (A10 + (rho) * (A12 + \
    (rho) * (A14 + (rho) * (A16 + (rho) * (A18 + (rho) * A20)))))))))
#define ASPHERE_DPOLY(rho) ((rho) * (2.0f * A4 + (rho) * (3.0f * A6 + (rho) * (4.0f * A8 + (rho) * (5.0f * A10 + \
    (rho) * (6.0f * A12 + (rho) * (7.0f * A14 + (rho) * (8.0f * A16 + (rho) * (9.0f * A18 + (rho) * 10.0f * A20)))))))))
/* One Newton step on F(t), written out six times rather than looped: PoCL's
 * work-group vectoriser is LLVM's loop vectoriser run on the loop over work items, which widens
 * innermost loops only, so any loop left inside the kernel body (even a constant-count one) kept
 * the asphere path scalar (objdump of the built kernel: 0 ymm instructions, 0.5-1.1 M rays/s). */
#define ASPHERE_NEWTON_STEP \
    hx = r->ox + t * r->dx; \
    hy = r->oy + t * r->dy; \
    rho = hx * hx + hy * hy; \
    q2 = 1.0f - CCK * rho; \
    q = __builtin_sqrtf(q2 > 0.0f ? q2 : 0.0f); \
    f = r->w + t * r->dz + C * rho / (1.0f + q) + ASPHERE_POLY(rho); \
    slope = C / (2.0f * q) + ASPHERE_DPOLY(rho); \
    t = t - f / (r->dz + 2.0f * slope * (hx * r->dx + hy * r->dy));
inline __attribute__((always_inline)) void asphere(Ray *r, const float C, const float K, const float A4, const float A6,
                                                  const float A8, const float A10, const float A12, const float A14,
                                                  const float A16, const float A18, const float A20, const float AP2,
                                                  const float ETA, const int REFRACTS, const float GAP,
                                                  const int AHEAD) {
    const float CK = (1.0f + K) * C;
    const float CCK = CK * C;
    float a = C * (r->dx * r->dx + r->dy * r->dy) + CK * r->dz * r->dz;
    float b = C * (r->ox * r->dx + r->oy * r->dy) + r->dz + CK * r->w * r->dz;
    float g = C * (r->ox * r->ox + r->oy * r->oy) + 2.0f * r->w + CK * r->w * r->w;
    float disc = b * b - a * g;
    float root = __builtin_sqrtf(disc > 0.0f ? disc : 0.0f);
    float qq = -(b + (b < 0.0f ? -root : root));
    /* The two roots' tests are written as different instruction sequences on purpose (as
     * concentric_disk's): as twins, LLVM's SLP vectoriser packed them into 2-wide vectors, and a
     * vector-typed instruction in the body stops PoCL's work-group vectoriser ("instruction return
     * type cannot be vectorized" with POCL_VECTORIZER_REMARKS=1). */
    float t1 = qq / a, t2 = g / qq;
    int ok1 = (disc >= 0.0f) & (t1 > 0.0f) & (1.0f + CK * (r->w + t1 * r->dz) >= 0.0f);
    int ok2 = (disc >= 0.0f) & (0.0f < t2) & (CK * r->w + (CK * r->dz) * t2 >= -1.0f);
    /* Both roots and the plane's are computed for every ray and chosen by masks: written as a
     * ternary with the plane's division in one arm, clang made the choice a branch (`br i1` in
     * PoCL's program.bc), which the work-group vectoriser would have to if-convert. */
    float tp = -r->w / r->dz;
    int take1 = -(ok1 & !(ok2 & (t2 < t1)));
    int take2 = -((take1 == 0) & ok2);
    float t = as_float((as_int(t1) & take1) | (as_int(t2) & take2) | (as_int(tp) & ~(take1 | take2)));
    float hx, hy, rho, q2, q, f, slope;
    ASPHERE_NEWTON_STEP ASPHERE_NEWTON_STEP ASPHERE_NEWTON_STEP
    ASPHERE_NEWTON_STEP ASPHERE_NEWTON_STEP ASPHERE_NEWTON_STEP
    hx = r->ox + t * r->dx;
    hy = r->oy + t * r->dy;
    float hw = r->w + t * r->dz;
    rho = hx * hx + hy * hy;
    q2 = 1.0f - CCK * rho;
    q = __builtin_sqrtf(q2 > 0.0f ? q2 : 0.0f);
    f = hw + C * rho / (1.0f + q) + ASPHERE_POLY(rho);
    float af = f < 0.0f ? -f : f;
    r->alive = r->alive & (af <= ASPHERE_TOLERANCE_MM) & (q2 >= 0.0f) & ((t > 0.0f) | !AHEAD) & (rho <= AP2);
    float slope2 = 2.0f * (C / (2.0f * q) + ASPHERE_DPOLY(rho));
    float nx = hx * slope2, ny = hy * slope2;
    float s = (nx * r->dx + ny * r->dy + r->dz > 0.0f ? -1.0f : 1.0f) / __builtin_sqrtf(nx * nx + ny * ny + 1.0f);
    if (REFRACTS) refract(r, nx * s, ny * s, s, ETA);
    r->ox = hx;
    r->oy = hy;
    r->w = hw - GAP;
}

/* A plane at the vertex: the aperture stop (REFRACTS = 0) or a flat refracting surface. */
inline __attribute__((always_inline)) void plane(Ray *r, const float AP2, const float ETA, const int REFRACTS,
                                                const float GAP, const int AHEAD) {
    float t = -r->w / r->dz;
    float hx = r->ox + t * r->dx;
    float hy = r->oy + t * r->dy;
    r->alive = r->alive & ((t > 0.0f) | !AHEAD) & (hx * hx + hy * hy <= AP2);
    if (REFRACTS) refract(r, 0.0f, 0.0f, r->dz > 0.0f ? -1.0f : (r->dz < 0.0f ? 1.0f : 0.0f), ETA);
    r->ox = hx;
    r->oy = hy;
    r->w = -GAP;
}

/* A paraxial surface (realistic.optics.lens): an ideal thin lens of powers PX, PY on the vertex plane.
 * The ray's slopes along its travel, d / |dz|, lose (hx PX, hy PY); no light is lost. AP2 is the
 * clear semi-aperture squared (settings[SET_STOP_R2] when the surface is the stop). */
inline __attribute__((always_inline)) void paraxial(Ray *r, const float AP2, const float PX, const float PY,
                                                   const float GAP, const int AHEAD) {
    float t = -r->w / r->dz;
    float hx = r->ox + t * r->dx;
    float hy = r->oy + t * r->dy;
    r->alive = r->alive & ((t > 0.0f) | !AHEAD) & (hx * hx + hy * hy <= AP2);
    float along = 1.0f / (r->dz < 0.0f ? -r->dz : r->dz);
    float ux = r->dx * along - hx * PX;
    float uy = r->dy * along - hy * PY;
    float s = 1.0f / __builtin_sqrtf(ux * ux + uy * uy + 1.0f);
    r->dx = ux * s;
    r->dy = uy * s;
    r->dz = r->dz < 0.0f ? -s : s;
    r->ox = hx;
    r->oy = hy;
    r->w = -GAP;
}

/* The aperture stop: a plane whose opening is STOP_INSIDE(x, y), generated by the host: the circle
 * of squared radius STOP_R2 (a setting), the sides (half-planes) or arcs (disks) of a bladed stop, or
 * the mask. */
inline __attribute__((always_inline)) void stop(Ray *r, const float GAP, const float STOP_R2, const int AHEAD) {
    float t = -r->w / r->dz;
    float hx = r->ox + t * r->dx;
    float hy = r->oy + t * r->dy;
    r->alive = r->alive & ((t > 0.0f) | !AHEAD) & STOP_INSIDE(hx, hy);
    r->ox = hx;
    r->oy = hy;
    r->w = -GAP;
}

/* ------------------------------------------------------------------ sampling (sincos_quarter and
 * concentric_disk: kernels/common.cl) */

#if LENS_SAMPLING_PUPIL
/* Exit-pupil box of the film point's radial interval, rotated to its polar angle. */
inline void sample_plane(__constant float *settings, float fx, float fy, float u, float v, float *px, float *py,
                         float *area) {
    float rho2 = fx * fx + fy * fy;
    float rho = __builtin_sqrtf(rho2);
    int k = (int)(rho * settings[SET_SAMPLING]);
    k = k < PUPIL_INTERVALS - 1 ? k : PUPIL_INTERVALS - 1;
    __constant float *box = settings + SET_PUPIL + 4 * k;
    float x0 = box[0], x1 = box[1], y0 = box[2], y1 = box[3];
    float x = x0 + u * (x1 - x0);
    float y = y0 + v * (y1 - y0);
    float inv = rho > 0.0f ? 1.0f / rho : 0.0f;
    float cos_phi = rho > 0.0f ? fx * inv : 1.0f;
    float sin_phi = fy * inv;
    *px = x * cos_phi - y * sin_phi;
    *py = x * sin_phi + y * cos_phi;
    *area = settings[SET_PUPIL + 4 * PUPIL_INTERVALS + k];
}
#else
/* Rear-element disk whose radius covers the element's real extent from this film point. */
inline void sample_plane(__constant float *settings, float fx, float fy, float u, float v, float *px, float *py,
                         float *area) {
    float rho = __builtin_sqrtf(fx * fx + fy * fy);
    float clear = settings[SET_SAMPLING + 2];
    float radius = rho * settings[SET_SAMPLING] + settings[SET_SAMPLING + 1];
    radius = radius > clear ? radius : clear;
    float dx, dy;
    concentric_disk(u, v, &dx, &dy);
    *px = dx * radius;
    *py = dy * radius;
    *area = PI_F * radius * radius;
}
#endif

/* ------------------------------------------------------------------ pixel filter
 * filter_offset_x / filter_offset_y: kernels/common.cl's (CAMERA_SAMPLES), shared with thin_lens.cl. */

/* ------------------------------------------------------------------ several rays per work item
 * PoCL makes the loop over a work group's work items SIMD with LLVM's loop vectoriser, whose cost
 * model runs a body as long as this kernel's one vector of work items at a time: each surface's
 * chain of dependent square roots and divisions then waits on the one before, and the kernel is
 * bound by their latency. So each work item traces RAYS_PER_ITEM rays (the host's
 * realistic.camera.opencl_host.rays_per_item), and the generated TRACE_SURFACES(EACH) meets each
 * surface with all of them (EACH_RAY) before the next: that many independent chains in flight.
 * Work item i of n traces rays i, i + n, i + 2n, ...: their outputs are not adjacent, so LLVM's
 * SLP vectoriser finds no consecutive stores to pack the twin chains into short vectors from
 * (which would stop the loop vectoriser, see concentric_disk). Each ray's arithmetic is unchanged.
 * A SPECTRAL sample's K rays share its film and lens point (all but the wavelength), so with
 * SAMPLE_RAYS a work item traces one sample's K = RAYS_PER_ITEM rays, the sample's part (its
 * hashes, address division, pixel filter and lens point: start_sample) made once instead of K
 * times. Their outputs are consecutive, which LLVM's SLP vectoriser may pack (it does for K = 4, so
 * the host uses this layout for K = 2 and 3 only: realistic.camera.opencl_host.MAX_SAMPLE_RAYS), and
 * the host times it against one ray per work item as it times several rays (rays_per_item_choices). */
#if RAYS_PER_ITEM == 4
#define EACH_RAY(STEP) STEP(0) STEP(1) STEP(2) STEP(3)
#define EACH_RAY_SURFACE(SURFACE) SURFACE(&r0, il2_0) SURFACE(&r1, il2_1) SURFACE(&r2, il2_2) SURFACE(&r3, il2_3)
#elif RAYS_PER_ITEM == 3
#define EACH_RAY(STEP) STEP(0) STEP(1) STEP(2)
#define EACH_RAY_SURFACE(SURFACE) SURFACE(&r0, il2_0) SURFACE(&r1, il2_1) SURFACE(&r2, il2_2)
#elif RAYS_PER_ITEM == 2
#define EACH_RAY(STEP) STEP(0) STEP(1)
#define EACH_RAY_SURFACE(SURFACE) SURFACE(&r0, il2_0) SURFACE(&r1, il2_1)
#else
#define EACH_RAY(STEP) STEP(0)
#define EACH_RAY_SURFACE(SURFACE) SURFACE(&r0, il2_0)
#endif

/* Sample sample_gid of the launch up to the lens: its pixel, weight, the ray leaving the film
 * toward the rear surface, and R5's fifth value (the wavelength's, when SPECTRAL) in *b4: what every
 * ray of the sample shares. */
inline __attribute__((always_inline)) void start_sample(uint sample_gid, uint first_pixel, uint offset,
                                                       uint slice_start, uint slice_width, uint seed,
                                                       __constant float *settings, uint width, double pixel_rows,
                                                       float inv_width, float inv_height, float film_w_mm,
                                                       float film_h_mm, Ray *r, uint *pixel, float *weight,
                                                       uint *b4) {
    uint sample;
    sample_address(first_pixel, offset, slice_start, slice_width, sample_gid, pixel, &sample);
    uint b0, b1, b2, b3;
    stratified(*pixel, sample, seed, &b0, &b1, &b2, &b3, b4);

    /* pixel / width without an integer division (no vector form: PoCL scalarised it, -10% rays/s):
     * pixel_rows = 1 / width in double; (pixel + 0.5) / width is at least 0.5 / width from an
     * integer and its error below 2^-21 for pixel < 2^31, so truncation is exact. */
    uint py_i = (uint)(((double)*pixel + 0.5) * pixel_rows);
    uint px_i = *pixel - py_i * width;
    float filter_wx, filter_wy;
    float off_x = filter_offset_x(to_unit(b0), &filter_wx);
    float off_y = filter_offset_y(to_unit(b1), &filter_wy);
    float fx = -(((float)px_i + (0.5f + off_x)) * inv_width - 0.5f) * film_w_mm;
    float fy = (((float)py_i + (0.5f + off_y)) * inv_height - 0.5f) * film_h_mm;

    float tx, ty, area;
    sample_plane(settings, fx, fy, to_unit(b2), to_unit(b3), &tx, &ty, &area);
    float ddx = tx - fx, ddy = ty - fy;
    float plane_z2 = settings[SET_PLANE_Z2];
    float len2 = ddx * ddx + ddy * ddy + plane_z2;
    float inv_len = 1.0f / __builtin_sqrtf(len2);
    /* cos^4(theta) A / Z^2 with cos(theta) = Z / |delta|. */
    *weight = area * plane_z2 / (len2 * len2) * (filter_wx * filter_wy);

    r->ox = fx;
    r->oy = fy;
    r->w = settings[SET_REAR_W];
    r->dx = ddx * inv_len;
    r->dy = ddy * inv_len;
    r->dz = settings[SET_PLANE_Z] * inv_len;
    r->alive = 1;
    r->T = 1.0f;
}

/* The wavelength (when SPECTRAL; 0 otherwise) of a sample's ray in wavelength stratum `stratum`,
 * from the sample's b4 (start_sample), and 1 / lambda^2 in um^-2 (il2, 0 when not SPECTRAL: the
 * indices are literals). */
inline __attribute__((always_inline)) void ray_wavelength(uint b4, uint stratum, float *lambda, float *il2) {
#if SPECTRAL
    *lambda = wavelength_nm(to_unit(b4 / WAVELENGTHS_PER_SAMPLE + stratum * LAMBDA_STRATUM_STEP));
    *il2 = 1.0e6f / (*lambda * *lambda);
#else
    *lambda = 0.0f;
    *il2 = 0.0f;
#endif
}

/* Ray gid of the launch up to the lens: its sample's part (start_sample) and its wavelength's. */
inline __attribute__((always_inline)) void start_ray(uint gid, uint first_pixel, uint offset, uint slice_start,
                                                    uint slice_width, uint seed, __constant float *settings,
                                                    uint width, double pixel_rows, float inv_width,
                                                    float inv_height, float film_w_mm, float film_h_mm, Ray *r,
                                                    uint *pixel, float *weight, float *lambda, float *il2) {
    uint sample_gid, stratum, b4;
    ray_of_sample(gid, &sample_gid, &stratum);
    start_sample(sample_gid, first_pixel, offset, slice_start, slice_width, seed, settings, width, pixel_rows,
                 inv_width, inv_height, film_w_mm, film_h_mm, r, pixel, weight, &b4);
    ray_wavelength(b4, stratum, lambda, il2);
}

/* Ray gid's outputs, from the ray leaving the front surface (see generate_rays). */
inline __attribute__((always_inline)) void finish_ray(uint gid, const Ray *r, uint pixel, float weight, float lambda,
                                                     __constant float *world, __constant float *settings,
                                                     uint stride, __global float *out, __global int *pixel_out) {
    float oz = r->w + settings[SET_FRONT_VERTEX_Z];
    float wx = world[0] * r->ox + world[1] * r->oy + world[2] * oz + world[3];
    float wy = world[4] * r->ox + world[5] * r->oy + world[6] * oz + world[7];
    float wz = world[8] * r->ox + world[9] * r->oy + world[10] * oz + world[11];
    float vx = world[0] * r->dx + world[1] * r->dy + world[2] * r->dz;
    float vy = world[4] * r->dx + world[5] * r->dy + world[6] * r->dz;
    float vz = world[8] * r->dx + world[9] * r->dy + world[10] * r->dz;
    float scale = 1.0f / __builtin_sqrtf(vx * vx + vy * vy + vz * vz);
    out[gid] = r->alive ? wx : 0.0f;
    out[stride + gid] = r->alive ? wy : 0.0f;
    out[2 * stride + gid] = r->alive ? wz : 0.0f;
    out[3 * stride + gid] = r->alive ? vx * scale : 0.0f;
    out[4 * stride + gid] = r->alive ? vy * scale : 0.0f;
    out[5 * stride + gid] = r->alive ? vz * scale : 0.0f;
#if COATED
    weight = weight * r->T;
#endif
    out[6 * stride + gid] = r->alive ? weight : 0.0f;
#if SPECTRAL
    out[7 * stride + gid] = lambda;
#endif
    pixel_out[gid] = (int)pixel;
}

/* ------------------------------------------------------------------ kernels */

/* Rays of the sample block the host lays out (sample_address): one per sample, or when SPECTRAL
 * WAVELENGTHS_PER_SAMPLE consecutive ones per sample (ray_of_sample), RAYS_PER_ITEM per work item
 * (stride = RAYS_PER_ITEM x the launch's work items; with SAMPLE_RAYS work item i traces sample i's,
 * rays i K .. i K + K - 1). out holds 7 rows of `stride` floats: origin
 * x, y, z, direction x, y, z, weight
 * (world space; a blocked ray has weight 0 and zero origin and direction), and when SPECTRAL an
 * eighth: the wavelength in nm. world is the camera-to-world matrix, rows of (m0 m1 m2 t). */
__kernel void generate_rays(uint first_pixel, uint offset, uint slice_start, uint slice_width, uint seed, __constant float *world,
                            __constant float *settings, uint width, double pixel_rows, float inv_width, float inv_height, float film_w_mm, float film_h_mm,
                            uint stride, __global float *out, __global int *pixel_out) {
    uint item = get_global_id(0);
#if SAMPLE_RAYS
    Ray first;
    uint pixel, b4;
    float weight;
    start_sample(item, first_pixel, offset, slice_start, slice_width, seed, settings, width, pixel_rows, inv_width,
                 inv_height, film_w_mm, film_h_mm, &first, &pixel, &weight, &b4);
#define START_RAY(j) \
    Ray r##j = first; \
    float lambda_##j, il2_##j; \
    ray_wavelength(b4, j, &lambda_##j, &il2_##j);
#define FINISH_RAY(j) \
    finish_ray(item * RAYS_PER_ITEM + j, &r##j, pixel, weight, lambda_##j, world, settings, stride, out, pixel_out);
#else
    uint items = stride / RAYS_PER_ITEM;
#define START_RAY(j) \
    Ray r##j; \
    uint pixel_##j; \
    float weight_##j, lambda_##j, il2_##j; \
    start_ray(item + j * items, first_pixel, offset, slice_start, slice_width, seed, settings, width, pixel_rows, \
              inv_width, inv_height, film_w_mm, film_h_mm, &r##j, &pixel_##j, &weight_##j, &lambda_##j, &il2_##j);
#define FINISH_RAY(j) \
    finish_ray(item + j * items, &r##j, pixel_##j, weight_##j, lambda_##j, world, settings, stride, out, pixel_out);
#endif
    EACH_RAY(START_RAY)
    TRACE_SURFACES(EACH_RAY_SURFACE)
    EACH_RAY(FINISH_RAY)
}

/* Debug: the stratified uint32 values of each sample, 4 rows of `stride` (and the wavelength's
 * as a fifth when SPECTRAL), so the tests can check them against realistic.core.rng bit for bit. */
__kernel void sample_bits(uint first_pixel, uint offset, uint slice_start, uint slice_width, uint seed, uint stride, __global uint *out) {
    uint gid = get_global_id(0);
    uint pixel, sample;
    sample_address(first_pixel, offset, slice_start, slice_width, gid, &pixel, &sample);
    uint b0, b1, b2, b3, b4;
    stratified(pixel, sample, seed, &b0, &b1, &b2, &b3, &b4);
    out[gid] = b0;
    out[stride + gid] = b1;
    out[2 * stride + gid] = b2;
    out[3 * stride + gid] = b3;
#if SPECTRAL
    out[4 * stride + gid] = b4;
#endif
}
