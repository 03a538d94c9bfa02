/* Direct lighting of camera-ray hits: closest hit -> shadow rays and their contributions.
 *
 * OpenCL 1.2 C, float32. The numpy reference is realistic.renderer.integrator.DirectLighting (its
 * numpy path); the host is realistic/renderer/shade_kernel.py. One work item per camera ray i
 * (the n rays padded to the work-group size): the per-hit work (hit point, normals, albedo) once,
 * then light samples first_sample .. first_sample + LAUNCH_SAMPLES - 1 (a build option, so the
 * loop is unrolled and the body stays loop-free for the vectoriser).
 *
 * Per work item, as the numpy code does it, in the same float32 operations and order:
 *   - the hit point o + t d, the geometric normal (embree's Ng normalised, turned to face the ray),
 *     the shadow-ray origin offset along it by SHADOW_OFFSET (max |p_i| + 1e-2 extent);
 *   - the smooth shading normal of meshes with varying vertex normals: barycentric interpolation,
 *     the instance's normal matrix, normalised, turned to the geometric normal's side, kept only
 *     where it normalised to unit length (``DirectLighting._shading_normal``);
 *   - the albedo: the material's diffuse colour, times a grid or checker texture's colour at the
 *     interpolated uv (``realistic.scene.textures.evaluate``), or, for materials the kernel does
 *     not evaluate (image textures, filtered over pixel footprints), the host's albedo row (ewa.cl's kernels or numpy);
 *   - light sample k of light_samples: the pixel's scrambled Sobol' numbers at index
 *     sample * light_samples + k (realistic.core.rng.light_bits, bit for bit), the light picked by its float32 CDF rounded up (the same choice as numpy's
 *     searchsorted on the float64 CDF), a point on the disk (concentric map) or quad, and the
 *     area-sampling estimate rho / pi L cos_p cos_q / d^2 A / P;
 *   - for spectral rays (SPECTRAL), rho and L as spectra at the ray's wavelength
 *     (realistic.core.spectrum.spectral_value, in its order, with the rgb_basis row): the
 *     contribution is one spectral value, and the ray's film weight rgb_response and its basis row
 *     are written once per ray (`response`, `basis`: 3 floats each), for the host to weight the
 *     ray's sum as numpy does and to colour what the ray sees directly. Both come
 *     from the host's SPECTRUM table, rgb_basis and rgb_response's factors cie_rgb and
 *     wavelength_pdf at SPECTRUM_INTERVALS + 1 equally spaced wavelengths (the wavelength
 *     density's nodes among them), interpolated linearly: within 5e-6 of numpy's largest values.
 * Outputs, row o = (k - first_sample) * stride + i: shadow-ray origin and vector (to the light
 * point) (3 floats each), its length 1 - 1e-4 in units of that vector, or -1 for a dead sample (a
 * miss, an emitter, a light facing away, padding) so embree skips it, and the contribution (3
 * floats, or 1 for spectral rays; 0 when dead). The light's emitting side, the shading and the geometric normal decide
 * which samples live, as in numpy; embree's answer decides which contributions count (the host).
 *
 * Written for PoCL's work-group vectoriser as kernels/lens.cl is (see its header): no calls to
 * OpenCL builtin math functions (__builtin_sqrtf and __builtin_floorf are LLVM intrinsics), no
 * loops, no early exits, ternaries instead of branches, and every gather's index clamped into its
 * table so masked-off lanes read valid memory. FP_CONTRACT is off so that a * b + c rounds twice,
 * as numpy does: the hit point and the shadow-ray origin are then bit-identical to the numpy
 * path's (the light point differs from numpy's float64 concentric map by float32 rounding).
 * Every table read is a vector gather on the CPU, the kernel's main cost: the build options below
 * leave out the reads a scene does not need. Check: POCL_VECTORIZER_REMARKS=1 prints "vectorized
 * loop" for shade (tests/test_shade_kernel.py does), with POCL_KERNEL_CACHE=0 for a fresh build.
 */

#pragma OPENCL FP_CONTRACT OFF

#define PI_F 3.14159265358979f
#define GOLDEN 0x9E3779B9u
#define SHADOW_OFFSET 1e-4f
#define SHADOW_LENGTH 0.9999f
/* Build options (-D) the host sets per scene, so that the work the scene never needs costs no gathers:
 * PICK_BITS (0 .. 16, see pick_light), SMOOTH, TEXTURED, HOST_ALBEDO (0 or 1, see the kernel); and
 * per launch LAUNCH_SAMPLES, the light samples each work item makes (1 or more), and SPECTRAL (0 or
 * 1): whether the rays carry one wavelength each (see the kernel). */
#if !defined(PICK_BITS) || !defined(SMOOTH) || !defined(TEXTURED) || !defined(HOST_ALBEDO) \
    || !defined(LAUNCH_SAMPLES) || !defined(SPECTRAL)
#error "build with -DPICK_BITS=.. -DSMOOTH=.. -DTEXTURED=.. -DHOST_ALBEDO=.. -DLAUNCH_SAMPLES=.. -DSPECTRAL=.."
#endif
/* The tables' row widths and field offsets (GEOM_INT_*, GEOM_FLOAT_*, MATERIAL_*, LIGHT_*) and the
 * material kinds (KIND_*) are #defines the host prepends, generated from the tables it packs
 * (realistic/renderer/shade_kernel.py: GEOM_INTS, GEOM_FLOATS, MATERIALS, LIGHTS, KINDS). A grid's
 * colour a is its line, b its base, low and high line_width / 2 and 1 - line_width / 2; a checker's
 * a is even, b odd; KIND_HOST's albedo comes from the host's array. */

/* Component c of row i of a table of row width w, and field k of a table row. The offsets go
 * through the kernel argument `unit` (always 1), which LLVM cannot see through: with literal
 * offsets the x, y, z chains read neighbouring addresses, LLVM's SLP vectoriser packs them into
 * 2-wide vectors before PoCL's work-group vectoriser runs, and that one then gives up on the whole
 * kernel ("instruction return type cannot be vectorized" with POCL_VECTORIZER_REMARKS=1): on the
 * bench's dragon pass (131072 samples, one PoCL thread) 36 ms scalar against 7.5 ms vectorised. */
#define AT(a, w, i, c) ((a)[(w) * (i) + (c) * unit])
#define FIELD(row, k) ((row)[(k) * unit])

#include "common.cl"  /* expanded by the host (realistic.device.opencl.kernel_source) */

/* The light of sample value u: how many entries of the rounded-up CDF are <= u (numpy's
 * searchsorted side="right"), at most count - 1. A branch-free binary search written out in
 * PICK_BITS steps (a build option: the bit length of count - 1, so steps of 2^(PICK_BITS - 1) .. 1
 * reach every light; 0 for a single light, at most 16). */
#define PICK_STEP(step) \
    probe = found + (step); \
    at = (probe < count ? probe : count) - 1; \
    found = ((probe <= count) & (FIELD(cdf, at) <= u)) ? probe : found;
inline __attribute__((always_inline)) int pick_light(__global const float *cdf, int count, float u, uint unit) {
    int found = 0, probe, at;
#if PICK_BITS > 16
#error "the light search is written out for at most 65535 lights"
#endif
#if PICK_BITS >= 16
    PICK_STEP(32768)
#endif
#if PICK_BITS >= 15
    PICK_STEP(16384)
#endif
#if PICK_BITS >= 14
    PICK_STEP(8192)
#endif
#if PICK_BITS >= 13
    PICK_STEP(4096)
#endif
#if PICK_BITS >= 12
    PICK_STEP(2048)
#endif
#if PICK_BITS >= 11
    PICK_STEP(1024)
#endif
#if PICK_BITS >= 10
    PICK_STEP(512)
#endif
#if PICK_BITS >= 9
    PICK_STEP(256)
#endif
#if PICK_BITS >= 8
    PICK_STEP(128)
#endif
#if PICK_BITS >= 7
    PICK_STEP(64)
#endif
#if PICK_BITS >= 6
    PICK_STEP(32)
#endif
#if PICK_BITS >= 5
    PICK_STEP(16)
#endif
#if PICK_BITS >= 4
    PICK_STEP(8)
#endif
#if PICK_BITS >= 3
    PICK_STEP(4)
#endif
#if PICK_BITS >= 2
    PICK_STEP(2)
#endif
#if PICK_BITS >= 1
    PICK_STEP(1)
#endif
    return found < count - 1 ? found : count - 1;
}

/* Light sample k of light_samples (per camera sample) of a pixel's sample: the pick u0 and the
 * light point u1, u2, as realistic.core.rng.light_bits computes them (bit for bit): the index
 * shuffled per pixel, Sobol's first two dimensions Owen-scrambled per pixel for the point, a
 * scrambled van der Corput number of the index shuffled by its own key for the pick. The keys are
 * hash_key(pixel, 0xFFFFFFFF, d, seed) at d = 16 .. 20 (rng.LIGHT_KEYS). u2's bits are multiplied
 * by `unit` (1; see AT): the u1 and u2 chains are otherwise isomorphic, LLVM's SLP vectoriser packs
 * them into 2-wide vectors, and PoCL's work-group vectoriser then gives up on the kernel. */
inline __attribute__((always_inline)) void light_numbers(uint pixel, uint sample, uint k, uint light_samples, uint seed,
                                                         uint unit, float *u0, float *u1, float *u2) {
    uint h = hash32(hash32(hash32(seed + GOLDEN) ^ pixel) ^ 0xFFFFFFFFu);
    uint index = sample * light_samples + k;
    uint reversed = reverse_bits(index);
    uint shuffled = reverse_bits(owen_scramble_digits(reversed, hash32(h ^ 16u)));
    *u1 = to_unit(reverse_bits(owen_scramble_digits(shuffled, hash32(h ^ 17u))));
    *u2 = to_unit(reverse_bits(owen_scramble_digits(sobol1_digits(shuffled), hash32(h ^ 18u))) * unit);
    uint picked = reverse_bits(owen_scramble_digits(reversed, hash32(h ^ 19u)));
    *u0 = to_unit(reverse_bits(owen_scramble_digits(picked, hash32(h ^ 20u))));
}

/* ------------------------------------------------------------------ kernels */

__kernel void shade(uint n, uint stride, uint first_sample, uint light_samples, uint seed, uint unit, int instance_count, float offset_base, int light_count,
                    __global const float *origin, __global const float *direction, __global const float *tfar,
                    __global const float *hit_u, __global const float *hit_v, __global const int *prim,
                    __global const int *geom, __global const float *ng_in, __global const uint *pixel,
                    __global const uint *sample, __global const float *albedo_in, __global const float *wavelength,
                    __global const float *spectrum,
                    __global const int *faces, __global const float *normals, __global const float *uvs,
                    __global const int *geom_ints, __global const float *geom_floats,
                    __global const float *materials, __global const float *lights, __global const float *cdf,
                    __global float *shadow_origin, __global float *shadow_vector, __global float *shadow_length,
                    __global float *contribution, __global float *response, __global float *basis) {
    uint i = get_global_id(0);
    uint r = i < n ? i : n - 1;
    int g = geom[r];
    int surface = (i < n) & (g >= 0) & (g < instance_count);
    int gs = surface ? g : 0;

    /* hit point and geometric normal facing the ray */
    float dx = AT(direction, 3, r, 0), dy = AT(direction, 3, r, 1), dz = AT(direction, 3, r, 2);
    float t = surface ? tfar[r] : 0.0f;
    float px = AT(origin, 3, r, 0) + t * dx;
    float py = AT(origin, 3, r, 1) + t * dy;
    float pz = AT(origin, 3, r, 2) + t * dz;
    float gx = AT(ng_in, 3, r, 0), gy = AT(ng_in, 3, r, 1), gz = AT(ng_in, 3, r, 2);
    float glen = __builtin_sqrtf(gx * gx + gy * gy + gz * gz);
    int gok = glen > 0.0f;
    gx = gok ? gx / glen : 0.0f;
    gy = gok ? gy / glen : 0.0f;
    gz = gok ? gz / glen : 0.0f;
    float side = gx * dx + gy * dy + gz * dz > 0.0f ? -1.0f : 1.0f;
    gx *= side;
    gy *= side;
    gz *= side;
    float ax = px < 0.0f ? -px : px, ay = py < 0.0f ? -py : py, az = pz < 0.0f ? -pz : pz;
    float magnitude = ax > ay ? ax : ay;
    magnitude = magnitude > az ? magnitude : az;
    float eps = SHADOW_OFFSET * (magnitude + offset_base);
    float sx = px + gx * eps, sy = py + gy * eps, sz = pz + gz * eps;

    /* the triangle and its barycentrics */
    int face = geom_ints[GEOM_INT_WIDTH * gs + GEOM_INT_FACE_OFFSET] + (surface ? prim[r] : 0);
    int material = geom_ints[GEOM_INT_WIDTH * gs + GEOM_INT_MATERIAL];
    int i0 = AT(faces, 3, face, 0), i1 = AT(faces, 3, face, 1), i2 = AT(faces, 3, face, 2);
    float b1 = hit_u[r], b2 = hit_v[r];
    float b0 = 1.0f - b1 - b2;

    /* shading normal (SMOOTH: whether any instance has varying vertex normals) */
#if SMOOTH
    int smooth = geom_ints[GEOM_INT_WIDTH * gs + GEOM_INT_SMOOTH];
    float nx = AT(normals, 3, i0, 0) * b0 + AT(normals, 3, i1, 0) * b1 + AT(normals, 3, i2, 0) * b2;
    float ny = AT(normals, 3, i0, 1) * b0 + AT(normals, 3, i1, 1) * b1 + AT(normals, 3, i2, 1) * b2;
    float nz = AT(normals, 3, i0, 2) * b0 + AT(normals, 3, i1, 2) * b1 + AT(normals, 3, i2, 2) * b2;
    __global const float *m = geom_floats + GEOM_FLOAT_WIDTH * gs;
    /* the normal matrix, row major, at NM (its offsets fold to constants, as literal ones did) */
#define NM GEOM_FLOAT_NORMAL_MATRIX
    float wx = FIELD(m, NM) * nx + FIELD(m, NM + 1) * ny + FIELD(m, NM + 2) * nz;
    float wy = FIELD(m, NM + 3) * nx + FIELD(m, NM + 4) * ny + FIELD(m, NM + 5) * nz;
    float wz = FIELD(m, NM + 6) * nx + FIELD(m, NM + 7) * ny + FIELD(m, NM + 8) * nz;
#undef NM
    float wlen = __builtin_sqrtf(wx * wx + wy * wy + wz * wz);
    int wok = wlen > 0.0f;
    wx = wok ? wx / wlen : 0.0f;
    wy = wok ? wy / wlen : 0.0f;
    wz = wok ? wz / wlen : 0.0f;
    float wside = wx * gx + wy * gy + wz * gz < 0.0f ? -1.0f : 1.0f;
    wx *= wside;
    wy *= wside;
    wz *= wside;
    int use_smooth = smooth & (wx * wx + wy * wy + wz * wz > 0.5f);
    float shx = use_smooth ? wx : gx, shy = use_smooth ? wy : gy, shz = use_smooth ? wz : gz;
#else
    float shx = gx, shy = gy, shz = gz;
#endif

    /* albedo (TEXTURED: whether any material has a grid or checker texture; HOST_ALBEDO: whether
     * any material's albedo comes from the host) */
    __global const float *mat = materials + MATERIAL_WIDTH * material;
    float rho_r = FIELD(mat, MATERIAL_DIFFUSE), rho_g = FIELD(mat, MATERIAL_DIFFUSE + 1);
    float rho_b = FIELD(mat, MATERIAL_DIFFUSE + 2);
#if TEXTURED || HOST_ALBEDO
    int kind = (int)FIELD(mat, MATERIAL_KIND);
#endif
#if TEXTURED
    float tu = AT(uvs, 2, i0, 0) * b0 + AT(uvs, 2, i1, 0) * b1 + AT(uvs, 2, i2, 0) * b2;
    float tv = AT(uvs, 2, i0, 1) * b0 + AT(uvs, 2, i1, 1) * b1 + AT(uvs, 2, i2, 1) * b2;
    float cu = tu * FIELD(mat, MATERIAL_CELLS), cv = tv * FIELD(mat, MATERIAL_CELLS);
    float fu_floor = __builtin_floorf(cu), fv_floor = __builtin_floorf(cv);
    float fu = cu - fu_floor, fv = cv - fv_floor;
    int on_line = (fu < FIELD(mat, MATERIAL_LOW)) | (fu > FIELD(mat, MATERIAL_HIGH))
                  | (fv < FIELD(mat, MATERIAL_LOW)) | (fv > FIELD(mat, MATERIAL_HIGH));
    float parity_sum = fu_floor + fv_floor;
    int odd = parity_sum - 2.0f * __builtin_floorf(parity_sum * 0.5f) != 0.0f;
    int use_b = kind == KIND_GRID ? !on_line : odd;
    float tex_r = use_b ? FIELD(mat, MATERIAL_COLOUR_B) : FIELD(mat, MATERIAL_COLOUR_A);
    float tex_g = use_b ? FIELD(mat, MATERIAL_COLOUR_B + 1) : FIELD(mat, MATERIAL_COLOUR_A + 1);
    float tex_b = use_b ? FIELD(mat, MATERIAL_COLOUR_B + 2) : FIELD(mat, MATERIAL_COLOUR_A + 2);
    int textured = kind == KIND_GRID || kind == KIND_CHECKER;
    rho_r = textured ? rho_r * tex_r : rho_r;
    rho_g = textured ? rho_g * tex_g : rho_g;
    rho_b = textured ? rho_b * tex_b : rho_b;
#endif
#if HOST_ALBEDO
    uint host_row = kind == KIND_HOST ? r : 0u;
    rho_r = kind == KIND_HOST ? AT(albedo_in, 3, host_row, 0) : rho_r;
    rho_g = kind == KIND_HOST ? AT(albedo_in, 3, host_row, 1) : rho_g;
    rho_b = kind == KIND_HOST ? AT(albedo_in, 3, host_row, 2) : rho_b;
#endif

    /* SPECTRAL: every ray has one wavelength; its rgb_basis row (b_*) and rgb_response (f_*, cie_rgb
     * over the density) come from the SPECTRUM table's rows either side, interpolated linearly. The albedo becomes the
     * spectrum's value there, as spectral_value computes it (r b_R + g b_G + b b_B, in that order),
     * and so does each light's radiance below. */
#if SPECTRAL
    float st = (wavelength[r] - SPECTRUM_MIN_NM) * SPECTRUM_PER_NM;
    st = st > 0.0f ? st : 0.0f;
    int si = (int)__builtin_floorf(st);
    si = si < SPECTRUM_INTERVALS - 1 ? si : SPECTRUM_INTERVALS - 1;
    float sw = st - (float)si;
    __global const float *s0 = spectrum + SPECTRUM_WIDTH * si;
    __global const float *s1 = s0 + SPECTRUM_WIDTH;
#define LERP(k) (FIELD(s0, k) + sw * (FIELD(s1, k) - FIELD(s0, k)))
    float b_r = LERP(SPECTRUM_BASIS), b_g = LERP(SPECTRUM_BASIS + 1), b_b = LERP(SPECTRUM_BASIS + 2);
    float pdf = LERP(SPECTRUM_PDF);
    float f_r = LERP(SPECTRUM_CIE) / pdf, f_g = LERP(SPECTRUM_CIE + 1) / pdf, f_b = LERP(SPECTRUM_CIE + 2) / pdf;
#undef LERP
    float rho_s = rho_r * b_r + rho_g * b_g + rho_b * b_b;
    /* the film weight, once per ray: weighting each light sample's value by it in the loop below
     * gives LLVM's SLP vectoriser a pattern it packs, and PoCL's then gives up on the kernel */
    AT(response, 3, i, 0) = f_r;
    AT(response, 3, i, 1) = f_g;
    AT(response, 3, i, 2) = f_b;
    AT(basis, 3, i, 0) = b_r;
    AT(basis, 3, i, 1) = b_g;
    AT(basis, 3, i, 2) = b_b;
#endif

    /* the launch's light samples, unrolled */
#pragma unroll
    for (uint q = 0; q < LAUNCH_SAMPLES; ++q) {
        /* light sample k, row o */
        uint k = first_sample + q;
        uint o = q * stride + i;
        float u_pick, u1, u2;
        light_numbers(pixel[r], sample[r], k, light_samples, seed, unit, &u_pick, &u1, &u2);
        int j = pick_light(cdf, light_count, u_pick, unit);
        __global const float *light = lights + LIGHT_WIDTH * j;
        float disk_x, disk_y;
        concentric_disk(u1, u2, &disk_x, &disk_y);
        int disk = FIELD(light, LIGHT_DISK) != 0.0f;
        float lx = disk ? disk_x : 2.0f * u1 - 1.0f;
        float ly = disk ? disk_y : 2.0f * u2 - 1.0f;
        float qx = FIELD(light, LIGHT_CENTRE) + FIELD(light, LIGHT_A) * lx + FIELD(light, LIGHT_B) * ly;
        float qy = FIELD(light, LIGHT_CENTRE + 1) + FIELD(light, LIGHT_A + 1) * lx + FIELD(light, LIGHT_B + 1) * ly;
        float qz = FIELD(light, LIGHT_CENTRE + 2) + FIELD(light, LIGHT_A + 2) * lx + FIELD(light, LIGHT_B + 2) * ly;
        float tx = qx - px, ty = qy - py, tz = qz - pz;
        float dist2 = tx * tx + ty * ty + tz * tz;
        float dist = __builtin_sqrtf(dist2);
        float ix = tx / dist, iy = ty / dist, iz = tz / dist;
        float cos_p = ix * shx + iy * shy + iz * shz;
        float cos_q = -(ix * FIELD(light, LIGHT_NORMAL) + iy * FIELD(light, LIGHT_NORMAL + 1)
                        + iz * FIELD(light, LIGHT_NORMAL + 2));
        cos_q = FIELD(light, LIGHT_TWO_SIDED) != 0.0f && cos_q < 0.0f ? -cos_q : cos_q;
        int live = surface & (cos_p > 0.0f) & (cos_q > 0.0f) & (ix * gx + iy * gy + iz * gz > 0.0f) & (dist2 > 0.0f);
        float scale = cos_p * cos_q / dist2 * FIELD(light, LIGHT_SCALE);

        AT(shadow_origin, 3, o, 0) = live ? sx : 0.0f;
        AT(shadow_origin, 3, o, 1) = live ? sy : 0.0f;
        AT(shadow_origin, 3, o, 2) = live ? sz : 0.0f;
        AT(shadow_vector, 3, o, 0) = live ? qx - sx : 0.0f;
        AT(shadow_vector, 3, o, 1) = live ? qy - sy : 0.0f;
        AT(shadow_vector, 3, o, 2) = live ? qz - sz : 0.0f;
        shadow_length[o] = live ? SHADOW_LENGTH : -1.0f;
#if SPECTRAL
        float emitted = FIELD(light, LIGHT_RADIANCE) * b_r + FIELD(light, LIGHT_RADIANCE + 1) * b_g
                        + FIELD(light, LIGHT_RADIANCE + 2) * b_b;
        contribution[o] = live ? rho_s * emitted * scale : 0.0f;
#else
        AT(contribution, 3, o, 0) = live ? rho_r * FIELD(light, LIGHT_RADIANCE) * scale : 0.0f;
        AT(contribution, 3, o, 1) = live ? rho_g * FIELD(light, LIGHT_RADIANCE + 1) * scale : 0.0f;
        AT(contribution, 3, o, 2) = live ? rho_b * FIELD(light, LIGHT_RADIANCE + 2) * scale : 0.0f;
#endif
    }
}

/* Debug: the light-sample random numbers of each ray, rows u_pick, u1, u2 per light sample
 * (3 * light_samples rows of `stride`), so the tests can check them against realistic.core.rng. */
__kernel void light_uniforms(uint n, uint stride, uint seed, __global const uint *pixel, __global const uint *sample,
                             __global float *out) {
    uint i = get_global_id(0);
    uint k = get_global_id(1);
    uint r = i < n ? i : n - 1;
    float u0, u1, u2;
    light_numbers(pixel[r], sample[r], k, get_global_size(1), seed, 1u, &u0, &u1, &u2);
    out[(3 * k) * stride + i] = u0;
    out[(3 * k + 1) * stride + i] = u1;
    out[(3 * k + 2) * stride + i] = u2;
}

/* Debug: the concentric map of (u1, u2) pairs, for the tests against realistic.core.warp. */
__kernel void disk_points(__global const float *u1, __global const float *u2, __global float *x, __global float *y) {
    uint i = get_global_id(0);
    float px, py;
    concentric_disk(u1[i], u2[i], &px, &py);
    x[i] = px;
    y[i] = py;
}
