/* Rays from the scene along one path through the lens (a ghost, or the direct path) onto the film.
 *
 * OpenCL 1.2 C, float32, one work item per ray. The float64 reference is
 * realistic/optics/ghosts.py (trace_ghost, trace_direct); this kernel follows its rules and the real-ray
 * tracer's (realistic/optics/tracer.py): the sphere's root chosen by direction (the vertex cap), a
 * hit on the far hemisphere a miss, each surface's clear aperture and the stop clipping on every
 * pass, Heckbert refraction with total internal reflection blocking, mirror reflection about the
 * normal, and the Fresnel factors of realistic/optics/coating.py (polarisation-averaged R at a
 * reflection, T = 1 - R at a refraction: every medium is lossless).
 *
 * The path is the host's table of steps (realistic/camera/ghost_host.py, STEPS, declared once as a
 * realistic.device.tables.Table whose STEP_* offsets the host prepends as #defines), one row per
 * surface met, in order: the surface's shape, clear aperture, what the ray does there (STEP_ACTION:
 * ACTION_PASS, ACTION_REFRACT or ACTION_REFLECT), the coating model (MODEL_*: realistic.optics.coating),
 * the media on the ray's side and the far side (rows of the media table: each medium's index
 * tabulated over the launch's wavelengths, so every ray has its own), and the axial shift from
 * this surface's vertex to the next one's (to the film plane after the last). As in kernels/lens.cl,
 * the ray's axial position w is kept relative to the vertex of the surface about to be met, so float32
 * keeps precision at the scale of the sag rather than of the lens-frame z.
 *
 * Unlike lens.cl, this kernel loops over its steps (one program serves every path of the lens). It is
 * written, as lens.cl is, for PoCL's work-group vectoriser (LLVM's loop vectoriser run on the loop
 * over a work group's work items): no calls to builtin math functions (PoCL does not inline them, and
 * a call stops the vectoriser: __builtin_sqrtf, a polynomial cos, ternaries for fabs and floor),
 * ternaries instead of branches (every shape and outcome is computed and the step's row picks one),
 * and a barrier at the end of each step, so that PoCL splits the kernel at it into regions, each with
 * its own loop over the work items: the step's region is a loop with no loop inside, which the
 * vectoriser widens (the loop over the steps, whose count is the same for every work item, runs
 * around it). Shapes the lens does not have are not compiled: ASPHERES and LAYERS (0 or 1) say
 * whether any surface is an asphere or has a MODEL_LAYER coating.
 *
 * The host's header also defines KIND_*, ACTION_*, MODEL_*, LAYER_MEDIUM (the media table's row of the
 * coating layer's own index), PI_LAMBDA0_OVER_NL0 (pi times the layer's design wavelength, nm, over
 * its index there), ASPHERES, LAYERS, ASPHERE_ITERATIONS, ASPHERE_TERMS, ASPHERE_TOLERANCE_MM and the
 * stop's opening STOP_INSIDE(x, y) (realistic.camera.opencl_host.stop_lines: a round stop's squared
 * radius STOP_R2 is the stop row's STEP_AP2, read through the row `s` in scope where it is used).
 */

#include "common.cl"  /* expanded by the host (realistic.device.opencl.kernel_source); its stop_mask */

typedef struct {
    float ox, oy, w;
    float dx, dy, dz;
    float weight;
    int alive;
    uint node;    /* the ray's wavelength: media table node below it, */
    float frac;   /* its place between that node and the next, */
    float layer;  /* the coating layer's index at that wavelength, */
    float phase;  /* and pi lambda0 nl / (lambda nl0) (reflectance's PHASE) */
} Ray;

/* The fraction of unpolarised light reflected by an interface from index N0 into N2 at incidence
 * cosine C0 (realistic.optics.coating.reflectance, whose float64 formulas these are); 1 past the
 * critical angle. PHASE = pi lambda0 nl / (lambda nl0), the layer's 2 delta at normal incidence. A
 * layer (MODEL_LAYER) of index NL is a quarter wave at lambda0: with a, b the amplitude
 * reflection coefficients entering and leaving the film, R = (a^2 + b^2 + 2 a b cos 2delta) /
 * (1 + a^2 b^2 + 2 a b cos 2delta), per polarisation (Born and Wolf 1.6.4). Past the layer's own
 * critical angle (light from dense glass beyond asin(NL / N0)) the film is crossed by an
 * evanescent wave, which this real form does not describe: the layer's cosine is taken as 0 there,
 * as lens.cl does. */
inline __attribute__((always_inline)) float reflectance(int model, float N0, float N2, float C0, float PHASE,
                                                       float NL) {
    float q = N0 / N2;
    float c2sq = 1.0f - q * q * (1.0f - C0 * C0);
    float c2 = __builtin_sqrtf(c2sq > 0.0f ? c2sq : 0.0f);
    float rs = (N0 * C0 - N2 * c2) / (N0 * C0 + N2 * c2);
    float rp = (N2 * C0 - N0 * c2) / (N2 * C0 + N0 * c2);
    float r = model == MODEL_BARE ? 0.5f * (rs * rs + rp * rp) : 0.0f;
#if LAYERS
    float ql = N0 / NL;
    float clsq = 1.0f - ql * ql * (1.0f - C0 * C0);
    float cl = __builtin_sqrtf(clsq > 0.0f ? clsq : 0.0f);
    float cp = cos_phase(PHASE * cl);
    float as = (N0 * C0 - NL * cl) / (N0 * C0 + NL * cl);
    float bs = (NL * cl - N2 * c2) / (NL * cl + N2 * c2);
    float ap = (NL * C0 - N0 * cl) / (NL * C0 + N0 * cl);
    float bp = (N2 * cl - NL * c2) / (N2 * cl + NL * c2);
    float ls = (as * as + bs * bs + 2.0f * as * bs * cp) / (1.0f + as * as * bs * bs + 2.0f * as * bs * cp);
    float lp = (ap * ap + bp * bp + 2.0f * ap * bp * cp) / (1.0f + ap * ap * bp * bp + 2.0f * ap * bp * cp);
    r = model == MODEL_LAYER ? 0.5f * (ls + lp) : r;
#endif
    return c2sq < 0.0f ? 1.0f : r;
}

/* The hit (hx, hy, hw: w relative to this surface's vertex) and the unit normal facing the ray of
 * step s; clears alive where the ray misses or leaves the clear aperture. Every shape the lens has is
 * computed and the step's kind picks one (ternaries, not branches, for the vectoriser). */
inline __attribute__((always_inline)) void meet(Ray *r, __constant float *s, float *hx, float *hy, float *hw,
                                                float *nx, float *ny, float *nz) {
    int kind = (int)s[STEP_KIND];
    int ahead = s[STEP_AHEAD] != 0.0f;
    /* a plane at the vertex: a flat face or the stop */
    float t = -r->w / r->dz;
    float x = r->ox + t * r->dx, y = r->oy + t * r->dy, w = 0.0f;
    float mx = 0.0f, my = 0.0f, mz = r->dz > 0.0f ? -1.0f : 1.0f;
    int ok = 1;
    /* a sphere: t^2 + 2 b t + c = 0 about the vertex (c = |o|^2 + 2 R w does not cancel R^2), roots in
     * the cancellation-free form q, c / q; the near one for a ray travelling +z when R < 0, the far
     * one when R > 0 (realistic.optics.tracer.intersect_surface), either way for -z. */
    float R = s[STEP_RADIUS];
    float b = r->ox * r->dx + r->oy * r->dy + (r->w + R) * r->dz;
    float c = r->ox * r->ox + r->oy * r->oy + r->w * (r->w + 2.0f * R);
    float disc = b * b - c;
    float root = __builtin_sqrtf(disc > 0.0f ? disc : 0.0f);
    float q = -(b + (b < 0.0f ? -root : root));
    float near = b > 0.0f ? q : c / q, far = b > 0.0f ? c / q : q;
    int use_near = (r->dz > 0.0f) == (R < 0.0f);
    float ts = use_near ? near : far;
    float sx = r->ox + ts * r->dx, sy = r->oy + ts * r->dy, sw = r->w + ts * r->dz;
    float cz = sw + R;  /* hit minus centre, axial */
    float scale = (sx * r->dx + sy * r->dy + cz * r->dz > 0.0f ? -1.0f : 1.0f) / (R < 0.0f ? -R : R);
    int sphere = kind == KIND_SPHERE;
    t = sphere ? ts : t;
    x = sphere ? sx : x;
    y = sphere ? sy : y;
    w = sphere ? sw : w;
    mx = sphere ? sx * scale : mx;
    my = sphere ? sy * scale : my;
    mz = sphere ? cz * scale : mz;
    ok = sphere ? (disc >= 0.0f) & (cz * R > 0.0f) : ok;
#if ASPHERES
    {
        /* The float64 tracer's start (realistic.optics.tracer.intersect_asphere): the nearer root
         * ahead on the base conic's vertex branch, else the vertex plane's; then Newton on
         * F(t) = w(t) + sag(rho(t)) (realistic.optics.asphere, Horner in rho = x^2 + y^2). */
        __constant float *a = s + STEP_ASPHERE;
        float C = s[STEP_CURVATURE], CK = (1.0f + s[STEP_CONIC]) * C, CCK = CK * C;
        float qa = C * (r->dx * r->dx + r->dy * r->dy) + CK * r->dz * r->dz;
        float qb = C * (r->ox * r->dx + r->oy * r->dy) + r->dz + CK * r->w * r->dz;
        float qg = C * (r->ox * r->ox + r->oy * r->oy) + 2.0f * r->w + CK * r->w * r->w;
        float adisc = qb * qb - qa * qg;
        float aroot = __builtin_sqrtf(adisc > 0.0f ? adisc : 0.0f);
        float qq = -(qb + (qb < 0.0f ? -aroot : aroot));
        float t1 = qq / qa, t2 = qg / qq;
        int ok1 = (adisc >= 0.0f) & (t1 > 0.0f) & (1.0f + CK * (r->w + t1 * r->dz) >= 0.0f);
        int ok2 = (adisc >= 0.0f) & (t2 > 0.0f) & (1.0f + CK * (r->w + t2 * r->dz) >= 0.0f);
        float ta = ok1 && !(ok2 && t2 < t1) ? t1 : (ok2 ? t2 : -r->w / r->dz);
        float rho = 0.0f, f = 0.0f, slope = 0.0f, ax = 0.0f, ay = 0.0f, qs = 0.0f;
#pragma unroll
        for (int k = 0; k <= ASPHERE_ITERATIONS; k++) {
            ax = r->ox + ta * r->dx;
            ay = r->oy + ta * r->dy;
            rho = ax * ax + ay * ay;
            qs = 1.0f - CCK * rho;
            float sq = __builtin_sqrtf(qs > 0.0f ? qs : 0.0f);
            float poly = 0.0f, dpoly = 0.0f;
#pragma unroll
            for (int j = ASPHERE_TERMS - 1; j >= 0; j--) {
                poly = poly * rho + a[j];
                dpoly = dpoly * rho + (float)(j + 2) * a[j];
            }
            f = r->w + ta * r->dz + C * rho / (1.0f + sq) + rho * rho * poly;
            slope = C / (2.0f * sq) + rho * dpoly;
            if (k < ASPHERE_ITERATIONS) ta = ta - f / (r->dz + 2.0f * slope * (ax * r->dx + ay * r->dy));
        }
        float nxs = ax * 2.0f * slope, nys = ay * 2.0f * slope;
        float ascale = (nxs * r->dx + nys * r->dy + r->dz > 0.0f ? -1.0f : 1.0f)
                       / __builtin_sqrtf(nxs * nxs + nys * nys + 1.0f);
        int asphere = kind == KIND_ASPHERE;
        t = asphere ? ta : t;
        x = asphere ? ax : x;
        y = asphere ? ay : y;
        w = asphere ? r->w + ta * r->dz : w;
        mx = asphere ? nxs * ascale : mx;
        my = asphere ? nys * ascale : my;
        mz = asphere ? ascale : mz;
        ok = asphere ? ((f < 0.0f ? -f : f) <= ASPHERE_TOLERANCE_MM) & (qs >= 0.0f) : ok;
    }
#endif
    *hx = x;
    *hy = y;
    *hw = w;
    *nx = mx;
    *ny = my;
    *nz = mz;
    int inside = s[STEP_STOP] != 0.0f ? STOP_INSIDE(x, y) : (x * x + y * y <= s[STEP_AP2]);
    r->alive = r->alive & ok & ((t > 0.0f) | !ahead) & inside;
}

/* One step: meet the surface, then pass, refract (weight x T) or reflect (weight x R), with the
 * indices of the media on the ray's side and the far side at the ray's wavelength (see trace_path);
 * each outcome computed and the step's action picks one. */
inline __attribute__((always_inline)) void step(Ray *r, __constant float *s, __global const float *media,
                                                uint nodes) {
    float hx, hy, hw, nx, ny, nz;
    meet(r, s, &hx, &hy, &hw, &nx, &ny, &nz);
    int action = (int)s[STEP_ACTION];
    __global const float *from = media + (uint)s[STEP_MEDIUM_FROM] * nodes + r->node;
    __global const float *to = media + (uint)s[STEP_MEDIUM_TO] * nodes + r->node;
    float n0 = from[0] + r->frac * (from[1] - from[0]), n2 = to[0] + r->frac * (to[1] - to[0]);
    float c1 = -(r->dx * nx + r->dy * ny + r->dz * nz);
    float R = reflectance((int)s[STEP_MODEL], n0, n2, c1, r->phase, r->layer);
    float eta = n0 / n2;
    float c2sq = 1.0f - eta * eta * (1.0f - c1 * c1);
    float k = eta * c1 - __builtin_sqrtf(c2sq > 0.0f ? c2sq : 0.0f);
    float tx = eta * r->dx + k * nx, ty = eta * r->dy + k * ny, tz = eta * r->dz + k * nz;
    float inv = 1.0f / __builtin_sqrtf(tx * tx + ty * ty + tz * tz);
    int reflect = action == ACTION_REFLECT, refract = action == ACTION_REFRACT;
    r->weight = reflect ? r->weight * R : (refract ? r->weight * (1.0f - R) : r->weight);
    r->alive = r->alive & (!refract | (c2sq >= 0.0f));
    r->dx = reflect ? r->dx + 2.0f * c1 * nx : (refract ? tx * inv : r->dx);
    r->dy = reflect ? r->dy + 2.0f * c1 * ny : (refract ? ty * inv : r->dy);
    r->dz = reflect ? r->dz + 2.0f * c1 * nz : (refract ? tz * inv : r->dz);
    r->ox = hx;
    r->oy = hy;
    r->w = hw + s[STEP_SHIFT];
}

/* Ray i's state from the input rows (see trace_path). */
inline __attribute__((always_inline)) void load(Ray *r, uint i, uint stride, __global const float *in, __global const float *media, uint nodes,
                 float lambda0, float inv_spacing) {
    float lambda = in[6 * stride + i];
    float u = (lambda - lambda0) * inv_spacing;
    float k = u > 0.0f ? (float)(int)u : 0.0f;  /* floor(u) clamped at 0, without the builtin's call */
    k = k > (float)(nodes - 2) ? (float)(nodes - 2) : k;
    r->node = (uint)k;
    r->frac = u - k;
    __global const float *layer = media + LAYER_MEDIUM * nodes + r->node;
    r->layer = layer[0] + r->frac * (layer[1] - layer[0]);
    r->phase = PI_LAMBDA0_OVER_NL0 * r->layer / lambda;
    r->ox = in[i];
    r->oy = in[stride + i];
    r->w = in[2 * stride + i];
    r->dx = in[3 * stride + i];
    r->dy = in[4 * stride + i];
    r->dz = in[5 * stride + i];
    r->weight = 1.0f;
    r->alive = 1;
}

/* Ray i's crossing of the film plane into the output rows (see trace_path). */
inline __attribute__((always_inline)) void store(Ray *r, uint i, uint stride, __global float *out) {
    float t = -r->w / r->dz;  /* w is now the axial position relative to the film plane */
    int alive = r->alive & (t > 0.0f);
    out[i] = alive ? r->ox + t * r->dx : 0.0f;
    out[stride + i] = alive ? r->oy + t * r->dy : 0.0f;
    out[2 * stride + i] = alive ? r->dx : 0.0f;
    out[3 * stride + i] = alive ? r->dy : 0.0f;
    out[4 * stride + i] = alive ? r->dz : 0.0f;
    out[5 * stride + i] = alive ? r->weight : 0.0f;
    out[6 * stride + i] = alive ? 1.0f : 0.0f;
}

/* Rays of a launch of stride / RAYS_PER_ITEM work items: in holds 7 rows of `stride` floats, origin
 * x, y, w (relative to the first step's vertex), direction x, y, z (unit) and wavelength (nm); out
 * holds 7 rows: film x, y, direction x, y, z at the film, weight, and 1 where the ray passed (0, and
 * the rest 0, where it did not). steps: `step_count` rows of STEP_WIDTH. media: each medium's index
 * (row STEP_MEDIUM_FROM / _TO of `nodes`) at wavelengths lambda0 + k / inv_spacing, interpolated
 * linearly at each ray's. Work item i of n traces rays i, i + n, ... (RAYS_PER_ITEM of them) through
 * each step before the next: independent chains of square roots and divisions for the processor to
 * overlap, where one ray's would wait on each other. The barrier ends a step's region (see the top);
 * every work item meets it step_count times, as OpenCL requires, and shares no memory through it.
 * Rays past `count` are padding, traced and dropped. */
__kernel void trace_path(uint count, uint step_count, __constant float *steps, __global const float *media,
                         uint nodes, float lambda0, float inv_spacing, uint stride, __global const float *in,
                         __global float *out) {
    uint items = stride / RAYS_PER_ITEM, i = get_global_id(0);
    Ray r[RAYS_PER_ITEM];
    for (uint j = 0; j < RAYS_PER_ITEM; j++) load(&r[j], i + j * items, stride, in, media, nodes, lambda0, inv_spacing);
    for (uint k = 0; k < step_count; k++) {
        for (uint j = 0; j < RAYS_PER_ITEM; j++) step(&r[j], steps + k * STEP_WIDTH, media, nodes);
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    for (uint j = 0; j < RAYS_PER_ITEM; j++) store(&r[j], i + j * items, stride, out);
}
