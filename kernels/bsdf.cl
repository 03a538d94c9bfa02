/* BSDF evaluation and sampling for the path integrator: one work item per surface hit.
 *
 * OpenCL 1.2 C, float32. The numpy references are realistic/renderer/bsdf/ (lambertian.py,
 * conductor.py, microfacet.py, fresnel.py, dielectric.py, mix.py for plastic); the host is
 * realistic/renderer/bsdf_kernel.py, which prepends the BSDF_PARAM table's #defines and the KIND_*
 * constants. Each hit's parameters are a row of BSDF_PARAM (its material's kind, colours, indices
 * and GGX widths looked up at the hit by the host, textures included). Directions are in the local
 * shading frame (normal +z). Per work item i:
 *   - for each of `lights` light directions (rows k * n + i of light_wi): f(wo, wi) and the pdf with
 *     which sampling would pick wi;
 *   - one BSDF sample from the host's uniform numbers u (2 per hit) and u_lobe: its direction, value,
 *     pdf and flags (bit 0 specular, bit 1 valid), as ``BSDF.sample`` returns them.
 * Kinds: Lambertian; conductor (GGX with the conductor Fresnel of eta + i k); mirror (no Fresnel);
 * smooth dielectric and thin dielectric; plastic (Lambertian kd + a GGX coat of ks with the
 * dielectric Fresnel of index eta, lobes picked in proportion to the colours' means). A lobe whose
 * max(alpha_x, alpha_y) is below SMOOTH_ALPHA reflects specularly. */

#include "common.cl"

#define PI_F 3.14159265358979f

typedef struct {
    int kind;
    float3 scale, tint, eta, k;
    float ax, ay;  /* GGX widths, at least 1e-4 as microfacet.GGX keeps them */
    int smooth;
} Params;

inline Params load_params(__global const float *row) {
    Params p;
    p.kind = (int)row[BSDF_PARAM_KIND];
    p.scale = vload3(0, row + BSDF_PARAM_SCALE);
    p.tint = vload3(0, row + BSDF_PARAM_TINT);
    p.eta = vload3(0, row + BSDF_PARAM_ETA);
    p.k = vload3(0, row + BSDF_PARAM_K);
    float ax = row[BSDF_PARAM_ALPHA], ay = row[BSDF_PARAM_ALPHA + 1];
    p.smooth = fmax(ax, ay) < SMOOTH_ALPHA;
    p.ax = fmax(ax, 1e-4f);
    p.ay = fmax(ay, 1e-4f);
    return p;
}

/* fresnel.dielectric: reflectance from outside (index 1) into eta at cosine c (negative: inside). */
inline float fresnel_dielectric(float c, float eta) {
    c = clamp(c, -1.0f, 1.0f);
    int entering = c > 0.0f;
    float eta_i = entering ? 1.0f : eta, eta_t = entering ? eta : 1.0f;
    c = fabs(c);
    float sin_t = eta_i / eta_t * sqrt(fmax(0.0f, 1.0f - c * c));
    if (sin_t >= 1.0f) return 1.0f;
    float cos_t = sqrt(fmax(0.0f, 1.0f - sin_t * sin_t));
    float r_par = (eta_t * c - eta_i * cos_t) / (eta_t * c + eta_i * cos_t);
    float r_perp = (eta_i * c - eta_t * cos_t) / (eta_i * c + eta_t * cos_t);
    float r = 0.5f * (r_par * r_par + r_perp * r_perp);
    return isnan(r) ? 1.0f : r;
}

/* fresnel.conductor per channel, at |c|. */
inline float3 fresnel_conductor(float c, float3 eta, float3 k) {
    c = clamp(fabs(c), 0.0f, 1.0f);
    float cos2 = c * c, sin2 = 1.0f - c * c;
    float3 eta2 = eta * eta, k2 = k * k;
    float3 t0 = eta2 - k2 - sin2;
    float3 a2_plus_b2 = sqrt(t0 * t0 + 4.0f * eta2 * k2);
    float3 t1 = a2_plus_b2 + cos2;
    float3 a = sqrt(fmax(0.0f, 0.5f * (a2_plus_b2 + t0)));
    float3 t2 = 2.0f * c * a;
    float3 r_s = (t1 - t2) / (t1 + t2);
    float3 t3 = cos2 * a2_plus_b2 + sin2 * sin2;
    float3 t4 = t2 * sin2;
    float3 r_p = r_s * (t3 - t4) / (t3 + t4);
    float3 r = 0.5f * (r_p + r_s);
    return (float3)(isnan(r.x) ? 1.0f : r.x, isnan(r.y) ? 1.0f : r.y, isnan(r.z) ? 1.0f : r.z);
}

/* The microfacet lobe's colour times its Fresnel at cosine c: the conductor's, the plastic coat's
 * (tint, dielectric eta.x), or the mirror's (none). */
inline float3 reflected(const Params *p, float c) {
    if (p->kind == KIND_CONDUCTOR) return p->scale * fresnel_conductor(c, p->eta, p->k);
    if (p->kind == KIND_PLASTIC) return p->tint * fresnel_dielectric(c, p->eta.x);
    return p->scale;
}

inline float ggx_d(const Params *p, float3 wh) {
    if (wh.z <= 0.0f) return 0.0f;
    float x = wh.x / p->ax, y = wh.y / p->ay;
    float den = x * x + y * y + wh.z * wh.z;
    return 1.0f / (PI_F * p->ax * p->ay * den * den);
}

inline float ggx_lambda(const Params *p, float3 w) {
    float tan2 = (p->ax * p->ax * w.x * w.x + p->ay * p->ay * w.y * w.y) / fmax(w.z * w.z, 1e-30f);
    return 0.5f * (sqrt(1.0f + tan2) - 1.0f);
}

/* (cos, sin) of 2 pi u for u in [0, 1): the nearest quarter turn (exact in float32), then common.cl's
 * polynomial within pi / 4 of it (no library call, and no rounding of 2 pi u). */
inline void sincos_turn(float u, float *c, float *s) {
    float t = 4.0f * u;
    float q = floor(t + 0.5f);
    float sq, cq;
    sincos_quarter((t - q) * (0.5f * PI_F), &sq, &cq);
    int quadrant = (int)q & 3;
    *c = quadrant == 0 ? cq : (quadrant == 1 ? -sq : (quadrant == 2 ? -cq : sq));
    *s = quadrant == 0 ? sq : (quadrant == 1 ? cq : (quadrant == 2 ? -sq : -cq));
}

/* Heitz 2018's visible-normal sample, as microfacet.GGX.sample_visible (wo in the upper hemisphere). */
inline float3 ggx_sample_visible(const Params *p, float3 wo, float u0, float u1) {
    float3 v = normalize((float3)(p->ax * wo.x, p->ay * wo.y, wo.z));
    float length2 = v.x * v.x + v.y * v.y;
    float3 t1 = length2 > 0.0f ? (float3)(-v.y, v.x, 0.0f) * rsqrt(length2) : (float3)(1.0f, 0.0f, 0.0f);
    float3 t2 = cross(v, t1);
    float r = sqrt(u0);
    float cos_phi, sin_phi;
    sincos_turn(u1, &cos_phi, &sin_phi);
    float p1 = r * cos_phi, p2 = r * sin_phi;
    float s = 0.5f * (1.0f + v.z);
    p2 = (1.0f - s) * sqrt(fmax(0.0f, 1.0f - p1 * p1)) + s * p2;
    float3 n = p1 * t1 + p2 * t2 + sqrt(fmax(0.0f, 1.0f - p1 * p1 - p2 * p2)) * v;
    return normalize((float3)(p->ax * n.x, p->ay * n.y, fmax(1e-9f, n.z)));
}

/* MicrofacetReflection.evaluate and .pdf at one pair (zero for a smooth lobe). */
inline float3 microfacet_eval(const Params *p, float3 wo, float3 wi, float *pdf) {
    *pdf = 0.0f;
    if (p->smooth || !(wo.z * wi.z > 0.0f)) return (float3)(0.0f);
    float flip = wo.z < 0.0f ? -1.0f : 1.0f;
    float3 wo_up = wo * flip, wi_up = wi * flip;
    float3 h = wo_up + wi_up;
    if (!(dot(h, h) > 1e-20f)) return (float3)(0.0f);
    float3 wh = normalize(h);
    float cos_o = wo_up.z, cos_i = wi_up.z;
    if (!(cos_o > 0.0f)) return (float3)(0.0f);
    float d = ggx_d(p, wh), lo = ggx_lambda(p, wo_up);
    *pdf = d / (1.0f + lo) / (4.0f * fmax(cos_o, 1e-30f));
    if (!(cos_i > 0.0f)) return (float3)(0.0f);
    float shape = d / (1.0f + lo + ggx_lambda(p, wi_up)) / (4.0f * cos_o * cos_i);
    return reflected(p, dot(wo_up, wh)) * shape;
}

/* The plastic's lobe probabilities: the diffuse and coat colours' means, normalised (halves if both 0). */
inline float diffuse_chance(const Params *p) {
    float m0 = (p->scale.x + p->scale.y + p->scale.z) / 3.0f, m1 = (p->tint.x + p->tint.y + p->tint.z) / 3.0f;
    return m0 + m1 > 0.0f ? m0 / (m0 + m1) : 0.5f;
}

/* f(wo, wi) and the sampling pdf of wi. */
inline float3 bsdf_eval(const Params *p, float3 wo, float3 wi, float *pdf) {
    float same = wo.z * wi.z > 0.0f ? 1.0f : 0.0f;
    if (p->kind == KIND_LAMBERTIAN) {
        *pdf = same * fabs(wi.z) / PI_F;
        return p->scale * (same / PI_F);
    }
    if (p->kind == KIND_DIELECTRIC || p->kind == KIND_THIN_DIELECTRIC) {
        *pdf = 0.0f;
        return (float3)(0.0f);
    }
    float coat_pdf;
    float3 f = microfacet_eval(p, wo, wi, &coat_pdf);
    if (p->kind != KIND_PLASTIC) {
        *pdf = coat_pdf;
        return f;
    }
    float c0 = diffuse_chance(p);
    *pdf = c0 * (same * fabs(wi.z) / PI_F) + (1.0f - c0) * coat_pdf;
    return p->scale * (same / PI_F) + f;
}

/* Cosine-weighted direction on wo's side (lambertian.cosine_on_side). */
inline float3 cosine_on_side(float3 wo, float u0, float u1) {
    float x, y;
    concentric_disk(u0, u1, &x, &y);
    float z = sqrt(fmax(0.0f, 1.0f - x * x - y * y));
    return (float3)(x, y, wo.z < 0.0f ? -z : z);
}

/* A microfacet lobe's sampled direction: the mirror direction where smooth, else reflected about a
 * visible normal on wo's side. */
inline float3 microfacet_direction(const Params *p, float3 wo, float u0, float u1) {
    if (p->smooth) return (float3)(-wo.x, -wo.y, wo.z);
    float flip = wo.z < 0.0f ? -1.0f : 1.0f;
    float3 wo_up = wo * flip;
    float3 wh = ggx_sample_visible(p, wo_up, u0, u1);
    return (-wo_up + 2.0f * dot(wo_up, wh) * wh) * flip;
}

/* Smooth or thin glass (dielectric.Dielectric.sample). */
inline float3 dielectric_sample(const Params *p, float3 wo, float u_lobe, float3 *value, float *pdf, int *valid) {
    float eta = p->eta.x, r;
    float3 transmitted;
    int ok = 1;
    if (p->kind == KIND_THIN_DIELECTRIC) {
        float r0 = fresnel_dielectric(fabs(wo.z), eta), t = 1.0f - r0;
        r = r0 < 1.0f ? r0 + t * t * r0 / (1.0f - r0 * r0) : 1.0f;
        transmitted = -wo;
    } else {
        r = fresnel_dielectric(wo.z, eta);
        int entering = wo.z > 0.0f;
        float ratio = entering ? 1.0f / eta : eta;
        float sin2_t = ratio * ratio * fmax(0.0f, 1.0f - wo.z * wo.z);
        ok = sin2_t < 1.0f;
        float cos_t = sqrt(fmax(0.0f, 1.0f - sin2_t));
        transmitted = (float3)(-ratio * wo.x, -ratio * wo.y, entering ? -cos_t : cos_t);
    }
    int reflect = u_lobe < r || !ok;
    float3 wi = reflect ? (float3)(-wo.x, -wo.y, wo.z) : transmitted;
    *pdf = reflect ? r : 1.0f - r;
    float c = fabs(wi.z);
    *value = c > 0.0f ? (reflect ? p->scale : p->tint) * (*pdf / c) : (float3)(0.0f);
    *valid = *pdf > 0.0f && c > 0.0f;
    return wi;
}

/* One BSDF sample from the uniform numbers u0, u1 and u_lobe: its direction (returned), value,
 * pdf and flags (bit 0 specular, bit 1 valid), as ``BSDF.sample`` returns them. The bsdf kernel
 * below and kernels/bounce.cl (the path integrator's fused bounce) both draw through it. */
inline float3 bsdf_sample(const Params *p, float3 wo, float u0, float u1, float ul, float3 *value_out,
                          float *pdf_out, int *flags_out) {
    float3 wi, value;
    float pdf;
    int specular, valid;
    if (p->kind == KIND_DIELECTRIC || p->kind == KIND_THIN_DIELECTRIC) {
        wi = dielectric_sample(p, wo, ul, &value, &pdf, &valid);
        specular = 1;
    } else {
        /* plastic: the diffuse lobe below the diffuse chance, else the coat (mix.WeightedSum) */
        int diffuse = p->kind == KIND_LAMBERTIAN || (p->kind == KIND_PLASTIC && ul < diffuse_chance(p));
        wi = diffuse ? cosine_on_side(wo, u0, u1) : microfacet_direction(p, wo, u0, u1);
        specular = !diffuse && p->smooth;
        value = bsdf_eval(p, wo, wi, &pdf);
        if (specular) {
            float c = fabs(wo.z);
            value = c > 0.0f ? reflected(p, c) / c : (float3)(0.0f);
            pdf = p->kind == KIND_PLASTIC ? 1.0f - diffuse_chance(p) : 1.0f;
        }
        /* the sampled lobe's own validity: a Lambertian's pdf positive; a microfacet lobe's pdf
         * positive (1 where smooth) and wi on wo's side */
        float lobe_pdf = 1.0f;
        if (!diffuse && !specular) microfacet_eval(p, wo, wi, &lobe_pdf);
        int side = wo.z * wi.z > 0.0f;
        valid = pdf > 0.0f && side && (diffuse ? wi.z != 0.0f : lobe_pdf > 0.0f && wo.z != 0.0f);
    }
    *value_out = value;
    *pdf_out = pdf;
    *flags_out = specular | (valid << 1);
    return wi;
}

__kernel void bsdf(uint n, uint lights, __global const float *params, __global const float *wo_in,
                   __global const float *light_wi, __global const float *u, __global const float *u_lobe,
                   __global float *light_f, __global float *light_pdf, __global float *wi_out,
                   __global float *value_out, __global float *pdf_out, __global int *flags_out) {
    uint i = get_global_id(0);
    if (i >= n) return;
    Params p = load_params(params + (size_t)i * BSDF_PARAM_WIDTH);
    float3 wo = vload3(i, wo_in);
    for (uint k = 0; k < lights; k++) {
        size_t row = (size_t)k * n + i;
        float pdf;
        vstore3(bsdf_eval(&p, wo, vload3(row, light_wi), &pdf), row, light_f);
        light_pdf[row] = pdf;
    }
    float3 value;
    float pdf;
    int flags;
    float3 wi = bsdf_sample(&p, wo, u[2 * i], u[2 * i + 1], u_lobe[i], &value, &pdf, &flags);
    vstore3(wi, i, wi_out);
    vstore3(value, i, value_out);
    pdf_out[i] = pdf;
    flags_out[i] = flags;
}
