/* One path-tracing bounce at surface hits: closest hit -> light samples' shadow rays and the next ray.
 *
 * OpenCL 1.2 C, float32. The numpy reference is realistic.renderer.path.PathIntegrator._shade; the
 * host is realistic/renderer/bounce_kernel.py, which puts the BSDF_PARAM and BOUNCE_* tables'
 * #defines first, then kernels/bsdf.cl (with common.cl), whose Params, bsdf_eval and bsdf_sample this
 * file uses, then this file. One work item per surface hit i (row rows[i] of the bounce's rays,
 * path path[row]), as the numpy code does it, in the same float32 operations and order where it can:
 *   - the hit point o + t d; the geometric normal (embree's Ng normalised, reversed under a mirroring
 *     transform); where the mesh has varying vertex normals, the interpolated one through the
 *     instance's normal matrix (kept where it normalised to unit length), which the geometric normal
 *     is turned toward and which is the shading normal (PathIntegrator._outward_normals);
 *   - the shading frame (Duff et al. 2017, as renderer.bsdf.ShadingFrame) and wo;
 *   - the material's BSDF_PARAM row (with `tables`, the BSDF kernel's TableStore: measured and
 *     named metals' tables, mixes' second lobes), or where BOUNCE_MATERIAL's per_hit says so the
 *     hit's own row (`hit_params`, row i: the host looked every parameter up at the hit, for
 *     spectral rays at its wavelength, as BounceKernel._hit_rows says) and, where second_per_hit
 *     says so (a mix's textured second material), the hit's own second lobe (`hit_second`, row i of
 *     BOUNCE_LOBE_WIDTH floats, made likewise) in place of the tables' one, or where its `tree` says
 *     so (a mix holding a mix) the hit's own BSDF_TREE row (`hit_tree`, row i of tree_width floats,
 *     as many lobes as the scene's largest tree has, made likewise: its lobes at the hit, spectral
 *     rays' at their wavelength), which is then the hit's BSDF (bsdf.cl's tree_eval and
 *     tree_sample), its diffuse-like colour
 *     (a Material's, plastic's or substrate's diffuse, a coated diffuse's reflectance) times a grid
 *     or checker texture at the interpolated uv (realistic.scene.textures.evaluate) where
 *     BOUNCE_MATERIAL says so, or, for
 *     an image texture, the hit's colour the host filtered before the launch (`albedo`, one RGB per
 *     hit: EwaKernel.at_hits);
 *   - light samples (picked by the rounded-up CDF as numpy's searchsorted picks; LightSampler.sample):
 *     at depth 0 light_samples of them with the pixel's Sobol' numbers (rng.all_light_uniforms), else
 *     one with rng.uniform at dimensions base + 4 .. 6; on an area light the point on the disk or
 *     quad, or on an emitting instance's triangle picked by its area CDF (Emitter.points), and the
 *     density d^2 / (cos_q A) P_j (A the whole light's area); from outside an emitting sphere a
 *     direction uniform in the cone it subtends, density P_j / (2 pi (1 - cos theta_max)), which the
 *     host meets with the sphere's mesh (cone_light); a point or spot light's position, I / d^2 (a spot's
 *     times its quartic or smoothstep falloff) and density P_j; a distant light's direction and P_j;
 *     a constant infinite light's direction uniform on the sphere, density P_j / 4 pi, or an
 *     environment map's by its Distribution2D (map_direction), density P_j p(uv) |d(uv)/d(omega)|
 *     and radiance times the texel; then f and the BSDF's pdf, the power heuristic (weight 1 for
 *     the delta lights, which no BSDF sample finds), the contribution beta f L |cos| w / (pdf n),
 *     and the shadow ray from the offset origin to the point, or along the direction to FAR for
 *     distant and infinite lights;
 *   - one BSDF sample (bsdf_sample) with rng.uniform at base .. base + 2, the throughput, Russian
 *     roulette (path mode, depth >= ROULETTE_AFTER, rng.uniform at base + 3) or the direct mode's
 *     rule, and the next ray from the offset origin;
 *   - BOUNCE_SPECTRAL: rays of one wavelength each (a dispersive camera's), with each camera ray's
 *     rgb_basis row in `basis` (3 floats at path[r]), at hits of every material the RGB build
 *     covers. Each lobe's colours (spectral_lobe: a mix's both; a hit's own row's first lobe and
 *     its own second lobe are already the ray's), the diffuse-like colour's texture
 *     colour (an image texture's bare, from the host), and each light's radiance (after the RGB test of
 *     whether it is 0, as LightSampler.sample tests it) become their spectral values at the ray's
 *     wavelength (realistic.core.spectrum.spectral_value, in its order: dot3), held in every
 *     channel of a float3 so the same code serves; beta comes and goes as one float a row and
 *     each contribution is one float (the roulette's max over channels is that value).
 * Outputs, light sample k of hit i at row k * m + i: shadow origin and vector (3 floats each), its
 * length (1 - 1e-4 in units of the vector, FAR along a direction) or -1 for a dead sample (embree
 * skips it), contribution (3 floats, one when spectral, 0 when dead), and the light of a live cone
 * sample toward an emitting sphere, else -1 (cone_light: such a sample's vector is its direction, its
 * length FAR, and its contribution as if the direction met the sphere's mesh from its emitting side,
 * until the host finds where it meets it, if it does). Per hit: the next origin, direction, beta (one
 * float when spectral), the point (3 floats each), the sample's pdf and flags (bit 0 the path goes
 * on, bit 1 specular, bit 2 shade its next hit).
 * Square roots and floors here are __builtin_sqrtf and __builtin_floorf (LLVM intrinsics, correctly
 * rounded as numpy's float32 ones), not the OpenCL library's calls, as in kernels/shade.cl.
 */

#pragma OPENCL FP_CONTRACT OFF

#define GOLDEN 0x9E3779B9u
#define SHADOW_OFFSET 1e-4f
/* FAR and SHADOW_LENGTH come with the host's header (light_sampler.SHADOW_DEFINES). */

/* realistic.core.rng.uniform at dimension dim, from the sample's key hash32(hash32(hash32(seed +
 * GOLDEN) ^ pixel) ^ sample): the top 24 bits of hash32(key ^ dim). */
inline float uniform_at(uint key, uint dim) { return to_unit(hash32(key ^ dim)); }

/* realistic.core.rng.light_uniforms (pick included), bit for bit: light sample k of light_samples
 * per camera sample (the same numbers as kernels/shade.cl's light_numbers). */
inline void light_uniforms(uint pixel, uint sample, uint k, uint light_samples, uint seed, float *u0, float *u1,
                           float *u2) {
    uint h = hash32(hash32(hash32(seed + GOLDEN) ^ pixel) ^ 0xFFFFFFFFu);
    uint index = sample * light_samples + k;
    uint reversed = reverse_bits(index);
    uint shuffled = reverse_bits(owen_scramble_digits(reversed, hash32(h ^ 16u)));
    *u1 = to_unit(reverse_bits(owen_scramble_digits(shuffled, hash32(h ^ 17u))));
    *u2 = to_unit(reverse_bits(owen_scramble_digits(sobol1_digits(shuffled), hash32(h ^ 18u))));
    uint picked = reverse_bits(owen_scramble_digits(reversed, hash32(h ^ 19u)));
    *u0 = to_unit(reverse_bits(owen_scramble_digits(picked, hash32(h ^ 20u))));
}

/* The light of pick value u: how many CDF entries are <= u (numpy's searchsorted side="right"),
 * at most count - 1 (a binary search). */
inline int pick_light(__global const float *cdf, int count, float u) {
    int lo = 0, hi = count;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (cdf[mid] <= u) lo = mid + 1; else hi = mid;
    }
    return min(lo, count - 1);
}

inline float3 load3(__global const float *a, size_t row) { return vload3(row, a); }

/* A ray's colour (beta, a contribution): 3 floats a row, or one (BOUNCE_SPECTRAL) held in every
 * channel of a float3, so that the arithmetic below serves both. */
#if BOUNCE_SPECTRAL
#define LOAD_COLOUR(a, row) ((float3)((a)[row]))
#define STORE_COLOUR(v, row, a) ((a)[row] = (v).x)
#else
#define LOAD_COLOUR(a, row) vload3(row, a)
#define STORE_COLOUR(v, row, a) vstore3(v, row, a)
#endif

/* a^2 / (a^2 + b^2) for a, b >= 0 without overflow (0 where both are 0): path.power_heuristic. */
inline float power_heuristic(float a, float b) {
    if (a > 0.0f) {
        float r = b / a;
        return 1.0f / (1.0f + r * r);
    }
    return 0.0f;
}

inline float3 normalise3(float3 v) {
    float l = __builtin_sqrtf(v.x * v.x + v.y * v.y + v.z * v.z);
    return l > 0.0f ? v / l : (float3)(0.0f);
}

inline float dot3(float3 a, float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

/* max |v_i| */
inline float magnitude3(float3 v) { return fmax(fmax(fabs(v.x), fabs(v.y)), fabs(v.z)); }

/* The sign of x as numpy's np.sign: -1, 0 or 1. */
inline float sign_of(float x) { return x > 0.0f ? 1.0f : (x < 0.0f ? -1.0f : 0.0f); }

/* The unit vectors s and t of the orthonormal frame (s, t, n) about unit n: renderer.bsdf.ShadingFrame
 * (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"). */
inline void frame_of(float3 n, float3 *s, float3 *t) {
    float sgn = n.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (sgn + n.z);
    float b = n.x * n.y * a;
    *s = normalise3((float3)(1.0f + sgn * n.x * n.x * a, sgn * b, -sgn * n.x));
    *t = normalise3((float3)(b, sgn + n.y * n.y * a, -n.y));
}

/* The cell of u among a piecewise-constant distribution's count cells (the number of CDF entries
 * <= u, less one, within 0 .. count - 1: Distribution2D.sample's searchsorted) and u's place
 * within it, in [0, 1]. */
inline int cdf_cell(__global const float *cdf, int count, float u, float *within) {
    int cell = max(pick_light(cdf, count + 1, u) - 1, 0);
    float lo = cdf[cell], hi = cdf[cell + 1];
    *within = clamp((u - lo) / fmax(hi - lo, 1e-30f), 0.0f, 1.0f);
    return cell;
}

/* An environment map's sample (_Environment.sample): (u, v) by the map's Distribution2D from u1
 * (columns) and u2 (rows), the light-frame direction of a lat-long or equal-area map at uv
 * (latlong_direction, equal_area_square_to_sphere) turned to the world by its frame; the solid-angle
 * density (the cell's density times d(uv)/d(omega)) and the cell's texel, which the direction's
 * nearest-texel lookup reads. */
inline float3 map_direction(__global const float *light, __global const float *environment, float u1, float u2,
                            float *density, float3 *texel) {
    int width = (int)light[BOUNCE_LIGHT_MAP_SIZE], height = (int)light[BOUNCE_LIGHT_MAP_SIZE + 1];
    __global const float *start = light + BOUNCE_LIGHT_MAP_TABLES;
    __global const float *row_cdf = environment + (size_t)start[0] * BSDF_TABLE_ALIGN;
    __global const float *col_cdf = environment + (size_t)start[1] * BSDF_TABLE_ALIGN;
    __global const float *cells = environment + (size_t)start[2] * BSDF_TABLE_ALIGN;
    __global const float *texels = environment + (size_t)start[3] * BSDF_TABLE_ALIGN;
    float du, dv;
    int row = cdf_cell(row_cdf, height, u2, &dv);
    int col = cdf_cell(col_cdf + (size_t)row * (width + 1), width, u1, &du);
    float u = fmin(((float)col + du) / (float)width, 0x1.fffffep-1f);
    float v = fmin(((float)row + dv) / (float)height, 0x1.fffffep-1f);
    size_t cell = (size_t)row * width + col;
    *texel = vload3(cell, texels);
    float3 w;
    float jacobian;
    if ((int)light[BOUNCE_LIGHT_MAPPING] == BOUNCE_MAPPING_LATLONG) {
        float phi = u * (2.0f * M_PI_F), theta = v * M_PI_F;
        float s = sin(theta);
        w = (float3)(s * cos(phi), s * sin(phi), cos(theta));
        jacobian = s > 0.0f ? 1.0f / (2.0f * M_PI_F * M_PI_F * s) : 0.0f;
    } else {  /* Clarberg's octahedral equal-area square */
        float a = 2.0f * u - 1.0f, b = 2.0f * v - 1.0f;
        float ap = fabs(a), bp = fabs(b);
        float signed_distance = 1.0f - (ap + bp);
        float r = 1.0f - fabs(signed_distance);
        float phi = (r == 0.0f ? 1.0f : (bp - ap) / r + 1.0f) * (0.25f * M_PI_F);
        float radial = r * __builtin_sqrtf(fmax(0.0f, 2.0f - r * r));
        w = (float3)(copysign(cos(phi), a) * radial, copysign(sin(phi), b) * radial,
                     copysign(1.0f - r * r, signed_distance));
        jacobian = 0.25f * M_1_PI_F;
    }
    __global const float *m = light + BOUNCE_LIGHT_FRAME;
    *density = cells[cell] * jacobian;
    return normalise3((float3)(m[0] * w.x + m[1] * w.y + m[2] * w.z, m[3] * w.x + m[4] * w.y + m[5] * w.z,
                               m[6] * w.x + m[7] * w.y + m[8] * w.z));
}

/* A coated base made from its albedo a (the lobe's scale: RGB, or a spectral value in every channel)
 * as CoatedLambertian makes it (eta.y its internal reflectance F, eta.z pi eta^2, extra.y 1 - F):
 * its scale a / (pi eta^2 (1 - a F)) and albedo estimate, the channels' mean of a (1 - F) / (1 - a F)
 * (a spectral ray's one channel). For an albedo that is a texture's per hit, and spectral rays'. */
inline void coated_base(Lobe *p) {
    float3 rest = 1.0f - p->scale * p->eta.y;
    p->k = p->scale / (p->eta.z * rest);
    float3 estimate = p->scale * p->extra.y / rest;
#if BOUNCE_SPECTRAL
    p->extra.x = estimate.x;
#else
    p->extra.x = (estimate.x + estimate.y + estimate.z) / 3.0f;
#endif
}

#if BOUNCE_SPECTRAL
/* A lobe's RGB colours as their spectral values at a ray's wavelength (`basis`: its rgb_basis row),
 * each in every channel, as bsdf_for builds the lobe from SurfaceParameters' spectral colours: the
 * albedo, scale, reflection and transmission tints, a plastic's or substrate's specular colour and a
 * conductor's eta and k each the dot with the basis (light_sampler.colour); a named metal's and a
 * measured or MERL table's RGB-to-channel rows each the basis row (bsdf_kernel.rgb_channels); a coated
 * base made from its albedo's spectral value (coated_base); the coat's tint stays 1. Indices are
 * not dispersive. */
inline void spectral_lobe(Lobe *p, float3 basis) {
    if (p->kind == KIND_MEASURED || p->kind == KIND_MERL) {
        p->scale = p->tint = p->eta = basis;
        return;
    }
    p->scale = (float3)(dot3(p->scale, basis));
    if (p->kind == KIND_COATED_DIFFUSE) {
        coated_base(p);
    } else if (p->kind == KIND_TABULATED_CONDUCTOR) {
        p->tint = p->eta = p->k = basis;
    } else if (p->kind == KIND_CONDUCTOR) {
        p->eta = (float3)(dot3(p->eta, basis));
        p->k = (float3)(dot3(p->k, basis));
    } else {
        p->tint = (float3)(dot3(p->tint, basis));
    }
}
#endif

__kernel void bounce(uint m, uint light_samples, uint depth, uint seed, uint mode_flags, uint max_depth,
                     float offset_base, int light_count,
                     __global const int *rows, __global const int *path, __global const uint *pixel,
                     __global const uint *sample, __global const float *origin, __global const float *direction,
                     __global const float *tfar, __global const float *hit_u, __global const float *hit_v,
                     __global const int *prim, __global const int *geom, __global const float *ng_in,
                     __global const float *beta_in, __global const float *albedo, __global const float *basis,
                     __global const float *hit_params, __global const float *hit_second, __global const float *hit_tree,
                     uint tree_width,
                     __global const int *faces, __global const float *normals, __global const float *uvs,
                     __global const int *geom_ints, __global const float *geom_floats,
                     __global const float *params, __global const float *materials,
                     __global const float *lights, __global const float *cdf, __global const float *environment,
                     __global const float *tables,
                     __global float *shadow_origin, __global float *shadow_vector, __global float *shadow_length,
                     __global float *contribution, __global int *cone_light, __global float *next_origin, __global float *next_direction,
                     __global float *next_beta, __global float *next_point, __global float *next_pdf,
                     __global int *next_flags) {
    uint i = get_global_id(0);
    if (i >= m) return;
    int r = rows[i];
    int g = geom[r];
    uint px = pixel[path[r]], sx = sample[path[r]];
    float3 d = load3(direction, r);
    float t = tfar[r];
    float3 point = load3(origin, r) + t * d;

    /* normals (PathIntegrator._outward_normals) */
    __global const int *gi = geom_ints + GEOM_INT_WIDTH * g;
    float3 ng = normalise3(load3(ng_in, r));
    if (gi[GEOM_INT_SWAPS]) ng = -ng;
    /* the triangle's corners are read only where smooth normals or a texture need them: a random
     * read of a large mesh's faces costs a cache miss */
    int face = gi[GEOM_INT_FACE_OFFSET] + prim[r];
    float b1 = hit_u[r], b2 = hit_v[r];
    float b0 = 1.0f - b1 - b2;
    float3 shading = ng;
    if (gi[GEOM_INT_SMOOTH]) {
        int i0 = faces[3 * face], i1 = faces[3 * face + 1], i2 = faces[3 * face + 2];
        float3 n = load3(normals, i0) * b0 + load3(normals, i1) * b1 + load3(normals, i2) * b2;
        __global const float *nm = geom_floats + GEOM_FLOAT_WIDTH * g + GEOM_FLOAT_NORMAL_MATRIX;
        float3 w = (float3)(nm[0] * n.x + nm[1] * n.y + nm[2] * n.z, nm[3] * n.x + nm[4] * n.y + nm[5] * n.z,
                            nm[6] * n.x + nm[7] * n.y + nm[8] * n.z);
        w = normalise3(w);
        if (dot3(w, w) > 0.5f) {
            if (dot3(ng, w) < 0.0f) ng = -ng;
            shading = w;
        }
    }
    /* the shading frame */
    float3 fs, ft;
    frame_of(shading, &fs, &ft);
    float3 wo = (float3)(-dot3(d, fs), -dot3(d, ft), -dot3(d, shading));
    float eps = SHADOW_OFFSET * (magnitude3(point) + offset_base);

    /* the material: its BSDF row; its diffuse-like colour (a Material's albedo, a plastic's or
     * substrate's Kd, a coated diffuse's reflectance: the lobe's scale) times its grid or checker
     * texture's colour, or times its image texture's (the host's, per hit: the colour itself for RGB
     * rays, the bare texture for spectral ones), a coated base then remade from it */
    int material = gi[GEOM_INT_MATERIAL];
    __global const float *mat = materials + BOUNCE_MATERIAL_WIDTH * material;
    int per_hit = mat[BOUNCE_MATERIAL_PER_HIT] != 0.0f;
    int second_per_hit = mat[BOUNCE_MATERIAL_SECOND_PER_HIT] != 0.0f;
    Params p = load_params(per_hit ? hit_params + (size_t)BSDF_PARAM_WIDTH * i : params + BSDF_PARAM_WIDTH * material,
                           tables);
    if (second_per_hit && p.amount > 0.0f) p.lobe[1] = load_lobe(hit_second + (size_t)BOUNCE_LOBE_WIDTH * i, tables);
    if (mat[BOUNCE_MATERIAL_TREE] != 0.0f) p.tree = hit_tree + (size_t)tree_width * i;
    int texture = (int)mat[BOUNCE_MATERIAL_TEXTURE];
    float3 texel = (float3)(1.0f);
    if (texture == BOUNCE_TEXTURE_IMAGE) {
        texel = load3(albedo, i);
    } else if (texture != BOUNCE_TEXTURE_NONE) {
        int i0 = faces[3 * face], i1 = faces[3 * face + 1], i2 = faces[3 * face + 2];
        float tu = uvs[2 * i0] * b0 + uvs[2 * i1] * b1 + uvs[2 * i2] * b2;
        float tv = uvs[2 * i0 + 1] * b0 + uvs[2 * i1 + 1] * b1 + uvs[2 * i2 + 1] * b2;
        float cu = tu * mat[BOUNCE_MATERIAL_CELLS], cv = tv * mat[BOUNCE_MATERIAL_CELLS];
        float fu = cu - __builtin_floorf(cu), fv = cv - __builtin_floorf(cv);
        float low = mat[BOUNCE_MATERIAL_LOW], high = mat[BOUNCE_MATERIAL_HIGH];
        int use_b;
        if (texture == BOUNCE_TEXTURE_GRID) {
            use_b = !((fu < low) | (fu > high) | (fv < low) | (fv > high));
        } else {
            float parity = __builtin_floorf(cu) + __builtin_floorf(cv);
            use_b = parity - 2.0f * __builtin_floorf(parity * 0.5f) != 0.0f;
        }
        texel = use_b ? vload3(0, mat + BOUNCE_MATERIAL_COLOUR_B) : vload3(0, mat + BOUNCE_MATERIAL_COLOUR_A);
    }
#if BOUNCE_SPECTRAL
    /* the ray's wavelength: each lobe's colours as spectral values (spectral_lobe), the diffuse-like
     * colour's constant factor's times its texture's, each the dot with the ray's rgb_basis row
     * (SurfaceParameters.colour turns each of them so) */
    float3 wavelength_basis = load3(basis, path[r]);
    if (!per_hit) spectral_lobe(&p.lobe[0], wavelength_basis);  /* a hit's own rows are at its wavelength */
    if (p.amount > 0.0f && !second_per_hit) spectral_lobe(&p.lobe[1], wavelength_basis);
    if (texture != BOUNCE_TEXTURE_NONE) p.lobe[0].scale *= (float3)(dot3(texel, wavelength_basis));
#else
    if (texture == BOUNCE_TEXTURE_IMAGE) p.lobe[0].scale = texel;
    else if (texture != BOUNCE_TEXTURE_NONE) p.lobe[0].scale *= texel;
#endif
    if (texture != BOUNCE_TEXTURE_NONE && p.lobe[0].kind == KIND_COATED_DIFFUSE) coated_base(&p.lobe[0]);
    float3 beta = LOAD_COLOUR(beta_in, r);
    uint base = BOUNCE_DIMENSION + 8 * depth;
    uint key = hash32(hash32(hash32(seed + GOLDEN) ^ px) ^ sx);
    int mis = (mode_flags & BOUNCE_MIS) != 0;

    /* light samples */
    float n_light = (float)light_samples;
    for (uint k = 0; k < light_samples; k++) {
        size_t o = (size_t)k * m + i;
        float u_pick, u1, u2;
        if (depth == 0) {
            light_uniforms(px, sx, k, light_samples, seed, &u_pick, &u1, &u2);
        } else {
            u_pick = uniform_at(key, base + 4);
            u1 = uniform_at(key, base + 5);
            u2 = uniform_at(key, base + 6);
        }
        int picked = pick_light(cdf, light_count, u_pick);
        __global const float *light = lights + BOUNCE_LIGHT_WIDTH * picked;
        int kind = (int)light[BOUNCE_LIGHT_KIND];
        float3 radiance = vload3(0, light + BOUNCE_LIGHT_RADIANCE);
        float probability = light[BOUNCE_LIGHT_PROBABILITY];
        float3 wi, target = (float3)(0.0f);
        float light_pdf = probability;  /* a delta light's: its pick probability */
        /* an emitting sphere seen from outside it: a direction in the cone it subtends (Emitter.cone) */
        float radius = light[BOUNCE_LIGHT_RADIUS];
        float3 to_centre = vload3(0, light + BOUNCE_LIGHT_CENTRE) - point;
        float centre2 = dot3(to_centre, to_centre);
        int cone = kind == BOUNCE_KIND_INSTANCE && radius > 0.0f && centre2 > radius * radius;
        int far = kind == BOUNCE_KIND_DISTANT || kind == BOUNCE_KIND_INFINITE || cone;
        if (cone) {
            /* LightSampler._towards_sphere: 1 - cos(theta) uniform on [0, 1 - cos(theta_max)], the
             * latter as sin^2 / (1 + cos); the host meets the direction with the mesh */
            float sin2 = radius * radius / centre2;
            float one_minus_cos = sin2 / (1.0f + __builtin_sqrtf(fmax(0.0f, 1.0f - sin2)));
            float lower = u1 * one_minus_cos;
            float sin_theta = __builtin_sqrtf(fmax(0.0f, lower * (2.0f - lower)));
            float phi = 2.0f * M_PI_F * u2;
            float3 axis = to_centre / __builtin_sqrtf(fmax(centre2, 1e-30f)), cs, ct;
            frame_of(axis, &cs, &ct);
            wi = cs * (sin_theta * cos(phi)) + ct * (sin_theta * sin(phi)) + axis * (1.0f - lower);
            light_pdf = probability / (2.0f * M_PI_F * one_minus_cos);
        } else if (kind == BOUNCE_KIND_AREA || kind == BOUNCE_KIND_INSTANCE) {  /* by area: d^2 / (cos_q A) */
            float3 normal;
            if (kind == BOUNCE_KIND_INSTANCE) {
                /* Emitter.points: u1 picks a triangle by the area CDF and, rescaled within its step,
                 * with u2 places the point in it by Turk's square-root map */
                __global const float *triangle_cdf = environment
                                                     + (size_t)light[BOUNCE_LIGHT_TRIANGLES] * BSDF_TABLE_ALIGN;
                int count = (int)light[BOUNCE_LIGHT_TRIANGLES + 2];
                int tri = pick_light(triangle_cdf, count, u1);
                float lo = tri > 0 ? triangle_cdf[tri - 1] : 0.0f;
                float s = clamp((u1 - lo) / fmax(triangle_cdf[tri] - lo, 1e-30f), 0.0f, 1.0f);
                float root = __builtin_sqrtf(s);
                __global const float *triangle = environment
                    + (size_t)light[BOUNCE_LIGHT_TRIANGLES + 1] * BSDF_TABLE_ALIGN + (size_t)tri * BOUNCE_TRIANGLE_WIDTH;
                target = vload3(0, triangle + BOUNCE_TRIANGLE_ORIGIN)
                         + vload3(0, triangle + BOUNCE_TRIANGLE_E1) * (1.0f - root)
                         + vload3(0, triangle + BOUNCE_TRIANGLE_E2) * (u2 * root);
                normal = vload3(0, triangle + BOUNCE_TRIANGLE_NORMAL);
            } else {  /* LightSampler._sample_areas: on the disk or quad */
                float x, y;
                if (light[BOUNCE_LIGHT_DISK] != 0.0f) {
                    concentric_disk(u1, u2, &x, &y);
                } else {
                    x = 2.0f * u1 - 1.0f;
                    y = 2.0f * u2 - 1.0f;
                }
                target = vload3(0, light + BOUNCE_LIGHT_CENTRE) + vload3(0, light + BOUNCE_LIGHT_A) * x
                         + vload3(0, light + BOUNCE_LIGHT_B) * y;
                normal = vload3(0, light + BOUNCE_LIGHT_NORMAL);
            }
            float3 to_light = target - point;
            float d2 = dot3(to_light, to_light);
            wi = to_light / __builtin_sqrtf(fmax(d2, 1e-30f));
            float cos_q = -dot3(wi, normal);
            if (light[BOUNCE_LIGHT_TWO_SIDED] != 0.0f) cos_q = fabs(cos_q);
            int ok = cos_q > 0.0f && d2 > 0.0f;
            light_pdf = ok ? d2 / (cos_q * light[BOUNCE_LIGHT_AREA]) * probability : 0.0f;
        } else if (kind == BOUNCE_KIND_POINT || kind == BOUNCE_KIND_SPOT) {
            /* I / d^2 toward the light's position, a spot's times its falloff (SpotLight.falloff) */
            target = vload3(0, light + BOUNCE_LIGHT_CENTRE);
            float3 to_light = target - point;
            float d2 = dot3(to_light, to_light);
            wi = to_light / __builtin_sqrtf(fmax(d2, 1e-30f));
            float scale = 1.0f / fmax(d2, 1e-30f);
            if (kind == BOUNCE_KIND_SPOT) {
                /* the cosine to the cone's axis of -wi in the light's frame */
                __global const float *frame = light + BOUNCE_LIGHT_FRAME;
                float3 in_frame = -(float3)(frame[0] * wi.x + frame[1] * wi.y + frame[2] * wi.z,
                                         frame[3] * wi.x + frame[4] * wi.y + frame[5] * wi.z,
                                         frame[6] * wi.x + frame[7] * wi.y + frame[8] * wi.z);
                float cos_axis = in_frame.z / fmax(__builtin_sqrtf(dot3(in_frame, in_frame)), 1e-30f);
                float cos_total = light[BOUNCE_LIGHT_COS_TOTAL], span = light[BOUNCE_LIGHT_SPAN];
                float t = span > 0.0f ? clamp((cos_axis - cos_total) / span, 0.0f, 1.0f)
                                      : (cos_axis >= cos_total ? 1.0f : 0.0f);
                scale *= light[BOUNCE_LIGHT_SMOOTHSTEP] != 0.0f ? t * t * (3.0f - 2.0f * t) : (t * t) * (t * t);
            }
            radiance *= scale;
        } else if (kind == BOUNCE_KIND_DISTANT) {  /* from its direction, a shadow ray to FAR */
            wi = vload3(0, light + BOUNCE_LIGHT_NORMAL);
        } else if ((int)light[BOUNCE_LIGHT_MAPPING] == BOUNCE_MAPPING_NONE) {
            /* a constant infinite light: uniform over the sphere (_Environment.sample), density 1 / 4 pi */
            float z = 1.0f - 2.0f * u1;
            float r = __builtin_sqrtf(fmax(0.0f, 1.0f - z * z));
            float phi = 2.0f * M_PI_F * u2;
            wi = (float3)(r * cos(phi), r * sin(phi), z);
            light_pdf = probability * (0.25f * M_1_PI_F);
        } else {  /* an environment map: its texel and density at a direction from its tables */
            float density;
            float3 texel;
            wi = map_direction(light, environment, u1, u2, &density, &texel);
            light_pdf = probability * density;
            radiance *= texel;
        }
        /* no BSDF sample can hit a delta light: its light sample weighs 1 */
        int delta = kind == BOUNCE_KIND_POINT || kind == BOUNCE_KIND_SPOT || kind == BOUNCE_KIND_DISTANT;
        int valid = light_pdf > 0.0f && (radiance.x != 0.0f || radiance.y != 0.0f || radiance.z != 0.0f);
#if BOUNCE_SPECTRAL
        radiance = (float3)(dot3(radiance, wavelength_basis));  /* light_sampler.colour, after the RGB test */
#endif
        float3 light_wi = (float3)(dot3(wi, fs), dot3(wi, ft), dot3(wi, shading));
        float bsdf_pdf;
        float3 f = bsdf_eval(&p, wo, light_wi, &bsdf_pdf);
        float side_g = dot3(wi, ng);
        int usable = valid && side_g * light_wi.z > 0.0f;
        float weight = mis && !delta ? power_heuristic(n_light * light_pdf, bsdf_pdf) : 1.0f;
        float scale = usable ? fabs(light_wi.z) * weight / (light_pdf * n_light) : 0.0f;
        float3 c = beta * f * radiance * scale;
        int live = c.x != 0.0f || c.y != 0.0f || c.z != 0.0f;
        float3 start = point + ng * eps * sign_of(side_g);
        vstore3(live ? start : (float3)(0.0f), o, shadow_origin);
        vstore3(live ? (far ? wi : target - start) : (float3)(0.0f), o, shadow_vector);
        shadow_length[o] = live ? (far ? FAR : SHADOW_LENGTH) : -1.0f;
        STORE_COLOUR(live ? c : (float3)(0.0f), o, contribution);
        cone_light[o] = live && cone ? picked : -1;
    }

    /* the BSDF sample and the next ray */
    float3 value;
    float pdf;
    int flags;
    float3 local_wi = bsdf_sample(&p, wo, uniform_at(key, base), uniform_at(key, base + 1), uniform_at(key, base + 2),
                                  &value, &pdf, &flags);
    int specular = flags & 1;
    int ok = (flags & 2) && pdf > 0.0f;
    float3 throughput = ok ? value * (fabs(local_wi.z) / pdf) : (float3)(0.0f);
    float3 world_wi = fs * local_wi.x + ft * local_wi.y + shading * local_wi.z;
    float side = dot3(world_wi, ng);
    int go = ok && side * local_wi.z > 0.0f;
    float3 new_beta = beta * throughput;
    int shade = 1;
    if (mode_flags & BOUNCE_DIRECT) {
        /* pbrt-v3 DirectLightingIntegrator: specular reflection while depth + 1 < maxdepth */
        int follow = specular && depth + 1 < max_depth;
        shade = follow;
        go = go && (follow || (!specular && (mode_flags & BOUNCE_EMISSION_AFTER_DIFFUSE)));
    } else if (depth >= BOUNCE_ROULETTE_AFTER) {
        float q = fmax(0.05f, 1.0f - fmax(fmax(new_beta.x, new_beta.y), new_beta.z));
        go = go && uniform_at(key, base + 3) >= q;
        new_beta /= fmax(1.0f - q, 1e-6f);
    }
    go = go && (new_beta.x != 0.0f || new_beta.y != 0.0f || new_beta.z != 0.0f);
    vstore3(point + ng * eps * sign_of(side), i, next_origin);
    vstore3(world_wi, i, next_direction);
    STORE_COLOUR(new_beta, i, next_beta);
    vstore3(point, i, next_point);
    next_pdf[i] = pdf;
    next_flags[i] = go | (specular << 1) | (shade << 2);
}
