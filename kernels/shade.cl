/* Direct lighting of camera-ray hits: closest hit -> shadow rays and their contributions.
 *
 * OpenCL 1.2 C, float32. The numpy reference is realistic.renderer.integrator.DirectLighting (its
 * numpy path); the host is realistic/renderer/shade_kernel.py. One work item per camera ray i
 * (the n rays padded to whole groups), in work groups of LANES (16: a group of the outputs' lanes,
 * see OUT): the per-hit work (hit point, normals, albedo) once,
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
 *     are written once per ray (`response`, `basis`: 3 rows of the launch's rays each, value c of
 *     ray i at c * get_global_size(0) + i, which the host reads in place as (rays, 3)),
 *     for the host to weight the ray's sum as numpy does and to colour what the ray sees directly. Both come
 *     from the host's SPECTRUM table, rgb_basis and rgb_response's factors cie_rgb and
 *     wavelength_pdf at SPECTRUM_INTERVALS + 1 equally spaced wavelengths (the wavelength
 *     density's nodes among them), interpolated linearly: within 5e-6 of numpy's largest values.
 *   - with MEASURED, at hits of a measured material: f(wo, wi) from its table in rho / pi's place,
 *     and a BSDF sample paired with each light sample (see measured_f and the loop);
 * Outputs in lanes (LANE_AT, from realistic.scene.packet_loop's LANE_DEFINES: in groups of 16 work
 * items, value c of each one's k-th shadow ray side by side, so that neighbouring work items'
 * values are adjacent and each store is a vector store, not a scatter; the host traces each hit
 * point's shadow rays together all the same), k = q, the launch's q-th light sample (MEASURED: k =
 * 2 q, and the BSDF sample's k = 2 q + 1, dead where the material is not measured): shadow-ray
 * origin and vector (to the light point or, for a BSDF sample, the point it meets on the light)
 * (3 floats each), its length 1 - 1e-4 in units of that vector, or -1 for a dead sample (a
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
 * Every table read is a vector gather on the CPU (the outputs' lanes make every store a vector
 * store); with the light-sample numbers (light_numbers) these are the kernel's main costs: the build
 * options below leave out the reads a scene does not need. Check: POCL_VECTORIZER_REMARKS=1 prints "vectorized
 * loop" for shade (tests/test_shade_kernel.py does), with POCL_KERNEL_CACHE=0 for a fresh build.
 */

#pragma OPENCL FP_CONTRACT OFF

#define PI_F 3.14159265358979f
#define GOLDEN 0x9E3779B9u
#define SHADOW_OFFSET 1e-4f
/* SHADOW_LENGTH comes with the host's header (light_sampler.SHADOW_DEFINES). */
/* Build options (-D) the host sets per scene, so that the work the scene never needs costs no gathers:
 * PICK_BITS (0 .. 16, see pick_light), SMOOTH, TEXTURED, HOST_ALBEDO, MEASURED (0 or 1, see the
 * kernel); and per launch LAUNCH_SAMPLES, the light samples each work item makes (1 or more), and
 * SPECTRAL (0 or 1): whether the rays carry one wavelength each (see the kernel). */
#if !defined(PICK_BITS) || !defined(SMOOTH) || !defined(TEXTURED) || !defined(HOST_ALBEDO) \
    || !defined(LAUNCH_SAMPLES) || !defined(SPECTRAL) || !defined(MEASURED)
#error "build with -DPICK_BITS=.. -DSMOOTH=.. -DTEXTURED=.. -DHOST_ALBEDO=.. -DMEASURED=.. -DLAUNCH_SAMPLES=.. -DSPECTRAL=.."
#endif
#if MEASURED && SPECTRAL
#error "measured materials shade RGB rays only"
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
/* Value c of the work item's shadow ray o of an output with `width` values per ray, of PER a work
 * item: adjacent across work items, so that the vectoriser stores a vector of them at once (rows of
 * `width` adjacent values were scatters, and the vectoriser took 4 work items at a time rather
 * than 8). A work group is a group of lanes (the kernel requires LANES work items a group), so
 * the address is the group id's plus the local id: the global id's i / 16 and i % 16 hid that
 * from the vectoriser, which then scattered. */
#define PER ((1 + MEASURED) * LAUNCH_SAMPLES)
#define OUT(name, width, o, c) LANE_AT(name, PER, width, o, c, group, lane)
/* shadow ray o: from the offset point (sx, sy, sz) to (x, y, z), or a dead row (length -1) */
#define WRITE_SHADOW_RAY(o, live, x, y, z) do { \
        OUT(shadow_origin, 3, o, 0) = (live) ? sx : 0.0f; \
        OUT(shadow_origin, 3, o, 1) = (live) ? sy : 0.0f; \
        OUT(shadow_origin, 3, o, 2) = (live) ? sz : 0.0f; \
        OUT(shadow_vector, 3, o, 0) = (live) ? (x) - sx : 0.0f; \
        OUT(shadow_vector, 3, o, 1) = (live) ? (y) - sy : 0.0f; \
        OUT(shadow_vector, 3, o, 2) = (live) ? (z) - sz : 0.0f; \
        OUT(shadow_length, 1, o, 0) = (live) ? SHADOW_LENGTH : -1.0f; \
    } while (0)

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

#if MEASURED
/* MEASURED: materials of kind KIND_MEASURED (pbrt-v2's irregular isotropic measured BRDFs) are
 * shaded by multiple importance sampling as pbrt-v2's directlighting integrator does for a
 * non-specular BSDF (src/core/integrator.cpp, EstimateDirect): each light sample is paired with a
 * cosine-weighted BSDF sample (BxDF::Sample_f's default, src/core/reflection.cpp), both weighted by
 * the power heuristic. f(wo, wi) is the trilinear lookup of realistic.renderer.bsdf.measured's
 * table (table_lookup: BRDFRemap, then the eight nodes of the cell) in bfloat16 (a float's upper
 * half), the tables of every file one after another in `measured_tables`, TABLE_NODES^3 records
 * each: record (x, y, z) holds the RGB of nodes (x, y, z) and (x + 1, y, z), six bfloat16 values
 * in three uints, so that a lookup reads two pairs of adjacent records (z and z + 1), two or three
 * cache lines, where four nodes' pairs of floats took four to six (the table is larger than the
 * caches, and its misses are most of a lookup's cost; the host packs it: shade_kernel.table_records). */

/* atan2(y, x) for y >= 0, in [0, pi]: an odd polynomial of degree 15 for atan on [0, 1] (a
 * least-squares fit, within 1.5e-7 of atan in float32), folded by pi/2 - and pi -; 0 at (0, 0).
 * A builtin atan2 would be a call, which PoCL's vectoriser does not widen. */
inline __attribute__((always_inline)) float half_turn_atan2(float y, float x) {
    float ax = x < 0.0f ? -x : x;
    float hi = ax > y ? ax : y, lo = ax > y ? y : ax;
    float a = hi > 0.0f ? lo / hi : 0.0f;
    float a2 = a * a;
    float p = -0.004073309246450663f;
    p = p * a2 + 0.021946610882878304f;
    p = p * a2 - 0.056063175201416016f;
    p = p * a2 + 0.09656256437301636f;
    p = p * a2 - 0.13915802538394928f;
    p = p * a2 + 0.19948509335517883f;
    p = p * a2 - 0.3333010673522949f;
    p = p * a2 + 0.999999463558197f;
    float angle = a * p;
    angle = y > ax ? 0.5f * PI_F - angle : angle;
    return x < 0.0f ? PI_F - angle : angle;
}

/* A bfloat16 value (the high or low 16 bits of `word`: a float's upper half) as a float. */
#define HALF(word, high) as_float((high) ? (word) & 0xFFFF0000u : (word) << 16)

/* The table's RGB for directions wo and wi about the shading normal n, as table_lookup computes
 * it in float64 from local directions, given cos_o = wo.n, cos_i = wi.n, cross = n.(wo x wi) and
 * along = wo.wi - cos_o cos_i (the sine and cosine of the azimuth between them, times sin_o sin_i:
 * no local frame is needed). 0 unless both are on one side; BRDFRemap (sin_i sin_o, delta phi / pi,
 * cos_i cos_o) scaled to the grid, clamped (so every gather stays inside the table), trilinear over
 * the cell. `base`: the table's first node; `use`: whether the value is used (else it is garbage). */
inline __attribute__((always_inline)) void measured_f(__global const uint *table, int base, int use, float oz,
                                                      float iz, float cross, float along, uint unit,
                                                      float *fr, float *fg, float *fb) {
    /* The three coordinates are computed by different instruction sequences on purpose (as
     * concentric_disk's |a| and |b| in common.cl): isomorphic chains would be packed into 2-wide
     * vectors by LLVM's SLP vectoriser, and PoCL's work-group vectoriser then gives up on the kernel. */
    const float last = (float)(TABLE_NODES - 1);
    float so2 = 1.0f - oz * oz, si2 = (1.0f - iz) * (1.0f + iz);
    float sin_o = __builtin_sqrtf(so2 > 0.0f ? so2 : 0.0f), sin_i = __builtin_sqrtf(__builtin_fmaxf(si2, 0.0f));
    float dphi = half_turn_atan2(cross < 0.0f ? -cross : cross, along);
    float vx = sin_i * sin_o * last, vy = dphi * (last / PI_F), vz = iz * oz * last;
    float gx = vx > 0.0f ? (vx < last ? vx : last) : 0.0f;  /* NaN to 0 */
    float gy = __builtin_fminf(__builtin_fmaxf(vy, 0.0f), last);  /* fmax(NaN, 0) is 0 */
    float gz = vz < last ? vz : last;
    gz = gz > 0.0f ? gz : 0.0f;
    /* a lane whose value is unused reads the table's first cell, which stays in the cache: the
     * lookups are scattered over a table larger than the caches, and their misses are most of its cost */
    int cx = use ? (int)gx : 0, cy = use ? (int)gy : 0, cz = use ? (int)gz : 0;
    cx = cx < TABLE_NODES - 2 ? cx : TABLE_NODES - 2;
    cy -= cy == TABLE_NODES - 1;
    cz = cz > TABLE_NODES - 2 ? TABLE_NODES - 2 : cz;
    float wx = gx - (float)cx, wy = gy - (float)cy, wz = gz - (float)cz;
    /* the four records (x, y..y+1, z..z+1) of the cell, each the RGB at x and at x + 1 */
    int r00 = base + (cx * TABLE_NODES + cy) * TABLE_NODES + cz;
    int r10 = r00 + TABLE_NODES, r01 = r00 + 1, r11 = r10 + 1;
    /* Trilinear interpolation: the corners' weights, then per channel a serial sum of weighted
     * nodes (no binary operation there has two operands of the same shape, which LLVM's SLP
     * vectoriser would pack into a 2-wide vector, and PoCL's work-group vectoriser then gives up on
     * the kernel: see AT). */
    float vx0 = 1.0f - wx, vy0 = 1.0f - wy, vz0 = 1.0f - wz;
    /* (1 - wy)(1 - wz), wy (1 - wz), (1 - wy) wz and wy wz, by differing operations (see above) */
    float w00 = vy0 * vz0, w10 = vz0 - w00, w01 = vy0 - w00, w11 = wy * wz;
    /* a record's uints: (r, g) at x, (b at x, r at x + 1), (g, b) at x + 1, low half first */
#define WORD(record, k) AT(table, 3, record, k)
#define CHANNEL(lo_word, lo_high, hi_word, hi_high) \
    ((((((((HALF(WORD(r00, lo_word), lo_high) * vx0) * w00 + HALF(WORD(r00, hi_word), hi_high) * wx * w00) \
          + HALF(WORD(r10, lo_word), lo_high) * vx0 * w10) + HALF(WORD(r10, hi_word), hi_high) * wx * w10) \
        + HALF(WORD(r01, lo_word), lo_high) * vx0 * w01) + HALF(WORD(r01, hi_word), hi_high) * wx * w01) \
      + HALF(WORD(r11, lo_word), lo_high) * vx0 * w11) + HALF(WORD(r11, hi_word), hi_high) * wx * w11)
    float red = CHANNEL(0, 0, 1, 1), green = CHANNEL(0, 1, 2, 0), blue = CHANNEL(1, 0, 2, 1);
#undef CHANNEL
#undef WORD
    int same = oz * iz > 0.0f;
    *fr = same ? red : 0.0f;
    *fg = same ? green : 0.0f;
    *fb = same ? blue : 0.0f;
}

/* The BSDF sample's numbers paired with light sample k (realistic.core.rng.light_bsdf_uniforms,
 * bit for bit): the light point's shuffled index, its two Sobol' dimensions scrambled with the keys
 * hash_key(pixel, 0xFFFFFFFF, d, seed) at d = 21, 22 (rng.BSDF_KEYS). */
inline __attribute__((always_inline)) void bsdf_numbers(uint pixel, uint sample, uint k, uint light_samples, uint seed,
                                                        uint unit, float *v1, float *v2) {
    uint h = hash32(hash32(hash32(seed + GOLDEN) ^ pixel) ^ 0xFFFFFFFFu);
    uint index = sample * light_samples + k;
    uint shuffled = reverse_bits(owen_scramble_digits(reverse_bits(index), hash32(h ^ 16u)));
    *v1 = to_unit(reverse_bits(owen_scramble_digits(shuffled, hash32(h ^ 21u))));
    *v2 = to_unit(reverse_bits(owen_scramble_digits(sobol1_digits(shuffled), hash32(h ^ 22u))) * unit);
}
#endif

/* ------------------------------------------------------------------ kernels */

__kernel __attribute__((reqd_work_group_size(LANES, 1, 1))) void shade(uint n, uint first_sample, uint light_samples, uint seed, uint unit, int instance_count, float offset_base, int light_count,
                    __global const float *origin, __global const float *direction, __global const float *tfar,
                    __global const float *hit_u, __global const float *hit_v, __global const int *prim,
                    __global const int *geom, __global const float *ng_in, __global const uint *pixel,
                    __global const uint *sample, __global const float *albedo_in, __global const float *wavelength,
                    __global const float *spectrum,
                    __global const int *faces, __global const float *normals, __global const float *uvs,
                    __global const int *geom_ints, __global const float *geom_floats,
                    __global const float *materials, __global const float *lights, __global const float *cdf,
                    __global const uint *measured_tables,
                    __global float *shadow_origin, __global float *shadow_vector, __global float *shadow_length,
                    __global float *contribution, __global float *response, __global float *basis) {
    uint i = get_global_id(0);
    uint group = get_group_id(0), lane = get_local_id(0);
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
#if TEXTURED || HOST_ALBEDO || MEASURED
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
    uint rays = get_global_size(0);
    response[i] = f_r;
    response[rays + i] = f_g;
    response[2 * rays + i] = f_b;
    basis[i] = b_r;
    basis[rays + i] = b_g;
    basis[2 * rays + i] = b_b;
#endif

#if MEASURED
    /* a measured material: its table's first node, wo = -d, cos_o and n x wo (for the azimuths) */
    int measured = surface & (kind == KIND_MEASURED);
    int table_base = (int)FIELD(mat, MATERIAL_TABLE) * (TABLE_NODES * TABLE_NODES * TABLE_NODES);
    float cos_o = -(dx * shx + dy * shy + dz * shz);
    float mx = shz * dy - shy * dz, my = shx * dz - shz * dx, mz = shy * dx - shx * dy;
#endif

    /* the launch's light samples, unrolled */
#pragma unroll
    for (uint q = 0; q < LAUNCH_SAMPLES; ++q) {
        /* light sample k, the work item's shadow ray o (MEASURED: its BSDF sample's o + 1) */
        uint k = first_sample + q;
        uint o = (1 + MEASURED) * q;
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
#if MEASURED
        /* a measured hit's light sample: f(wo, wi) pi in rho's place (the scale holds 1 / pi),
         * times the power heuristic's weight against the cosine-sampled BSDF's density cos_p / pi:
         * 1 / (1 + (p_bsdf / p_light)^2), p_light = d^2 / (cos_q A) */
        float area = FIELD(light, LIGHT_AREA);
        float mf_r, mf_g, mf_b;
        measured_f(measured_tables, table_base, live & measured, cos_o, cos_p, ix * mx + iy * my + iz * mz,
                   -(ix * dx + iy * dy + iz * dz) - cos_o * cos_p, unit, &mf_r, &mf_g, &mf_b);
        float ratio_l = cos_p * cos_q * area / (PI_F * dist2);
        float weight_l = PI_F / (1.0f + ratio_l * ratio_l);
        float lr = measured ? mf_r * weight_l : rho_r;
        float lg = measured ? mf_g * weight_l : rho_g;
        float lb = measured ? mf_b * weight_l : rho_b;
#else
        float lr = rho_r, lg = rho_g, lb = rho_b;
#endif

        WRITE_SHADOW_RAY(o, live, qx, qy, qz);
#if SPECTRAL
        float emitted = FIELD(light, LIGHT_RADIANCE) * b_r + FIELD(light, LIGHT_RADIANCE + 1) * b_g
                        + FIELD(light, LIGHT_RADIANCE + 2) * b_b;
        OUT(contribution, 1, o, 0) = live ? rho_s * emitted * scale : 0.0f;
#else
        OUT(contribution, 3, o, 0) = live ? lr * FIELD(light, LIGHT_RADIANCE) * scale : 0.0f;
        OUT(contribution, 3, o, 1) = live ? lg * FIELD(light, LIGHT_RADIANCE + 1) * scale : 0.0f;
        OUT(contribution, 3, o, 2) = live ? lb * FIELD(light, LIGHT_RADIANCE + 2) * scale : 0.0f;
#endif
#if MEASURED
        /* the BSDF sample (pbrt-v2 EstimateDirect's second half, for the light picked above): a
         * cosine-weighted direction about the shading normal from the sample's own numbers, n plus
         * a uniform point on the unit sphere (the concentric disk mapped by area: z = 1 - 2 r^2,
         * (x, y) scaled by 2 sqrt(1 - r^2)), normalised, which needs no frame about n; it
         * counts where it meets that light's disk or parallelogram from its emitting side, weighted
         * by the power heuristic against the light's density there, over the pick's probability
         * (1 / P = scale pi / A). Its shadow ray goes to the point met. */
        float v1, v2;
        bsdf_numbers(pixel[r], sample[r], k, light_samples, seed, unit, &v1, &v2);
        float bx, by;
        concentric_disk(v1, v2, &bx, &by);
        /* r^2 of the disk point from the map's radius max(|2 v1 - 1|, |2 v2 - 1|), not bx^2 + by^2:
         * that pair of squares would give LLVM's SLP vectoriser a seed (see concentric_disk) */
        float da = 2.0f * v1 - 1.0f, db = 2.0f * v2 - 1.0f;
        da = da < 0.0f ? -da : da;
        db = __builtin_fabsf(db);
        float b2 = da > db ? da * da : db * db;
        float lift = 1.0f - b2;
        lift = 2.0f * __builtin_sqrtf(lift > 0.0f ? lift : 0.0f);
        /* y by other instructions than x (the same value): see concentric_disk */
        float fx = shx + bx * lift, fy = shy - (-by) * lift, fz = shz + (1.0f - 2.0f * b2);
        float flen = __builtin_sqrtf(fx * fx + fy * fy + fz * fz);
        int fok = flen > 0.0f;
        fx = fok ? fx / flen : 0.0f;
        fy = fok ? fy / flen : 0.0f;
        fz = fok ? fz / flen : 0.0f;
        float cos_f = fx * shx + fy * shy + fz * shz;
        float nlx = FIELD(light, LIGHT_NORMAL), nly = FIELD(light, LIGHT_NORMAL + 1);
        float nlz = FIELD(light, LIGHT_NORMAL + 2);
        float cx = FIELD(light, LIGHT_CENTRE), cy = FIELD(light, LIGHT_CENTRE + 1);
        float cz = FIELD(light, LIGHT_CENTRE + 2);
        float denom = fx * nlx + fy * nly + fz * nlz;
        float th = ((cx - px) * nlx + (cy - py) * nly + (cz - pz) * nlz) / denom;
        float hx = px + th * fx, hy = py + th * fy, hz = pz + th * fz;
        float rx = hx - cx, ry = hy - cy, rz = hz - cz;
        /* the point's (x, y) in the light's frame: dot products with the dual axes of a and b */
        float lu = rx * FIELD(light, LIGHT_DUAL_A) + ry * FIELD(light, LIGHT_DUAL_A + 1)
                   + rz * FIELD(light, LIGHT_DUAL_A + 2);
        float lv = rx * FIELD(light, LIGHT_DUAL_B) + ry * FIELD(light, LIGHT_DUAL_B + 1)
                   + rz * FIELD(light, LIGHT_DUAL_B + 2);
        float lu2 = lu * lu;
        int inside = disk ? lu2 <= 1.0f - lv * lv
                          : (lu >= -1.0f) & (lu <= 1.0f) & (lv >= -1.0f) & (lv <= 1.0f);
        float cos_h = -denom;
        cos_h = FIELD(light, LIGHT_TWO_SIDED) != 0.0f && cos_h < 0.0f ? -cos_h : cos_h;
        int live_f = measured & (cos_f > 0.0f) & (fx * gx + fy * gy + fz * gz > 0.0f) & (th > 0.0f) & inside
                     & (cos_h > 0.0f);
        float bf_r, bf_g, bf_b;
        measured_f(measured_tables, table_base, live_f, cos_o, cos_f, fx * mx + fy * my + fz * mz,
                   -(fx * dx + fy * dy + fz * dz) - cos_o * cos_f, unit, &bf_r, &bf_g, &bf_b);
        float ratio_f = th * th * PI_F / (cos_h * area * cos_f);
        float scale_f = PI_F / (1.0f + ratio_f * ratio_f) * (FIELD(light, LIGHT_SCALE) * PI_F / area);
        uint of = o + 1;
        WRITE_SHADOW_RAY(of, live_f, hx, hy, hz);
        OUT(contribution, 3, of, 0) = live_f ? bf_r * FIELD(light, LIGHT_RADIANCE) * scale_f : 0.0f;
        OUT(contribution, 3, of, 1) = live_f ? bf_g * FIELD(light, LIGHT_RADIANCE + 1) * scale_f : 0.0f;
        OUT(contribution, 3, of, 2) = live_f ? bf_b * FIELD(light, LIGHT_RADIANCE + 2) * scale_f : 0.0f;
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
