/* EWA texture lookups on a MIP map, one work-item per lookup: the same mathematics as
 * realistic/scene/mipmap.py (MipMap.ewa, its numpy reference), after pbrt-v3 src/core/mipmap.h
 * (MIPMap::EWA): eccentricity clamped to max_anisotropy, level from the minor axis, two levels
 * blended, each a sum over the texels inside the ellipse weighted by a 128-entry table of
 * exp(-2 r^2) - exp(-2). In single precision, as pbrt-v3's Float (lookups are float32 rows): the
 * same float32 operations in the same order as the reference, so the same taps, weights and sums,
 * with twice the vector lanes of float64. The ellipse is pbrt's, arranged so that no step cancels
 * (see ewa_ellipse). The axes' lengths, the eccentricity clamp and the level are float64 from the
 * float32 axes (ewa_axes), as before; the level's log2 is the library's, as numpy's, to float64
 * rounding. Float32 division is correctly rounded, as numpy's (ewa_kernel builds with
 * -cl-fp32-correctly-rounded-divide-sqrt).
 *
 * Texels: every level's RGB rows, level after level, in one float array (MipMap._texels);
 * level k has width[k] x height[k] texels starting at texel base[k]. WRAP, a #define the host prepends
 * (one program per wrap mode): 0 repeat, 1 black, 2 clamp (validation.TEXTURE_WRAPS's order). A constant,
 * not an argument, so that each tap computes its texel's address in its map's mode alone, the other
 * modes' clamps and tests folded away.
 *
 * sqrt, ceil, floor, fmax and fabs are written as LLVM's builtins: PoCL's library versions of the
 * OpenCL functions are calls, and cost about a fifth of a lookup's time (same results: each is
 * exact or correctly rounded either way). log2 stays the library's (__builtin_log2 is slower still).
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF  /* a * b + c rounds twice, as in numpy */

/* LUT_SIZE, the entries of the float32 weights table `lut`, is a #define the host prepends
 * (realistic/scene/ewa_kernel.py, from realistic.scene.mipmap.EWA_WEIGHTS). */

inline double3 texel(__global const float *texels, __global const long *base, __global const long *width,
                     __global const long *height, int level, int x, int y) {
    int w = (int)width[level], h = (int)height[level];
    double inside = 1.0;
    if (WRAP == 0) {
        x %= w; if (x < 0) x += w;
        y %= h; if (y < 0) y += h;
    } else {
        if (WRAP == 1 && (x < 0 || x >= w || y < 0 || y >= h)) inside = 0.0;
        x = clamp(x, 0, w - 1);
        y = clamp(y, 0, h - 1);
    }
    __global const float *p = texels + 3 * (base[level] + (long)y * w + x);
    return (double3)(p[0], p[1], p[2]) * inside;
}

/* Bilinear interpolation of texel centres at (s, t) on `level` (MipMap.bilinear). */
inline double3 bilinear_at(__global const float *texels, __global const long *base, __global const long *width,
                           __global const long *height, int level, double s, double t) {
    double x = s * width[level] - 0.5, y = t * height[level] - 0.5;
    double x0 = __builtin_floor(x), y0 = __builtin_floor(y);
    double fx = x - x0, fy = y - y0;
    int ix = (int)x0, iy = (int)y0;
    double3 top = texel(texels, base, width, height, level, ix, iy) * (1 - fx)
                + texel(texels, base, width, height, level, ix + 1, iy) * fx;
    double3 bottom = texel(texels, base, width, height, level, ix, iy + 1) * (1 - fx)
                   + texel(texels, base, width, height, level, ix + 1, iy + 1) * fx;
    return top * (1 - fy) + bottom * fy;
}

/* The smallest normal float32, the floor of the weights' sum (0 where no texel is inside). */
#define EWA_TINY 0x1p-126f

/* The footprint's float32 axes as EWA filters over them (MipMap._ewa_axes): the longer first, and the
 * minor one stretched so that the eccentricity is at most max_anisotropy (pbrt-v3 MIPMap::Lookup), in
 * float64 from the float32 axes (no square of a float32 overflows or underflows a float64, so no
 * footprint's length is lost) and rounded back; returns the minor axis's length. `one` (1.0) is the
 * callers' own, for the vectoriser (see ewa_small). */
inline __attribute__((always_inline)) double ewa_axes(float *majs_out, float *majt_out, float *mins_out,
                                                      float *mint_out, double max_anisotropy, double one) {
    double majs = *majs_out, majt = *majt_out, mins = *mins_out, mint = *mint_out;
    int swap = majs * majs + majt * majt < (mins * mins + mint * mint) * one;
    double hs = swap ? mins : majs, ht = swap ? mint : majt;
    mins = swap ? majs : mins;
    mint = swap ? majt : mint;
    double major_len = __builtin_sqrt(hs * hs + ht * ht);
    double minor_len = __builtin_sqrt(mins * mins + mint * mint) * one;
    int clamped = minor_len * max_anisotropy < major_len && minor_len > 0;
    double stretch = major_len / __builtin_fmax(minor_len * max_anisotropy, 1e-300);
    *majs_out = (float)hs;
    *majt_out = (float)ht;
    *mins_out = (float)(clamped ? mins * stretch : mins);
    *mint_out = (float)(clamped ? mint * stretch : mint);
    return clamped ? minor_len * stretch : minor_len;
}

/* The EWA ellipse of the axes (a0s, a0t), (a1s, a1t) in texels, widened by a texel (pbrt-v3
 * MIPMap::EWA: A s^2 + B s t + C t^2 < F, A = a0t^2 + a1t^2 + 1, B = -2 (a0s a0t + a1s a1t),
 * C = a0s^2 + a1s^2 + 1, F = A C - B^2 / 4, r^2 the left side over F), arranged so that no step
 * cancels: F summed from its positive terms, (a0s a1t - a0t a1s)^2 + A + C - 1 (at least 1), and
 * r^2 = a (s - mid)^2 + t^2 / A with a = A / F, a row's centre mid = s - t B / (2 A) and its
 * half-width sqrt((1 - t^2 / A) / a), the ellipse's half-height sqrt(A). pbrt's a c - b^2 / 4 and
 * b^2 - 4 a c of a row's crossings cancel to nothing in float32 at eccentricities max_anisotropy
 * allows (1024). Writes a, 1 / a, B / (2 A), 1 / A and the half-height. */
inline __attribute__((always_inline)) void ewa_ellipse(float a0s, float a0t, float a1s, float a1t, float *a_out,
                                                       float *inv_a_out, float *shift_out, float *inv_big_a_out,
                                                       float *half_t_out) {
    float big_a = a0t * a0t + a1t * a1t + 1;
    float big_b = -2 * (a0s * a0t + a1s * a1t);
    float big_c = a0s * a0s + a1s * a1s + 1;
    float cross = a0s * a1t - a0t * a1s;
    float f = cross * cross + (big_a + big_c - 1);
    float inv_big_a = 1 / big_a;
    *a_out = big_a / f;
    *inv_a_out = f * inv_big_a;
    *shift_out = 0.5f * big_b * inv_big_a;
    *inv_big_a_out = inv_big_a;
    *half_t_out = __builtin_sqrtf(big_a);
}

inline float3 ewa_level(__global const float *texels, __global const long *base, __global const long *width,
                        __global const long *height, int levels, __global const float *lut,
                        long level, float s0, float t0_, float a0s, float a0t, float a1s, float a1t) {
    if (level >= levels) {
        __global const float *p = texels + 3 * base[levels - 1];
        return (float3)(p[0], p[1], p[2]);
    }
    float w = (float)width[level], h = (float)height[level];
    float s = s0 * w - 0.5f, t = t0_ * h - 0.5f;
    a0s *= w; a0t *= h; a1s *= w; a1t *= h;
    float a, inv_a, shift, inv_big_a, half_t;
    ewa_ellipse(a0s, a0t, a1s, a1t, &a, &inv_a, &shift, &inv_big_a, &half_t);
    int y0 = (int)__builtin_ceilf(t - half_t), y1 = (int)__builtin_floorf(t + half_t);
    /* texel() per tap, with the wrap done once per row and the column stepped. Every level's sides are
     * powers of two (MipMap), so repeat's x mod w is x & (w - 1), also for negative x. */
    int iw = (int)width[level], ih = (int)height[level];
    __global const float *level_texels = texels + 3 * base[level];
    float3 sum = (float3)(0.0f);
    float weights = 0.0f;
    for (int y = y0; y <= y1; ++y) {
        float dt = (float)y - t;
        float row_r2 = dt * dt * inv_big_a;
        float mid = s - shift * dt;
        float half_w = __builtin_sqrtf(__builtin_fmaxf(1 - row_r2, 0.0f) * inv_a);
        int x0 = (int)__builtin_ceilf(mid - half_w), x1 = (int)__builtin_floorf(mid + half_w);
        int row = WRAP == 0 ? y & (ih - 1) : clamp(y, 0, ih - 1);
        float row_inside = WRAP == 1 && (y < 0 || y >= ih) ? 0.0f : 1.0f;
        __global const float *row_texels = level_texels + 3 * (long)row * iw;
        for (int x = x0; x <= x1; ++x) {
            float u = (float)x - mid;
            float r2 = a * u * u + row_r2;
            if (r2 < 1) {
                /* r2 < 1, so r2 * 128 < 128 exactly: the index is at most 127 */
                float weight = lut[(int)(r2 * LUT_SIZE)];
                int at = WRAP == 0 ? x & (iw - 1) : clamp(x, 0, iw - 1);
                float inside = WRAP == 1 && (x < 0 || x >= iw) ? 0.0f : row_inside;
                __global const float *p = row_texels + 3 * at;
                sum += (float3)(p[0], p[1], p[2]) * inside * weight;
                weights += weight;
            }
        }
    }
    return sum / __builtin_fmaxf(weights, EWA_TINY);
}

/* The filtered colour of a lookup (s, t, axes as ewa_small reads them): none (0) where a value is not
 * finite in float32; level 0 bilinear where the minor axis is 0; else the two levels around the level
 * of the minor axis (clamped to 0) blended. */
inline float3 ewa_lookup(__global const float *texels, __global const long *base, __global const long *width,
                         __global const long *height, int levels, double max_anisotropy,
                         __global const float *lut, __global const float *lookup) {
    float s = lookup[0], t = lookup[1];
    float majs = lookup[2], majt = lookup[3], mins = lookup[4], mint = lookup[5];
    if (!(__builtin_isfinite(s) && __builtin_isfinite(t) && __builtin_isfinite(majs) && __builtin_isfinite(majt)
          && __builtin_isfinite(mins) && __builtin_isfinite(mint))) return (float3)(0.0f);
    double minor_len = ewa_axes(&majs, &majt, &mins, &mint, max_anisotropy, 1.0);
    if (minor_len == 0)
        return convert_float3(bilinear_at(texels, base, width, height, 0, s, t));
    /* lod is 0 where the minor axis is at most 2^(1 - levels) (a texel of the finest level along its
     * longer side): log2 is exact at powers of two and monotone, so levels - 1 + log2 of such a
     * length is at most 0, and the library call is skipped */
    double length = __builtin_fmax(minor_len, 1e-8);
    double lod = length <= 1.0 / (double)(1L << (levels - 1)) ? 0.0
               : __builtin_fmax(0.0, levels - 1 + log2(length));
    double lower = __builtin_floor(lod);
    float delta = (float)(lod - lower);
    float3 value = ewa_level(texels, base, width, height, levels, lut, (long)lower, s, t, majs, majt, mins, mint);
    /* A magnified lookup (lod clamped to 0: most of a near floor's) gives the next level no weight:
     * value * 1 + next * 0 is value, bit for bit, so the next level's sum is skipped. */
    if (delta == 0) return value;
    return value * (1 - delta)
         + ewa_level(texels, base, width, height, levels, lut, (long)lower + 1, s, t, majs, majt, mins, mint) * delta;
}

/* The arguments every filter's kernels take (EwaKernel._filter passes them in this order): a _small kernel
 * filters the lookups it can and marks the others pending; the kernel of the filter's own name filters the
 * pending rows in place. */
#define MAP_TABLES __global const float *texels, __global const long *base, __global const long *width, \
    __global const long *height, const int levels, const double max_anisotropy, __global const float *lut
#define LOOKUP_TABLES MAP_TABLES, __global const double *lookups
#define SMALL_LOOKUP_PARAMETERS LOOKUP_TABLES, const float red_scale, const float green_scale, \
    const float blue_scale, const int count, const int unit, __global uchar *pending, __global float *out
#define PENDING_LOOKUP_PARAMETERS LOOKUP_TABLES, __global const int *rows, const float red_scale, \
    const float green_scale, const float blue_scale, const int count, __global float *out
/* EWA's kernels read float32 lookups (EWA_LOOKUP_TABLES) and write through restrict pointers: no
 * 64-bit load is left in ewa_small's work-item loop (the level-0 sides are hoisted out of it once
 * the stores cannot alias them), so the vectoriser widens it to float32's lanes. */
#define EWA_LOOKUP_TABLES MAP_TABLES, __global const float *lookups
#define EWA_SMALL_PARAMETERS EWA_LOOKUP_TABLES, const float red_scale, const float green_scale, \
    const float blue_scale, const int count, const int unit, __global uchar *restrict pending, \
    __global float *restrict out
#define EWA_PENDING_PARAMETERS EWA_LOOKUP_TABLES, __global const int *rows, const float red_scale, \
    const float green_scale, const float blue_scale, const int count, __global float *restrict out

/* The scalar kernels (ewa, bilinear, point, trilinear) filter the lookups their _small twin left pending:
 * lookup rows[i] of `lookups` (rows of 6 doubles, EWA's of 6 floats, as the _small kernels read them), its colour times
 * (red, green, blue)_scale written into its own row of `out` (float32 products, as the _small kernels'),
 * so the host gathers and scatters nothing. */
inline void store(__global float *out, int r, float3 value, float red_scale, float green_scale,
                  float blue_scale) {
    out[3 * r] = red_scale * value.x;
    out[3 * r + 1] = green_scale * value.y;
    out[3 * r + 2] = blue_scale * value.z;
}

__kernel void ewa(EWA_PENDING_PARAMETERS) {
    int i = get_global_id(0);
    if (i >= count) return;
    int r = rows[i];
    float3 value = ewa_lookup(texels, base, width, height, levels, max_anisotropy, lut, lookups + 6 * (long)r);
    store(out, r, value, red_scale, green_scale, blue_scale);
}
/* ------------------------------------------------------------------ lookups at surface hits
 * The EWA lookups of camera-ray hits on one image-textured material, from embree's hit records: what
 * realistic.renderer.integrator.DirectLighting._albedo computes in numpy (its reference) before its
 * lookups, in the same operations and order (FP_CONTRACT off, so a * b + c rounds twice as numpy's does):
 *   - embree's Ng normalised in float32 and turned to face the ray (_facing);
 *   - the uv interpolated in float32 from the triangle's corners with barycentrics (1 - u - v, u, v);
 *   - the pixel footprint in float64 (realistic/renderer/footprint.py): the cone of width t * spread
 *     cut by the tangent plane (across the ray, and along its projection stretched by
 *     1 / max(|cos|, MIN_COSINE)), carried into uv by the triangle's world edges (the instance's
 *     linear map times the mesh's float64 edges) and uv edges;
 *   - st = uv * scale + offset with t flipped for a bottom-origin image, the axes scaled alike
 *     (realistic/scene/textures.py).
 * hit_lookups writes lookup i (s, t, axis0, axis1: 6 doubles; hit_lookups_single, ewa_small's input,
 * the same rounded to 6 floats) for the hit in
 * row rows[i], which the host picks among the hits on instances of the texture's material;
 * ewa_small, then ewa, filter them, times the material's diffuse colour. It is written for PoCL's
 * work-group vectoriser as ewa_small is (see there): scalars, no branches, every read inside its
 * table (work items past `count` read rows[count - 1]), and `one` (1.0) or `onef` (1.0f) on
 * one of each pair of alike expressions LLVM's SLP vectoriser would otherwise pack first (the y
 * and z of the normal, the second edge and its products, one uv of each axis).
 * MAPPING holds: spread (the camera's radians per pixel), s scale, t scale, s offset, t offset, t
 * flip (+-1), t shift (0 or 1), diffuse r, g, b, at the MAPPING_* offsets the host prepends
 * (realistic/scene/ewa_kernel.py: MAPPING). */

#define MIN_COSINE 1e-3
#define AT(a, w, i, c) ((a)[(w) * (i) + (c) * unit])

inline double dot3s(double ax, double ay, double az, double bx, double by, double bz) {
    return ax * bx + ay * by + az * bz;
}

/* The footprint code of hit_lookups and triangle_footprints: one definition of footprint.py's
 * triangle_footprint (its numpy reference) in the same float64 operations and order. world_edges: a
 * triangle's world edges, the linear map m (3 x 3, row-major: an instance's) times its mesh-space edges
 * p1 - p0 and p2 - p0 (corners c0, c1, c2: rows of the float64 `vertices`), each component summed
 * left to right as numpy's einsum does. footprint_axes: the uv axes of the pixel cone of width w cut
 * by the plane of unit normal (nrx, nry, nrz) along unit (ddx, ddy, ddz) (tangent_axes: across the ray,
 * (a0u, a0v), and along its projection stretched by 1 / max(|cos|, MIN_COSINE), (a1u, a1v)), carried
 * into uv by the world edges and the uv edges (g1s, g1t), (g2s, g2t) (to_uv: zero on a triangle
 * whose world edges are degenerate). `unit` and `one` (1 and 1.0) are the callers' own, for the
 * vectoriser (see hit_lookups), which widens a kernel only without calls: always inlined (LLVM's
 * inliner found footprint_axes just over its cost threshold in triangle_footprints). */
inline __attribute__((always_inline)) void world_edges(__global const double *vertices, __global const double *m,
                                                       int c0, int c1, int c2, const int unit, double one,
                                                       double *e1x, double *e1y, double *e1z, double *e2x,
                                                       double *e2y, double *e2z) {
    double px = AT(vertices, 3, c0, 0), py = AT(vertices, 3, c0, 1), pz = AT(vertices, 3, c0, 2);
    double q1x = AT(vertices, 3, c1, 0) - px, q1y = AT(vertices, 3, c1, 1) - py, q1z = AT(vertices, 3, c1, 2) - pz;
    double q2x = (AT(vertices, 3, c2, 0) - px) * one, q2y = (AT(vertices, 3, c2, 1) - py) * one;
    double q2z = (AT(vertices, 3, c2, 2) - pz) * one;
    *e1x = AT(m, 3, 0, 0) * q1x + AT(m, 3, 0, 1) * q1y + AT(m, 3, 0, 2) * q1z;
    *e1y = AT(m, 3, 1, 0) * q1x + AT(m, 3, 1, 1) * q1y + AT(m, 3, 1, 2) * q1z;
    *e1z = AT(m, 3, 2, 0) * q1x + AT(m, 3, 2, 1) * q1y + AT(m, 3, 2, 2) * q1z;
    *e2x = AT(m, 3, 0, 0) * q2x + AT(m, 3, 0, 1) * q2y + AT(m, 3, 0, 2) * q2z;
    *e2y = AT(m, 3, 1, 0) * q2x + AT(m, 3, 1, 1) * q2y + AT(m, 3, 1, 2) * q2z;
    *e2z = AT(m, 3, 2, 0) * q2x + AT(m, 3, 2, 1) * q2y + AT(m, 3, 2, 2) * q2z;
}

inline __attribute__((always_inline)) void footprint_axes(double w, double ddx, double ddy, double ddz,
                                                          double nrx, double nry, double nrz, double e1x, double e1y,
                                                          double e1z, double e2x, double e2y, double e2z, double g1s,
                                                          double g1t, double g2s, double g2t, double one,
                                                          double *a0u, double *a0v, double *a1u, double *a1v) {
    /* the tangent axes (footprint.tangent_axes) */
    double cosine = dot3s(ddx, ddy, ddz, nrx, nry, nrz);
    double ox = ddx - cosine * nrx, oy = ddy - cosine * nry, oz = ddz - cosine * nrz;
    double olen = __builtin_sqrt(dot3s(ox, oy, oz, ox, oy, oz));
    ox = olen > 0 ? ox / olen : 0.0;
    oy = olen > 0 ? oy / olen : 0.0;
    oz = olen > 0 ? oz / olen : 0.0;
    /* a ray along the normal: the normal crossed with x, or with y near the x axis */
    int near_x = !(__builtin_fabs(nrx) < 0.9);
    double tx = near_x ? 0.0 : 1.0, ty = near_x ? 1.0 : 0.0;
    double kx = nry * 0.0 - nrz * ty, ky = nrz * tx - nrx * 0.0, kz = nrx * ty - nry * tx;
    double klen = __builtin_sqrt(dot3s(kx, ky, kz, kx, ky, kz));
    int turned = !(dot3s(ox, oy, oz, ox, oy, oz) > 0.5);
    double ax_ = turned ? (klen > 0 ? kx / klen : 0.0) : ox;
    double ay_ = turned ? (klen > 0 ? ky / klen : 0.0) : oy;
    double az_ = turned ? (klen > 0 ? kz / klen : 0.0) : oz;
    double cx = nry * az_ - nrz * ay_, cy = nrz * ax_ - nrx * az_, cz = nrx * ay_ - nry * ax_;
    double stretch = 1.0 / __builtin_fmax(__builtin_fabs(cosine), MIN_COSINE);
    double wa = w * stretch;

    /* their uv offsets (to_uv) */
    double g11 = dot3s(e1x, e1y, e1z, e1x, e1y, e1z), g12 = dot3s(e1x, e1y, e1z, e2x, e2y, e2z);
    double g22 = dot3s(e2x, e2y, e2z, e2x, e2y, e2z) * one;
    double det_uv = g11 * g22 - g12 * g12;
    double inv_uv = det_uv > 1e-12 * g11 * g22 ? 1.0 / det_uv : 0.0;
    double wx = cx * w, wy = cy * w, wz = cz * w;
    double r1 = dot3s(e1x, e1y, e1z, wx, wy, wz), r2_ = dot3s(e2x, e2y, e2z, wx, wy, wz) * one;
    double alpha = (g22 * r1 - g12 * r2_) * inv_uv, beta = (g11 * r2_ - g12 * r1) * inv_uv;
    *a0u = alpha * g1s + beta * g2s;
    *a0v = (alpha * g1t + beta * g2t) * one;
    wx = ax_ * wa; wy = ay_ * wa; wz = az_ * wa;
    r1 = dot3s(e1x, e1y, e1z, wx, wy, wz);
    r2_ = dot3s(e2x, e2y, e2z, wx, wy, wz) * one;
    alpha = (g22 * r1 - g12 * r2_) * inv_uv;
    beta = (g11 * r2_ - g12 * r1) * inv_uv;
    *a1u = (alpha * g1s + beta * g2s) * one;
    *a1v = alpha * g1t + beta * g2t;
}

#define HIT_LOOKUP_PARAMETERS __global const int *faces, __global const double *vertices, \
    __global const float *uvs, __global const int *geom_face_offset, __global const double *geom_linear, \
    __global const double *mapping, __global const float *direction, __global const float *tfar, \
    __global const float *hit_u, __global const float *hit_v, __global const int *prim, __global const int *geom, \
    __global const float *ng_in, __global const int *rows, const int count, const int unit
#define HIT_LOOKUP_ARGUMENTS faces, vertices, uvs, geom_face_offset, geom_linear, mapping, direction, tfar, hit_u, \
    hit_v, prim, geom, ng_in, rows, count, unit

/* Work item i's lookup (s, t, axis0, axis1) into `lookup`: hit_lookups' body, which stores it as
 * doubles, hit_lookups_single's (EWA's lookups), as floats. */
inline __attribute__((always_inline)) void hit_lookup(HIT_LOOKUP_PARAMETERS, int i, double *lookup) {
    double one = (double)unit;
    float onef = (float)unit;
    int r = rows[i < count ? i : count - 1];
    int g = geom[r];

    /* embree's normal, normalised in float32 and facing the ray */
    float dx = AT(direction, 3, r, 0), dy = AT(direction, 3, r, 1), dz = AT(direction, 3, r, 2);
    float nx = AT(ng_in, 3, r, 0), ny = AT(ng_in, 3, r, 1), nz = AT(ng_in, 3, r, 2);
    float nlen = __builtin_sqrtf(nx * nx + ny * ny + nz * nz);
    nx = nlen > 0.0f ? nx / nlen : 0.0f;
    ny = nlen > 0.0f ? ny * onef / nlen : 0.0f;
    nz = nlen > 0.0f ? nz / nlen : 0.0f;
    float side = nx * dx + ny * dy + nz * dz > 0.0f ? -1.0f : 1.0f;
    double nrx = nx * side, nry = ny * side, nrz = nz * side * onef;
    double ddx = dx, ddy = dy, ddz = dz;

    /* the triangle, its uv at the hit (float32) and its edges in world space and in uv */
    int f = 3 * (geom_face_offset[g] + prim[r]);
    int c0 = AT(faces, 1, f, 0), c1 = AT(faces, 1, f, 1), c2 = AT(faces, 1, f, 2);
    float u = hit_u[r], v = hit_v[r];
    float b0 = 1.0f - u - v;
    float u0 = AT(uvs, 2, c0, 0), v0 = AT(uvs, 2, c0, 1), u1 = AT(uvs, 2, c1, 0), v1 = AT(uvs, 2, c1, 1);
    float u2 = AT(uvs, 2, c2, 0), v2 = AT(uvs, 2, c2, 1);
    float us = u0 * b0 + u1 * u + u2 * v;
    float vs = v0 * b0 + v1 * u + v2 * v;
    double g1s = (double)u1 - (double)u0, g1t = (double)v1 - (double)v0;
    double g2s = (double)u2 - (double)u0, g2t = (double)v2 - (double)v0;
    double e1x, e1y, e1z, e2x, e2y, e2z;
    world_edges(vertices, geom_linear + 9 * g, c0, c1, c2, unit, one, &e1x, &e1y, &e1z, &e2x, &e2y, &e2z);

    /* the footprint (footprint.uv_footprint) */
    double a0u, a0v, a1u, a1v;
    footprint_axes((double)tfar[r] * AT(mapping, 1, MAPPING_SPREAD, 0), ddx, ddy, ddz, nrx, nry, nrz,
                   e1x, e1y, e1z, e2x, e2y, e2z, g1s, g1t, g2s, g2t, one, &a0u, &a0v, &a1u, &a1v);

    /* into the image's st (textures._image) */
    double scale_s = AT(mapping, 1, MAPPING_ST_SCALE, 0), scale_t = AT(mapping, 1, MAPPING_ST_SCALE, 1);
    double flip_t = AT(mapping, 1, MAPPING_T_FLIP, 0);
    double s0 = ((double)us * scale_s + AT(mapping, 1, MAPPING_ST_OFFSET, 0)) * 1.0 + 0.0;
    double t0 = ((double)vs * scale_t + AT(mapping, 1, MAPPING_ST_OFFSET, 1)) * flip_t
              + AT(mapping, 1, MAPPING_T_SHIFT, 0);
    double majs = a0u * scale_s * 1.0, majt = a0v * scale_t * flip_t;
    double mins = a1u * scale_s * 1.0, mint = a1v * scale_t * flip_t;

    lookup[0] = s0;
    lookup[1] = t0;
    lookup[2] = majs;
    lookup[3] = majt;
    lookup[4] = mins;
    lookup[5] = mint;
}

/* hit_lookups writes the float64 rows of the point, bilinear and trilinear filters; hit_lookups_single
 * the same rows rounded to float32, EWA's. One body, two output types. The store loop is unrolled
 * (_Pragma: a #pragma cannot stand in a macro): a loop left in the body keeps PoCL's work-item loop
 * from being innermost, and the vectoriser widens innermost loops alone. */
#define HIT_LOOKUPS_KERNEL(name, type)                                                  \
__kernel void name(HIT_LOOKUP_PARAMETERS, __global type *restrict lookups) {            \
    int i = get_global_id(0);                                                           \
    double lookup[6];                                                                   \
    hit_lookup(HIT_LOOKUP_ARGUMENTS, i, lookup);                                        \
    if (i < count) {                                                                    \
        _Pragma("unroll")                                                               \
        for (int k = 0; k < 6; ++k) AT(lookups, 6, i, k) = (type)lookup[k];             \
    }                                                                                   \
}
HIT_LOOKUPS_KERNEL(hit_lookups, double)
HIT_LOOKUPS_KERNEL(hit_lookups_single, float)

/* ------------------------------------------------------------------ footprints of hits
 * triangle_footprints is footprint.triangle_footprint (its numpy reference) on the device, for the
 * image textures the host's SurfaceParameters look up (realistic/scene/ewa_kernel.py,
 * FootprintKernel): hit i on the triangle faces[i] (three rows of `vertices` and of the float32
 * `uvs`) of instance geom[i] (its linear map linear[geom[i]], 3 x 3 row-major), with unit
 * direction[i], unit normal[i] (as given: the reference neither normalises nor turns it) and hit
 * distance[i], all float64 as the reference reads them. It writes the footprint's axes, axis0[i]
 * across the ray and axis1[i] along it (2 doubles each), by world_edges and footprint_axes as
 * hit_lookups does, and is written for the vectoriser as hit_lookups is (work items past `count`
 * read row count - 1 and write nothing). */
__kernel void triangle_footprints(__global const int *faces, __global const double *vertices,
                                  __global const float *uvs, __global const double *linear,
                                  __global const int *geom, __global const double *direction,
                                  __global const double *normal, __global const double *distance,
                                  const double spread, const int count, const int unit,
                                  __global double *axis0, __global double *axis1) {
    int i = get_global_id(0);
    double one = (double)unit;
    int r = i < count ? i : count - 1;
    int c0 = AT(faces, 3, r, 0), c1 = AT(faces, 3, r, 1), c2 = AT(faces, 3, r, 2);
    float u0 = AT(uvs, 2, c0, 0), v0 = AT(uvs, 2, c0, 1), u1 = AT(uvs, 2, c1, 0), v1 = AT(uvs, 2, c1, 1);
    float u2 = AT(uvs, 2, c2, 0), v2 = AT(uvs, 2, c2, 1);
    double g1s = (double)u1 - (double)u0, g1t = (double)v1 - (double)v0;
    double g2s = (double)u2 - (double)u0, g2t = (double)v2 - (double)v0;
    double e1x, e1y, e1z, e2x, e2y, e2z;
    world_edges(vertices, linear + 9 * geom[r], c0, c1, c2, unit, one, &e1x, &e1y, &e1z, &e2x, &e2y, &e2z);
    double a0u, a0v, a1u, a1v;
    footprint_axes(distance[r] * spread, AT(direction, 3, r, 0), AT(direction, 3, r, 1), AT(direction, 3, r, 2),
                   AT(normal, 3, r, 0), AT(normal, 3, r, 1), AT(normal, 3, r, 2), e1x, e1y, e1z, e2x, e2y, e2z,
                   g1s, g1t, g2s, g2t, one, &a0u, &a0v, &a1u, &a1v);
    if (i < count) {
        AT(axis0, 2, i, 0) = a0u;
        AT(axis0, 2, i, 1) = a0v;
        AT(axis1, 2, i, 0) = a1u;
        AT(axis1, 2, i, 1) = a1v;
    }
}

/* ------------------------------------------------------------------ magnified lookups, vectorised
 * ewa_small is ewa for the lookups that read level 0 alone (lod clamped to 0: the minor axis at most
 * a texel of level 0, as most of a near floor's are at a render's sample counts) over an ellipse of
 * at most SMALL_SIDE rows of at most SMALL_SIDE texels each, and writes their colours times
 * (red, green, blue)_scale (float32 products: a material's diffuse colour, or 1); it writes
 * pending[i] = 1 for every other lookup, which the host gives to ewa. Lookups are rows of 6
 * floats: s, t, axis0, axis1. Same operations in the same order as ewa_lookup and ewa_level, so
 * the same bits: each row of the ellipse is walked from its first crossing over SMALL_SIDE columns,
 * and a column past the span or outside the ellipse adds +0.0 (the sum unchanged, but for the sign
 * of a zero sum) where ewa_level adds nothing.
 *
 * Written for PoCL's work-group vectoriser as kernels/shade.cl is (see its header): scalars only
 * (its loop vectoriser widens no OpenCL vector types), LLVM builtins for the maths, the fixed loops
 * unrolled, no early exits, ternaries for branches, every gather's index inside its table (rows past
 * `count` read row count - 1; values bound for an int are zeroed where the lookup is left to ewa),
 * and the reads offset through `unit` (always 1). LLVM's SLP vectoriser packs pairs of alike
 * expressions into 2-wide vectors before PoCL's vectoriser runs, which then gives up on the kernel:
 * `one` (unit as a double or a float, 1.0) multiplies one of each pair it took (minor axis against
 * major, t against s), which changes no bit (x * 1.0 is x) and leaves no two alike. POCL_VECTORIZER_REMARKS=1 prints
 * "vectorized loop" for ewa_small and hit_lookups (tests/test_ewa_kernel.py, test_ewa_hits.py check). */

#define SMALL_SIDE 3

__kernel void ewa_small(EWA_SMALL_PARAMETERS) {
    int i = get_global_id(0);
    int r = i < count ? i : count - 1;
    float one = (float)unit;
    float s0 = AT(lookups, 6, r, 0), t0 = AT(lookups, 6, r, 1);
    float majs = AT(lookups, 6, r, 2), majt = AT(lookups, 6, r, 3);
    float mins = AT(lookups, 6, r, 4), mint = AT(lookups, 6, r, 5);
    double minor_len = ewa_axes(&majs, &majt, &mins, &mint, max_anisotropy, (double)unit);
    double length = __builtin_fmax(minor_len, 1e-8);
    int magnified = minor_len != 0 && length <= 1.0 / (double)(1L << (levels - 1));
    float lw = (float)width[0], lh = (float)height[0];
    float s = s0 * lw - 0.5f, t = (t0 * lh - 0.5f) * one;
    float a0s = majs * lw, a0t = majt * lh, a1s = mins * lw, a1t = mint * lh;
    float a, inv_a, shift, inv_big_a, half_t;
    ewa_ellipse(a0s, a0t, a1s, a1t, &a, &inv_a, &shift, &inv_big_a, &half_t);
    /* a non-finite s, t or axis fails one of these (NaN compares false; an infinite axis makes
     * half_t infinite): ewa gives those 0 */
    int small = i < count && magnified && __builtin_fabsf(s) < 1e9f && __builtin_fabsf(t) < 1e9f
                && half_t < SMALL_SIDE;
    float ts = small ? t : 0.0f, hts = small ? half_t : 0.0f, ss = small ? s : 0.0f;
    int y0 = (int)__builtin_ceilf(ts - hts), y1 = (int)__builtin_floorf(ts + hts);
    small = small && y1 - y0 < SMALL_SIDE;
    int iw = (int)width[0], ih = (int)height[0];
    long level_base = base[0];
    float sum_r = 0.0f, sum_g = 0.0f, sum_b = 0.0f, weights = 0.0f;
    #pragma unroll
    for (int j = 0; j < SMALL_SIDE; ++j) {
        int y = y0 + j;
        float dt = (float)y - ts;
        float row_r2 = dt * dt * inv_big_a;
        float mid = ss - shift * dt;
        float half_w = __builtin_sqrtf(__builtin_fmaxf(1 - row_r2, 0.0f) * inv_a);
        float left = small ? mid - half_w : 0.0f, right = small ? mid + half_w : 0.0f;
        int x0 = (int)__builtin_ceilf(left), x1 = (int)__builtin_floorf(right);
        int in_rows = y <= y1;
        small = small && (!in_rows || x1 - x0 < SMALL_SIDE);
        int row = WRAP == 0 ? y & (ih - 1) : (y < 0 ? 0 : (y > ih - 1 ? ih - 1 : y));
        float row_inside = WRAP == 1 && (y < 0 || y >= ih) ? 0.0f : 1.0f;
        #pragma unroll
        for (int k = 0; k < SMALL_SIDE; ++k) {
            int x = x0 + k;
            float u = (float)x - mid;
            float r2 = a * u * u + row_r2;
            int take = in_rows && x <= x1 && r2 < 1;
            float weight = lut[(int)((take ? r2 : 0.0f) * LUT_SIZE)];
            int at = WRAP == 0 ? x & (iw - 1) : (x < 0 ? 0 : (x > iw - 1 ? iw - 1 : x));
            float inside = WRAP == 1 && (x < 0 || x >= iw) ? 0.0f : row_inside;
            long texel_at = level_base + (long)row * iw + at;
            float red = AT(texels, 3, texel_at, 0), green = AT(texels, 3, texel_at, 1);
            float blue = AT(texels, 3, texel_at, 2);
            sum_r += take ? red * inside * weight : 0.0f;
            sum_g += take ? green * inside * weight : 0.0f;
            sum_b += take ? blue * inside * weight : 0.0f;
            weights += take ? weight : 0.0f;
        }
    }
    float norm = __builtin_fmaxf(weights, EWA_TINY);
    if (small) {
        AT(out, 3, i, 0) = red_scale * (sum_r / norm);
        AT(out, 3, i, 1) = green_scale * (sum_g / norm);
        AT(out, 3, i, 2) = blue_scale * (sum_b / norm);
    }
    if (i < count) pending[i] = !small;
}

/* ------------------------------------------------------------------ point, bilinear and trilinear lookups
 * pbrt-v4's "point" and "bilinear" image-texture filters and both versions' "trilinear" (pbrt-v4
 * src/pbrt/util/mipmap.cpp, MIPMap::Filter; pbrt-v3 src/core/mipmap.h, MIPMap::Lookup): the filter
 * width twice the largest component of either axis (textures._image), the continuous level
 * levels - 1 + log2(width); at or past the coarsest level, its one texel (unwrapped); else point takes
 * the nearest texel (st * size - 0.5 rounded half away from zero, as std::round) and bilinear the
 * bilinear lookup at the level's floor clamped to 0, and trilinear blends the bilinear lookups of the
 * two levels around it (clamped to 0), or where that floor is under blend_from (its kernels' last
 * argument: 0 as pbrt-v3, 1 as pbrt-v4's `if (iLevel == 0) return Bilerp<T>(0, st)`) takes level 0's
 * alone: MipMap.point, bilinear_at_width and trilinear (MipMap.trilinear_blend_from), the numpy
 * references, in the same float64 operations, so the same bits (trilinear's blend weight is the
 * fraction of log2, OpenCL's to 3 ulps: within float32 rounding of the reference).
 *
 * Each filter's _small kernel does the lookups that read level 0 alone whatever the rounding of log2
 * (within 3 ulps, OpenCL's bound, a width under the limit times 1 - 2^-40 keeps the level under the
 * limit's by 1e-12), so no library call: most of a near floor's. The limit is 2^(2 - levels) for point
 * and bilinear (level under 1; 1 for a one-level map, whose level 0 is the coarsest) and for trilinear
 * blending from level 1 (level 0 alone under level 1), and 2^(1 - levels) for trilinear blending from
 * level 0 (level under 0, where the blend's second weight is 0: b0 * 1 + b1 * 0 is b0, bit for bit).
 * They are ewa_small's twins (same arguments, read as there, trilinear's then blend_from; written for
 * PoCL's vectoriser as ewa_small is) and mark the others pending for the scalar kernel of the same name,
 * ewa's twin (same arguments, trilinear's then blend_from). */

inline double filter_width(double a0s, double a0t, double a1s, double a1t) {
    return 2 * __builtin_fmax(__builtin_fmax(__builtin_fabs(a0s), __builtin_fabs(a0t)),
                              __builtin_fmax(__builtin_fabs(a1s), __builtin_fabs(a1t)));
}

/* The width under which point and bilinear read level 0 and are not at the coarsest level. */
inline double level0_limit(int levels) {
    return (levels > 1 ? 2.0 : 1.0) / (double)(1L << (levels - 1)) * (1 - 0x1p-40);
}

/* x rounded to the nearest integer, halves away from zero (C's round), as MipMap's _round_half_away. */
inline double round_half_away(double x) {
    double whole = __builtin_trunc(x);
    return whole + (__builtin_fabs(x - whole) >= 0.5 ? (x > 0 ? 1.0 : -1.0) : 0.0);
}

/* The coarsest level's one texel, as it is (MipMap._coarsest_where_wide). */
inline double3 coarsest(__global const float *texels, __global const long *base, int levels) {
    __global const float *p = texels + 3 * base[levels - 1];
    return (double3)(p[0], p[1], p[2]);
}

/* bilinear_small and trilinear_small: the bilinear lookup at level 0 of the lookups whose width is
 * under `limit`, scaled; the others marked pending. */
inline void bilinear_level0(__global const float *texels, __global const long *base, __global const long *width,
                            __global const long *height, const int levels,
                            __global const double *lookups, const float red_scale, const float green_scale,
                            const float blue_scale, const int count, const int unit, __global uchar *pending,
                            __global float *out, double limit) {
    int i = get_global_id(0);
    int r = i < count ? i : count - 1;
    double one = (double)unit;
    double w = filter_width(AT(lookups, 6, r, 2), AT(lookups, 6, r, 3), AT(lookups, 6, r, 4), AT(lookups, 6, r, 5));
    double lw = (double)width[0], lh = (double)height[0];
    double x = AT(lookups, 6, r, 0) * lw - 0.5, y = (AT(lookups, 6, r, 1) * lh - 0.5) * one;
    int small = i < count && w < limit && __builtin_fabs(x) < 1e9 && __builtin_fabs(y) < 1e9;
    x = small ? x : 0.0;
    y = small ? y : 0.0;
    double x0 = __builtin_floor(x), y0 = __builtin_floor(y);
    double fx = x - x0, fy = (y - y0) * one;
    int ix = (int)x0, iy = (int)y0;
    int iw = (int)width[0], ih = (int)height[0];
    int xs[2], ys[2];
    double inside_x[2], inside_y[2];
    #pragma unroll
    for (int k = 0; k < 2; ++k) {
        int xk = ix + k, yk = iy + k;
        xs[k] = WRAP == 0 ? xk & (iw - 1) : (xk < 0 ? 0 : (xk > iw - 1 ? iw - 1 : xk));
        ys[k] = WRAP == 0 ? yk & (ih - 1) : (yk < 0 ? 0 : (yk > ih - 1 ? ih - 1 : yk));
        inside_x[k] = WRAP == 1 && (xk < 0 || xk >= iw) ? 0.0 : 1.0;
        inside_y[k] = WRAP == 1 && (yk < 0 || yk >= ih) ? 0.0 : 1.0;
    }
    long level_base = base[0];
    double value[3];
    #pragma unroll
    for (int c = 0; c < 3; ++c) {
        double t00 = AT(texels, 3, level_base + (long)ys[0] * iw + xs[0], c) * (inside_x[0] * inside_y[0]);
        double t10 = AT(texels, 3, level_base + (long)ys[0] * iw + xs[1], c) * (inside_x[1] * inside_y[0]);
        double t01 = AT(texels, 3, level_base + (long)ys[1] * iw + xs[0], c) * (inside_x[0] * inside_y[1]);
        double t11 = AT(texels, 3, level_base + (long)ys[1] * iw + xs[1], c) * (inside_x[1] * inside_y[1]);
        double top = t00 * (1 - fx) + t10 * fx;
        double bottom = t01 * (1 - fx) + t11 * fx;
        value[c] = top * (1 - fy) + bottom * fy;
    }
    if (small) {
        AT(out, 3, i, 0) = red_scale * (float)value[0];
        AT(out, 3, i, 1) = green_scale * (float)value[1];
        AT(out, 3, i, 2) = blue_scale * (float)value[2];
    }
    if (i < count) pending[i] = !small;
}

__kernel void bilinear_small(SMALL_LOOKUP_PARAMETERS) {
    bilinear_level0(texels, base, width, height, levels, lookups, red_scale, green_scale, blue_scale, count,
                    unit, pending, out, level0_limit(levels));
}

__kernel void trilinear_small(SMALL_LOOKUP_PARAMETERS, const int blend_from) {
    bilinear_level0(texels, base, width, height, levels, lookups, red_scale, green_scale, blue_scale, count,
                    unit, pending, out,
                    blend_from ? level0_limit(levels) : 1.0 / (double)(1L << (levels - 1)) * (1 - 0x1p-40));
}

__kernel void point_small(SMALL_LOOKUP_PARAMETERS) {
    int i = get_global_id(0);
    int r = i < count ? i : count - 1;
    double one = (double)unit;
    double w = filter_width(AT(lookups, 6, r, 2), AT(lookups, 6, r, 3), AT(lookups, 6, r, 4), AT(lookups, 6, r, 5));
    double lw = (double)width[0], lh = (double)height[0];
    double x = AT(lookups, 6, r, 0) * lw - 0.5, y = (AT(lookups, 6, r, 1) * lh - 0.5) * one;
    int small = i < count && w < level0_limit(levels) && __builtin_fabs(x) < 1e9 && __builtin_fabs(y) < 1e9;
    /* round_half_away, written out with `one` on y's half (the SLP vectoriser would pair x's and y's) */
    x = small ? x : 0.0;
    y = small ? y : 0.0;
    double wx = __builtin_trunc(x), wy = __builtin_trunc(y) * one;
    int ix = (int)(wx + (__builtin_fabs(x - wx) >= 0.5 ? (x > 0 ? 1.0 : -1.0) : 0.0));
    int iy = (int)(wy + (__builtin_fabs(y - wy) * one >= 0.5 ? (y > 0 ? 1.0 : -1.0) : 0.0) * one);
    int iw = (int)width[0], ih = (int)height[0];
    int at_x = WRAP == 0 ? ix & (iw - 1) : (ix < 0 ? 0 : (ix > iw - 1 ? iw - 1 : ix));
    int at_y = WRAP == 0 ? iy & (ih - 1) : (iy < 0 ? 0 : (iy > ih - 1 ? ih - 1 : iy));
    double inside = WRAP == 1 && (ix < 0 || ix >= iw || iy < 0 || iy >= ih) ? 0.0 : 1.0;
    long texel_at = base[0] + (long)at_y * iw + at_x;
    if (small) {
        AT(out, 3, i, 0) = red_scale * (float)(AT(texels, 3, texel_at, 0) * inside);
        AT(out, 3, i, 1) = green_scale * (float)(AT(texels, 3, texel_at, 1) * inside);
        AT(out, 3, i, 2) = blue_scale * (float)(AT(texels, 3, texel_at, 2) * inside);
    }
    if (i < count) pending[i] = !small;
}

/* The continuous level of `lookup`'s filter width (MipMap._level_of). */
inline double width_level(__global const double *lookup, int levels) {
    double w = filter_width(lookup[2], lookup[3], lookup[4], lookup[5]);
    return (double)(levels - 1) + log2(__builtin_fmax(w, 1e-8));
}

/* The scalar kernels of the level filters (point, bilinear, trilinear: FILTER) share one body, each
 * kernel naming its filter, which the compiler folds: lookup rows[i] at its continuous level; at or
 * past the coarsest level, that level's one texel. */
#define LEVEL_POINT 0
#define LEVEL_BILINEAR 1
#define LEVEL_TRILINEAR 2
#define PENDING_LOOKUP_ARGUMENTS texels, base, width, height, levels, max_anisotropy, lut, lookups, rows, \
    red_scale, green_scale, blue_scale, count, out

inline void level_filter(PENDING_LOOKUP_PARAMETERS, const int filter, const int blend_from) {
    int i = get_global_id(0);
    if (i >= count) return;
    int r = rows[i];
    __global const double *lookup = lookups + 6 * (long)r;
    double level = width_level(lookup, levels);
    double s = lookup[0], t = lookup[1];
    double3 value;
    if (level >= levels - 1) {
        value = coarsest(texels, base, levels);
    } else if (filter == LEVEL_POINT) {
        int at = (int)__builtin_fmax(__builtin_floor(level), 0.0);
        int x = (int)round_half_away(s * width[at] - 0.5);
        int y = (int)round_half_away(t * height[at] - 0.5);
        value = texel(texels, base, width, height, at, x, y);
    } else if (filter == LEVEL_BILINEAR) {
        value = bilinear_at(texels, base, width, height, (int)__builtin_fmax(__builtin_floor(level), 0.0), s, t);
    } else {
        level = __builtin_fmax(level, 0.0);
        double lower = __builtin_floor(level);
        double delta = level - lower;
        int at = (int)lower;
        double3 below = bilinear_at(texels, base, width, height, at, s, t);
        value = at < blend_from ? below
                : below * (1 - delta) + bilinear_at(texels, base, width, height, min(at + 1, levels - 1), s, t) * delta;
    }
    store(out, r, convert_float3(value), red_scale, green_scale, blue_scale);
}

__kernel void point(PENDING_LOOKUP_PARAMETERS) {
    level_filter(PENDING_LOOKUP_ARGUMENTS, LEVEL_POINT, 0);
}

__kernel void bilinear(PENDING_LOOKUP_PARAMETERS) {
    level_filter(PENDING_LOOKUP_ARGUMENTS, LEVEL_BILINEAR, 0);
}

__kernel void trilinear(PENDING_LOOKUP_PARAMETERS, const int blend_from) {
    level_filter(PENDING_LOOKUP_ARGUMENTS, LEVEL_TRILINEAR, blend_from);
}
