/* BSDF evaluation and sampling for the path integrator: one work item per surface hit.
 *
 * OpenCL 1.2 C, float32. The numpy references are realistic/renderer/bsdf/ (lambertian.py,
 * oren_nayar.py, conductor.py, microfacet.py, fresnel.py, dielectric.py, rough_dielectric.py,
 * substrate.py, coated_diffuse.py, measured.py, mix.py for plastic, coated diffuse and mixes); the
 * host is realistic/renderer/bsdf_kernel.py, which prepends the BSDF_PARAM table's #defines, the
 * KIND_* constants and BSDF_TABLE_ALIGN. Each hit's parameters are a row of BSDF_PARAM (its
 * material's kind, colours, indices and GGX widths looked up at the hit by the host, textures
 * included; a mix's row holds its first lobe, its amount and where its second lobe lies in
 * `tables`), and `tables` the measured and named metals' tables and the mixes' second lobes.
 * Directions are in the local shading frame (normal +z). Per work item i:
 *   - for each of `lights` light directions (rows k * n + i of light_wi): f(wo, wi) and the pdf with
 *     which sampling would pick wi;
 *   - one BSDF sample from the host's uniform numbers u (2 per hit) and u_lobe: its direction, value,
 *     pdf and flags (bit 0 specular, bit 1 valid), as ``BSDF.sample`` returns them.
 * Lobe kinds: Lambertian; Oren-Nayar; conductor (GGX with the conductor Fresnel of eta + i k, or
 * a named metal's tabulated Fresnel); mirror (no Fresnel); smooth, thin and rough dielectric
 * (pbrt-v4's, GGX); plastic (Lambertian kd + a GGX
 * coat of ks with the dielectric Fresnel of index eta, lobes picked in proportion to the colours'
 * means); coated diffuse (the coated base + an uncoloured coat, lobes picked by the coat's Fresnel);
 * substrate (FresnelBlend); measured (a pbrt-v2 .brdf file's table, cosine-sampled); MERL (a
 * half-angle table's bins, cosine-sampled); diffuse
 * transmission (Lambertian reflection of scale and transmission of tint, the side picked in
 * proportion to their means; diffuse_transmission.py). A lobe whose
 * max(alpha_x, alpha_y) is below SMOOTH_ALPHA reflects (glass: and refracts) specularly. */

#include "common.cl"

/* the MERL lobe finds its bins in double precision, as its numpy reference does (PoCL's CPU device
 * has cl_khr_fp64, as kernels/ewa.cl uses) */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#define PI_F 3.14159265358979f

/* One lobe: a material that is not a mix (the first 17 columns of a BSDF_PARAM row, or a mix's
 * second lobe in the tables). `extra`: Oren-Nayar's A and B, the coated base's albedo estimate
 * (x), or a table's start in the tables (x, in units of BSDF_TABLE_ALIGN floats) and its size (y: a measured
 * table's nodes per axis, a named metal's reflectance table's rows; a MERL table's shape is MERL_*);
 * `table` points at that start (measured, MERL and tabulated-conductor lobes only). */
typedef struct {
    int kind;
    float3 scale, tint, eta, k;
    float ax, ay;  /* GGX widths, at least 1e-4 as microfacet.GGX keeps them */
    float2 extra;
    int smooth;
    __global const float *table;
} Lobe;

/* A hit's BSDF: its first lobe alone where amount is 0, else (1 - amount) first + amount second
 * (mix.WeightedSum with lobe chances 1 - amount and amount); lobe[1] is lobe[0] where amount is 0.
 * Where `tree` is not 0 (a mix holding a mix: kernels/bounce.cl and the bsdf kernel below set it),
 * the BSDF is that BSDF_TREE row instead (tree_eval, tree_sample), its lobes' tables in `tables`. */
typedef struct {
    Lobe lobe[2];
    float amount;
    __global const float *tree;
    __global const float *tables;
} Params;

inline Lobe load_lobe(__global const float *row, __global const float *tables) {
    Lobe p;
    p.kind = (int)row[BSDF_PARAM_KIND];
    p.scale = vload3(0, row + BSDF_PARAM_SCALE);
    p.tint = vload3(0, row + BSDF_PARAM_TINT);
    p.eta = vload3(0, row + BSDF_PARAM_ETA);
    p.k = vload3(0, row + BSDF_PARAM_K);
    float ax = row[BSDF_PARAM_ALPHA], ay = row[BSDF_PARAM_ALPHA + 1];
    p.extra = vload2(0, row + BSDF_PARAM_EXTRA);
    /* rough glass of index 1 refracts straight through: smooth, as rough_dielectric.RoughDielectric;
     * FresnelBlend samples its GGX however narrow (substrate.FresnelBlend) */
    p.smooth = p.kind != KIND_SUBSTRATE
               && (fmax(ax, ay) < SMOOTH_ALPHA || (p.kind == KIND_ROUGH_DIELECTRIC && p.eta.x == 1.0f));
    p.ax = fmax(ax, 1e-4f);
    p.ay = fmax(ay, 1e-4f);
    int tabulated = p.kind == KIND_MEASURED || p.kind == KIND_MERL || p.kind == KIND_TABULATED_CONDUCTOR;
    p.table = tables + (tabulated ? (size_t)p.extra.x * BSDF_TABLE_ALIGN : 0);
    return p;
}

/* A hit's row; `tables` holds the tables and mixes' second lobes (the host's TableStore). */
inline Params load_params(__global const float *row, __global const float *tables) {
    Params p;
    p.lobe[0] = load_lobe(row, tables);
    p.amount = row[BSDF_PARAM_AMOUNT];
    p.lobe[1] = p.amount > 0.0f ? load_lobe(tables + (size_t)row[BSDF_PARAM_SECOND] * BSDF_TABLE_ALIGN, tables)
                                : p.lobe[0];
    p.tree = 0;
    p.tables = tables;
    return p;
}

/* The squared cosine of the direction refracted at cosine c with index ratio eta_i / eta_t, 1 - ratio^2
 * (1 - c^2) summed as (1 - ratio^2) + ratio^2 c^2, which keeps grazing directions' digits at ratio 1
 * (negative: total internal reflection). */
inline float refracted_cos2(float ratio, float c) {
    float r2 = ratio * ratio;
    return (1.0f - r2) + r2 * (c * c);
}

/* fresnel.dielectric: reflectance from outside (index 1) into eta at cosine c (negative: inside). */
inline float fresnel_dielectric(float c, float eta) {
    c = clamp(c, -1.0f, 1.0f);
    int entering = c > 0.0f;
    float eta_i = entering ? 1.0f : eta, eta_t = entering ? eta : 1.0f;
    c = fabs(c);
    float cos2_t = refracted_cos2(eta_i / eta_t, c);
    if (cos2_t <= 0.0f) return 1.0f;
    float cos_t = sqrt(cos2_t);
    float r_par = (eta_t * c - eta_i * cos_t) / (eta_t * c + eta_i * cos_t);
    float r_perp = (eta_i * c - eta_t * cos_t) / (eta_i * c + eta_t * cos_t);
    float r = 0.5f * (r_par * r_par + r_perp * r_perp);
    return isnan(r) ? 1.0f : r;
}

/* 1 - fresnel_dielectric(c, eta) for light arriving from outside (c >= 0), as 1 - r^2 = (1 - r)(1 + r)
 * per polarisation: no cancellation at grazing angles, where the reflectance nears 1. */
inline float fresnel_transmittance(float c, float eta) {
    c = clamp(c, 0.0f, 1.0f);
    float sin_t = sqrt(fmax(0.0f, 1.0f - c * c)) / eta;
    if (sin_t >= 1.0f) return 0.0f;
    float cos_t = sqrt(fmax(0.0f, 1.0f - sin_t * sin_t));
    float a = eta * c, b = cos_t, d = eta * cos_t;
    float t_par = 2.0f * a * b / ((a + b) * (a + b)), t_perp = 2.0f * c * d / ((c + d) * (c + d));
    float t = t_par + t_perp;
    return isnan(t) ? 0.0f : t;
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

/* fresnel.tabulated: a named metal's RGB reflectance (its table's rows at evenly spaced cosines over
 * [0, 1], linear between them) at |c|, in the rays' channels (the rows of the host's matrix in
 * tint, eta and k). */
inline float3 tabulated_reflectance(const Lobe *p, float c) {
    int last = (int)p->extra.y - 1;
    float x = clamp(fabs(c), 0.0f, 1.0f) * (float)last;
    int i = min((int)x, last - 1);
    float t = x - (float)i;
    float3 rgb = vload3(i, p->table) * (1.0f - t) + vload3(i + 1, p->table) * t;
    return (float3)(dot(p->tint, rgb), dot(p->eta, rgb), dot(p->k, rgb));
}

/* The microfacet lobe's colour times its Fresnel at cosine c: the conductor's (eta + i k, or a named
 * metal's table), the plastic or coated-diffuse coat's (tint, dielectric eta.x), or the mirror's (none). */
inline float3 reflected(const Lobe *p, float c) {
    if (p->kind == KIND_CONDUCTOR) return p->scale * fresnel_conductor(c, p->eta, p->k);
    if (p->kind == KIND_TABULATED_CONDUCTOR) return p->scale * tabulated_reflectance(p, c);
    if (p->kind == KIND_PLASTIC || p->kind == KIND_COATED_DIFFUSE) return p->tint * fresnel_dielectric(c, p->eta.x);
    return p->scale;
}

inline float ggx_d(const Lobe *p, float3 wh) {
    if (wh.z <= 0.0f) return 0.0f;
    float x = wh.x / p->ax, y = wh.y / p->ay;
    float den = x * x + y * y + wh.z * wh.z;
    return 1.0f / (PI_F * p->ax * p->ay * den * den);
}

inline float ggx_lambda(const Lobe *p, float3 w) {
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
inline float3 ggx_sample_visible(const Lobe *p, float3 wo, float u0, float u1) {
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
inline float3 microfacet_eval(const Lobe *p, float3 wo, float3 wi, float *pdf) {
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

/* The two-lobe kinds' chance of the diffuse lobe at wo (diffuse transmission's: of reflection):
 * plastic's and diffuse transmission's the colours' means, normalised; coated diffuse's the
 * base's share (1 - F(|cos_o|)) times its albedo estimate against the coat's F(|cos_o|)
 * (factory.bsdf_for's chances); a half where both are 0. */
inline float diffuse_chance(const Lobe *p, float3 wo) {
    float m0, m1;
    if (p->kind == KIND_COATED_DIFFUSE) {
        float t = fresnel_transmittance(fabs(wo.z), p->eta.x);
        m0 = t * p->extra.x;
        m1 = 1.0f - t;
    } else {
        m0 = (p->scale.x + p->scale.y + p->scale.z) / 3.0f;
        m1 = (p->tint.x + p->tint.y + p->tint.z) / 3.0f;
    }
    return m0 + m1 > 0.0f ? m0 / (m0 + m1) : 0.5f;
}

/* oren_nayar.OrenNayar.evaluate without the albedo and the side test: (A + B term) / pi. */
inline float oren_nayar_shape(const Lobe *p, float3 wo, float3 wi) {
    float cos_i = fabs(wi.z), cos_o = fabs(wo.z);
    float sin_i = sqrt(fmax(0.0f, 1.0f - cos_i * cos_i)), sin_o = sqrt(fmax(0.0f, 1.0f - cos_o * cos_o));
    float term = 0.0f;
    if (sin_i > 1e-4f && sin_o > 1e-4f) {
        float cos_dphi = (wi.x * wo.x + wi.y * wo.y) / (sin_i * sin_o);
        int incident_steeper = cos_i > cos_o;
        float sin_alpha = incident_steeper ? sin_o : sin_i;
        float tan_beta = incident_steeper ? sin_i / cos_i : sin_o / cos_o;
        term = fmax(0.0f, cos_dphi) * sin_alpha * tan_beta;
    }
    return (p->extra.x + p->extra.y * term) / PI_F;
}

/* A measured table's RGB at a pair on one side (measured._table_loop): BRDFRemap, delta phi the angle
 * between the two azimuths, then the trilinear interpolation of the cell's eight nodes. */
inline float3 measured_rgb(const Lobe *p, float3 wo, float3 wi) {
    float cos_o = wo.z, cos_i = wi.z;
    /* 1 - c^2 as (1 - c)(1 + c): near the normal, where 1 - c^2 would cancel, 1 - c is exact */
    float sin_o = sqrt(fmax(0.0f, (1.0f - cos_o) * (1.0f + cos_o)));
    float sin_i = sqrt(fmax(0.0f, (1.0f - cos_i) * (1.0f + cos_i)));
    float dphi;
    if ((wo.x != 0.0f || wo.y != 0.0f) && (wi.x != 0.0f || wi.y != 0.0f)) {
        dphi = atan2(fabs(wo.x * wi.y - wo.y * wi.x), wo.x * wi.x + wo.y * wi.y);
    } else {  /* along the normal: pbrt's azimuth atan2(0, 0) = 0 */
        dphi = fmod(atan2(wi.y, wi.x) - atan2(wo.y, wo.x), 2.0f * PI_F);
        dphi = dphi < 0.0f ? dphi + 2.0f * PI_F : dphi;
        dphi = dphi > PI_F ? 2.0f * PI_F - dphi : dphi;
    }
    int n = (int)p->extra.y, last = n - 1;
    float top = (float)last;
    float gx = clamp(sin_i * sin_o * top, 0.0f, top), gy = clamp(dphi / PI_F * top, 0.0f, top);
    float gz = clamp(cos_i * cos_o * top, 0.0f, top);
    int ix = min((int)gx, last - 1), iy = min((int)gy, last - 1), iz = min((int)gz, last - 1);
    float fx = gx - ix, fy = gy - iy, fz = gz - iz;
    __global const float *t = p->table;
    size_t sx = (size_t)n * n * 3, sy = (size_t)n * 3, at = ix * sx + iy * sy + iz * 3;
    float3 c00 = vload3(0, t + at) * (1.0f - fx) + vload3(0, t + at + sx) * fx;
    float3 c01 = vload3(0, t + at + 3) * (1.0f - fx) + vload3(0, t + at + sx + 3) * fx;
    float3 c10 = vload3(0, t + at + sy) * (1.0f - fx) + vload3(0, t + at + sx + sy) * fx;
    float3 c11 = vload3(0, t + at + sy + 3) * (1.0f - fx) + vload3(0, t + at + sx + sy + 3) * fx;
    return (c00 * (1.0f - fy) + c10 * fy) * (1.0f - fz) + (c01 * (1.0f - fy) + c11 * fy) * fz;
}

/* REMAP of pbrt-v2's RegularHalfangleBRDF::f: the bin of v in [0, top) cut into count, truncated
 * and clamped to the table. */
inline int merl_bin(double v, double top, int count) {
    double at = v / top * count;
    return at < 0.0 ? 0 : (at >= count ? count - 1 : (int)at);
}

/* A MERL table's RGB at a pair on one side (measured.halfangle_lookup, pbrt-v2's RegularHalfangleBRDF::f
 * in src/core/reflection.cpp): the pair mirrored so that the half vector wh faces +z, wi in wh's frame
 * giving theta_d and phi_d (folded into [0, pi)), theta_h's bin from sqrt(theta_h / (pi / 2)). In
 * double, in numpy's order and unfused, so that both pick the same bin (float32 acos near 1 could not
 * tell theta_h's first bins, 0.011 degrees wide, apart). */
inline float3 merl_rgb(const Lobe *p, float3 wo_f, float3 wi_f) {
#pragma OPENCL FP_CONTRACT OFF
    double3 wi = convert_double3(wi_f), wh = convert_double3(wo_f) + wi;
    if (wh.z < 0.0) {
        wi = -wi;
        wh = -wh;
    }
    double length = sqrt(wh.x * wh.x + wh.y * wh.y + wh.z * wh.z);
    if (!(length > 0.0)) return (float3)(0.0f);
    wh = wh / length;
    double cos_h = clamp(wh.z, -1.0, 1.0), sin_h = sqrt(fmax(0.0, 1.0 - cos_h * cos_h));
    double cos_phi = sin_h > 0.0 ? clamp(wh.x / sin_h, -1.0, 1.0) : 1.0;
    double sin_phi = sin_h > 0.0 ? clamp(wh.y / sin_h, -1.0, 1.0) : 0.0;
    double dx = wi.x * (cos_phi * cos_h) + wi.y * (sin_phi * cos_h) + wi.z * -sin_h;
    double dy = wi.x * -sin_phi + wi.y * cos_phi;
    double dz = wi.x * wh.x + wi.y * wh.y + wi.z * wh.z;
    double phi_d = atan2(dy, dx);
    phi_d = phi_d < 0.0 ? phi_d + 2.0 * M_PI : phi_d;
    phi_d = phi_d > M_PI ? phi_d - M_PI : phi_d;
    int i_h = merl_bin(sqrt(fmax(0.0, acos(cos_h) / (M_PI / 2.0))), 1.0, MERL_THETA_H);
    int i_d = merl_bin(acos(clamp(dz, -1.0, 1.0)), M_PI / 2.0, MERL_THETA_D);
    int i_phi = merl_bin(phi_d, M_PI, MERL_PHI_D);
    return vload3(i_phi + MERL_PHI_D * (i_d + MERL_THETA_D * i_h), p->table);
}

/* The diffuse lobe of a kind that has one, for a pair on one side: Lambertian and plastic albedo /
 * pi, Oren-Nayar, coated diffuse's base (coated_diffuse.CoatedLambertian: k the host's scale,
 * times the coat's transmittance both ways), a measured or MERL table's RGB in the rays' channels
 * (the rows of the host's matrix in scale, tint and eta). */
inline float3 diffuse_value(const Lobe *p, float3 wo, float3 wi) {
    if (p->kind == KIND_OREN_NAYAR) return p->scale * oren_nayar_shape(p, wo, wi);
    if (p->kind == KIND_MEASURED || p->kind == KIND_MERL) {
        float3 rgb = p->kind == KIND_MERL ? merl_rgb(p, wo, wi) : measured_rgb(p, wo, wi);
        return (float3)(dot(p->scale, rgb), dot(p->tint, rgb), dot(p->eta, rgb));
    }
    if (p->kind == KIND_COATED_DIFFUSE)
        return p->k * (fresnel_transmittance(fabs(wi.z), p->eta.x) * fresnel_transmittance(fabs(wo.z), p->eta.x));
    return p->scale * (1.0f / PI_F);
}

/* Rough glass (rough_dielectric.RoughDielectric._lobes): f and the pdf of the pair wo, wi about the
 * microfacet normal wm (+z side); zero where wm faces away from either and on smooth lobes. */
inline float3 rough_dielectric_lobes(const Lobe *p, float3 wo, float3 wi, float3 wm, float *pdf) {
    *pdf = 0.0f;
    float eta = p->eta.x, cos_o = wo.z, cos_i = wi.z;
    int reflect = cos_o * cos_i > 0.0f;
    float etap = reflect ? 1.0f : (cos_o > 0.0f ? eta : 1.0f / eta);
    float o_m = dot(wo, wm), i_m = dot(wi, wm);
    if (p->smooth || cos_o == 0.0f || cos_i == 0.0f || !(i_m * cos_i > 0.0f) || !(o_m * cos_o > 0.0f))
        return (float3)(0.0f);
    float f_r = fresnel_dielectric(o_m, eta);
    float d = ggx_d(p, wm), lo = ggx_lambda(p, wo);
    float g = 1.0f / (1.0f + lo + ggx_lambda(p, wi));
    float visible = 1.0f / (1.0f + lo) / fabs(cos_o) * d * fabs(o_m);
    float f, density;
    if (reflect) {
        f = d * g * f_r / fabs(4.0f * cos_i * cos_o);
        density = visible / (4.0f * fabs(o_m)) * f_r;
    } else {
        float root = i_m + o_m / etap, denom = root * root;
        f = d * g * (1.0f - f_r) * fabs(i_m * o_m / (cos_i * cos_o * denom));
        density = visible * fabs(i_m) / denom * (1.0f - f_r);
    }
    if (!isfinite(f) || !isfinite(density)) return (float3)(0.0f);
    *pdf = density;
    return (reflect ? p->scale : p->tint) * f;
}

/* The generalised half vector of a pair (RoughDielectric._half_vector), turned to +z; zero where undefined. */
inline float3 rough_dielectric_half(const Lobe *p, float3 wo, float3 wi) {
    int reflect = wo.z * wi.z > 0.0f;
    float etap = reflect ? 1.0f : (wo.z > 0.0f ? p->eta.x : 1.0f / p->eta.x);
    float3 wm = wi * etap + wo;
    float length = sqrt(dot(wm, wm));
    wm = length > 0.0f ? wm / length : (float3)(0.0f);
    return wm.z < 0.0f ? -wm : wm;
}

/* 1 - (1 - x)^5 expanded (no cancellation at grazing angles, where x is near 0). */
inline float one_minus_fifth(float x) {
    return x * (5.0f + x * (-10.0f + x * (10.0f + x * (-5.0f + x))));
}

/* FresnelBlend (substrate.FresnelBlend.evaluate and .pdf). */
inline float3 substrate_eval(const Lobe *p, float3 wo, float3 wi, float *pdf) {
    *pdf = 0.0f;
    if (!(wo.z * wi.z > 0.0f)) return (float3)(0.0f);
    float flip = wo.z < 0.0f ? -1.0f : 1.0f;
    float3 wo_up = wo * flip, wi_up = wi * flip;
    float cos_i = wi_up.z, cos_o = wo_up.z;
    float diffuse = 28.0f / (23.0f * PI_F) * one_minus_fifth(0.5f * cos_i) * one_minus_fifth(0.5f * cos_o);
    float3 h = wo_up + wi_up;
    float3 value = p->scale * (1.0f - p->tint) * diffuse;
    float glossy = 0.0f;
    if (dot(h, h) > 1e-20f) {
        float3 wh = normalize(h);
        float cos_h = dot(wi_up, wh), d = ggx_d(p, wh);
        float shape = d / (4.0f * fabs(cos_h) * fmax(cos_i, cos_o));
        float m = 1.0f - clamp(fabs(cos_h), 0.0f, 1.0f);
        float m5 = m * m * m * m * m;
        if (isfinite(shape)) value += (p->tint + m5 * (1.0f - p->tint)) * shape;
        glossy = d / (1.0f + ggx_lambda(p, wo_up)) / (4.0f * fmax(cos_o, 1e-30f));
        if (!isfinite(glossy)) glossy = 0.0f;
    }
    *pdf = 0.5f * (fabs(wi.z) / PI_F + glossy);
    return value;
}

/* diffuse_transmission.DiffuseTransmission.evaluate and .pdf: scale / pi for a pair on one side,
 * tint / pi for a pair on opposite sides, each side's pdf its chance (diffuse_chance: the means of
 * scale and tint) times the cosine density; zero where wi lies in the surface. */
inline float3 diffuse_transmission_eval(const Lobe *p, float3 wo, float3 wi, float *pdf) {
    float side = wo.z * wi.z, reflect = diffuse_chance(p, wo);
    float chance = side > 0.0f ? reflect : (side < 0.0f ? 1.0f - reflect : 0.0f);
    *pdf = chance * fabs(wi.z) / PI_F;
    return side > 0.0f ? p->scale / PI_F : (side < 0.0f ? p->tint / PI_F : (float3)(0.0f));
}

/* One lobe's f(wo, wi) and the sampling pdf of wi. */
inline float3 lobe_eval(const Lobe *p, float3 wo, float3 wi, float *pdf) {
    float same = wo.z * wi.z > 0.0f ? 1.0f : 0.0f;
    switch (p->kind) {
    case KIND_DIFFUSE_TRANSMISSION:
        return diffuse_transmission_eval(p, wo, wi, pdf);
    case KIND_LAMBERTIAN:
    case KIND_OREN_NAYAR:
    case KIND_MEASURED:
    case KIND_MERL:
        *pdf = same * fabs(wi.z) / PI_F;
        return same > 0.0f ? diffuse_value(p, wo, wi) : (float3)(0.0f);
    case KIND_DIELECTRIC:
    case KIND_THIN_DIELECTRIC:
        *pdf = 0.0f;
        return (float3)(0.0f);
    case KIND_ROUGH_DIELECTRIC:
        return rough_dielectric_lobes(p, wo, wi, rough_dielectric_half(p, wo, wi), pdf);
    case KIND_SUBSTRATE:
        return substrate_eval(p, wo, wi, pdf);
    default:
        break;
    }
    float coat_pdf;
    float3 f = microfacet_eval(p, wo, wi, &coat_pdf);
    if (p->kind != KIND_PLASTIC && p->kind != KIND_COATED_DIFFUSE) {
        *pdf = coat_pdf;
        return f;
    }
    float c0 = diffuse_chance(p, wo);
    *pdf = c0 * (same * fabs(wi.z) / PI_F) + (1.0f - c0) * coat_pdf;
    return same > 0.0f ? diffuse_value(p, wo, wi) + f : f;
}

/* A mix's lobe chances (mix.WeightedSum.chances): 1 - amount and amount, normalised. */
inline float2 amount_chances(float amount) {
    float2 c = (float2)(1.0f - amount, amount);
    float total = c.x + c.y;
    return total > 0.0f ? c / total : (float2)(0.5f);
}

inline float2 mix_chances(const Params *p) { return amount_chances(p->amount); }

/* Leaf k of a BSDF_TREE row. */
inline Lobe tree_lobe(__global const float *tree, int k, __global const float *tables) {
    return load_lobe(tree + BSDF_TREE_LOBES + (size_t)k * BSDF_LOBE_WIDTH, tables);
}

/* f(wo, wi) and the sampling pdf of wi of a mix holding a mix (a BSDF_TREE row), as bsdf_for's nested
 * mix.WeightedSum gives them: each mix (1 - amount) f_first + amount f_second and chances c_first
 * pdf_first + c_second pdf_second (amount_chances), its materials' first, the last mix first (each
 * mix's materials come after it); node_pdf[n]: mix n's pdf, which tree_sample's validity reads. */
inline float3 tree_eval(__global const float *tree, __global const float *tables, float3 wo, float3 wi, float *pdf,
                        float *node_pdf) {
    float3 node_f[BSDF_MAX_LOBES - 1];
    for (int n = (int)tree[BSDF_TREE_NODES] - 1; n >= 0; n--) {
        float3 f[2];
        float part_pdf[2];
        for (int side = 0; side < 2; side++) {
            int code = (int)tree[(side ? BSDF_TREE_SECOND : BSDF_TREE_FIRST) + n];
            if (code >= 0) {
                f[side] = node_f[code];
                part_pdf[side] = node_pdf[code];
            } else {
                Lobe lobe = tree_lobe(tree, -1 - code, tables);
                f[side] = lobe_eval(&lobe, wo, wi, &part_pdf[side]);
            }
        }
        float amount = tree[BSDF_TREE_AMOUNT + n];
        float2 c = amount_chances(amount);
        node_pdf[n] = c.x * part_pdf[0] + c.y * part_pdf[1];
        node_f[n] = (1.0f - amount) * f[0] + amount * f[1];
    }
    *pdf = node_pdf[0];
    return node_f[0];
}

/* f(wo, wi) and the sampling pdf of wi. */
inline float3 bsdf_eval(const Params *p, float3 wo, float3 wi, float *pdf) {
    if (p->tree) {
        float node_pdf[BSDF_MAX_LOBES - 1];
        return tree_eval(p->tree, p->tables, wo, wi, pdf, node_pdf);
    }
    if (!(p->amount > 0.0f)) return lobe_eval(&p->lobe[0], wo, wi, pdf);
    float pdf0, pdf1;
    float2 c = mix_chances(p);
    float3 f0 = lobe_eval(&p->lobe[0], wo, wi, &pdf0), f1 = lobe_eval(&p->lobe[1], wo, wi, &pdf1);
    *pdf = c.x * pdf0 + c.y * pdf1;
    return (1.0f - p->amount) * f0 + p->amount * f1;
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
inline float3 microfacet_direction(const Lobe *p, float3 wo, float u0, float u1) {
    if (p->smooth) return (float3)(-wo.x, -wo.y, wo.z);
    float flip = wo.z < 0.0f ? -1.0f : 1.0f;
    float3 wo_up = wo * flip;
    float3 wh = ggx_sample_visible(p, wo_up, u0, u1);
    return (-wo_up + 2.0f * dot(wo_up, wh) * wh) * flip;
}

/* Smooth or thin glass (dielectric.Dielectric.sample); smooth rough glass samples as smooth glass. */
inline float3 dielectric_sample(const Lobe *p, float3 wo, float u_lobe, float3 *value, float *pdf, int *valid) {
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
        float cos2_t = refracted_cos2(ratio, wo.z);
        ok = cos2_t > 0.0f;
        float cos_t = sqrt(fmax(0.0f, cos2_t));
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

/* Rough glass (RoughDielectric.sample): a visible normal wm on wo's side; reflect about it with
 * probability F(wo.wm), else refract through it. */
inline float3 rough_dielectric_sample(const Lobe *p, float3 wo, float u0, float u1, float u_lobe, float3 *value,
                                      float *pdf, int *valid) {
    float side = wo.z < 0.0f ? -1.0f : 1.0f, eta = p->eta.x;
    float3 wm = ggx_sample_visible(p, wo * side, u0, u1);
    float o_m = dot(wo, wm);
    int reflect = u_lobe < fresnel_dielectric(o_m, eta);
    int inside = o_m < 0.0f;
    float ratio = inside ? eta : 1.0f / eta, cos_i = fabs(o_m);
    float cos2_t = refracted_cos2(ratio, cos_i);
    float cos_t = sqrt(fmax(0.0f, cos2_t));
    float3 wi = reflect ? -wo + 2.0f * o_m * wm : -ratio * wo + (ratio * cos_i - cos_t) * (inside ? -wm : wm);
    int same = wi.z * wo.z > 0.0f;
    *value = rough_dielectric_lobes(p, wo, wi, wm, pdf);
    *valid = (reflect ? same : !same && wi.z != 0.0f && cos2_t > 0.0f) && *pdf > 0.0f;
    return wi;
}

/* One lobe's sample from u0, u1 and u_lobe: its direction, value, pdf, whether specular and valid,
 * as the lobe's numpy ``sample`` gives them. */
inline float3 lobe_sample(const Lobe *p, float3 wo, float u0, float u1, float ul, float3 *value, float *pdf,
                          int *specular, int *valid) {
    if (p->kind == KIND_DIELECTRIC || p->kind == KIND_THIN_DIELECTRIC
        || (p->kind == KIND_ROUGH_DIELECTRIC && p->smooth)) {
        *specular = 1;
        return dielectric_sample(p, wo, ul, value, pdf, valid);
    }
    *specular = 0;
    if (p->kind == KIND_ROUGH_DIELECTRIC) return rough_dielectric_sample(p, wo, u0, u1, ul, value, pdf, valid);
    float3 wi;
    /* diffuse transmission: the cosine on wo's side, turned through from the reflection's chance up */
    if (p->kind == KIND_DIFFUSE_TRANSMISSION) {
        wi = cosine_on_side(wo, u0, u1);
        wi.z = ul < diffuse_chance(p, wo) ? wi.z : -wi.z;
        *value = diffuse_transmission_eval(p, wo, wi, pdf);
        *valid = *pdf > 0.0f;
        return wi;
    }
    if (p->kind == KIND_SUBSTRATE) {  /* half the time the cosine, else the GGX visible normals */
        wi = ul < 0.5f ? cosine_on_side(wo, u0, u1) : microfacet_direction(p, wo, u0, u1);
        *value = substrate_eval(p, wo, wi, pdf);
        *valid = *pdf > 0.0f;
        return wi;
    }
    /* plastic and coated diffuse: the diffuse lobe below the diffuse chance, else the coat (mix.WeightedSum) */
    int two = p->kind == KIND_PLASTIC || p->kind == KIND_COATED_DIFFUSE;
    int diffuse = p->kind == KIND_LAMBERTIAN || p->kind == KIND_OREN_NAYAR || p->kind == KIND_MEASURED
                  || p->kind == KIND_MERL || (two && ul < diffuse_chance(p, wo));
    wi = diffuse ? cosine_on_side(wo, u0, u1) : microfacet_direction(p, wo, u0, u1);
    *specular = !diffuse && p->smooth;
    *value = lobe_eval(p, wo, wi, pdf);
    if (*specular) {
        float c = fabs(wo.z);
        *value = c > 0.0f ? reflected(p, c) / c : (float3)(0.0f);
        *pdf = two ? 1.0f - diffuse_chance(p, wo) : 1.0f;
    }
    /* the sampled lobe's own validity: a diffuse lobe's pdf positive; a microfacet lobe's pdf
     * positive (1 where smooth) and wi on wo's side */
    float lobe_pdf = 1.0f;
    if (!diffuse && !*specular) microfacet_eval(p, wo, wi, &lobe_pdf);
    int side = wo.z * wi.z > 0.0f;
    *valid = *pdf > 0.0f && side && (diffuse ? wi.z != 0.0f : lobe_pdf > 0.0f && wo.z != 0.0f);
    return wi;
}

/* A mix holding a mix's BSDF sample (a BSDF_TREE row), as bsdf_for's nested mix.WeightedSum.sample
 * draws it: from the root down, each mix picks its first or second material with u_lobe and hands it
 * u_lobe rescaled within its share, down to a lobe, which samples with what is left of it; the value
 * and pdf are then the whole tree's (tree_eval), or for a specular sample the lobe's times each mix's
 * weight and chance on the way, the innermost first; valid where the lobe's sample is and each mix's
 * pdf on the way (of the sampled direction, or for a specular sample its product so far) is positive,
 * as each WeightedSum.sample checks its own. */
inline float3 tree_sample(const Params *p, float3 wo, float u0, float u1, float ul, float3 *value, float *pdf,
                          int *flags) {
    __global const float *tree = p->tree;
    int on_the_way[BSDF_MAX_LOBES - 1];
    float weight[BSDF_MAX_LOBES - 1], chance_of[BSDF_MAX_LOBES - 1];
    int levels = 0, code = 0;
    while (code >= 0 && levels < BSDF_MAX_LOBES - 1) {
        float amount = tree[BSDF_TREE_AMOUNT + code];
        float2 c = amount_chances(amount);
        int second = ul >= c.x;
        float chance = second ? c.y : c.x, start = second ? (c.x + c.y) - c.y : 0.0f;  /* numpy's cumsum - chance */
        ul = clamp((ul - start) / fmax(chance, 1e-12f), 0.0f, 1.0f - 1e-7f);
        on_the_way[levels] = code;
        weight[levels] = second ? amount : 1.0f - amount;
        chance_of[levels++] = chance;
        code = (int)tree[(second ? BSDF_TREE_SECOND : BSDF_TREE_FIRST) + code];
    }
    Lobe lobe = tree_lobe(tree, -1 - code, p->tables);
    int specular, valid;
    float3 wi = lobe_sample(&lobe, wo, u0, u1, ul, value, pdf, &specular, &valid);
    if (specular) {
        for (int k = levels - 1; k >= 0; k--) {
            *value = weight[k] * *value;
            *pdf = chance_of[k] * *pdf;
            valid = valid && *pdf > 0.0f;
        }
    } else {
        float node_pdf[BSDF_MAX_LOBES - 1];
        *value = tree_eval(tree, p->tables, wo, wi, pdf, node_pdf);
        for (int k = 0; k < levels; k++) valid = valid && node_pdf[on_the_way[k]] > 0.0f;
    }
    *flags = specular | (valid << 1);
    return wi;
}

/* The BSDF sample: a mix picks its lobe with u_lobe and hands the lobe u_lobe rescaled within its
 * share (mix.WeightedSum.sample); the value and pdf are then the whole mix's, or for a specular
 * sample the lobe's times its weight and chance. flags: bit 0 specular, bit 1 valid. The bsdf kernel
 * below and kernels/bounce.cl (the path integrator's fused bounce) both draw through it. */
inline float3 bsdf_sample(const Params *p, float3 wo, float u0, float u1, float ul, float3 *value, float *pdf,
                          int *flags) {
    if (p->tree) return tree_sample(p, wo, u0, u1, ul, value, pdf, flags);
    int specular, valid;
    float3 wi;
    if (!(p->amount > 0.0f)) {
        wi = lobe_sample(&p->lobe[0], wo, u0, u1, ul, value, pdf, &specular, &valid);
    } else {
        float2 c = mix_chances(p);
        int second = ul >= c.x;
        float chance = second ? c.y : c.x, start = second ? (c.x + c.y) - c.y : 0.0f;  /* numpy's cumsum - chance */
        float u_rest = clamp((ul - start) / fmax(chance, 1e-12f), 0.0f, 1.0f - 1e-7f);
        float3 lobe_value;
        float lobe_pdf;
        wi = lobe_sample(&p->lobe[second], wo, u0, u1, u_rest, &lobe_value, &lobe_pdf, &specular, &valid);
        if (specular) {
            *value = (second ? p->amount : 1.0f - p->amount) * lobe_value;
            *pdf = chance * lobe_pdf;
        } else {
            *value = bsdf_eval(p, wo, wi, pdf);
        }
        valid = valid && *pdf > 0.0f;
    }
    *flags = specular | (valid << 1);
    return wi;
}

/* Row i of `params` (row_width floats each) is hit i's BSDF_PARAM row, followed where its kind is
 * KIND_TREE (a mix holding a mix) by the hit's BSDF_TREE row, which is then its BSDF. */
__kernel void bsdf(uint n, uint lights, __global const float *params, uint row_width, __global const float *tables,
                   __global const float *wo_in,
                   __global const float *light_wi, __global const float *u, __global const float *u_lobe,
                   __global float *light_f, __global float *light_pdf, __global float *wi_out,
                   __global float *value_out, __global float *pdf_out, __global int *flags_out) {
    uint i = get_global_id(0);
    if (i >= n) return;
    __global const float *row = params + (size_t)i * row_width;
    Params p = load_params(row, tables);
    if ((int)row[BSDF_PARAM_KIND] == KIND_TREE) p.tree = row + BSDF_PARAM_WIDTH;
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
