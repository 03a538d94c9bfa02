/* EWA texture lookups on a MIP map, one work-item per lookup: the same mathematics as
 * realistic/scene/mipmap.py (MipMap.ewa, its numpy reference), after pbrt-v3 src/core/mipmap.h
 * (MIPMap::EWA): eccentricity clamped to max_anisotropy, level from the minor axis, two levels
 * blended, each a sum over the texels inside the ellipse weighted by a 128-entry table of
 * exp(-2 r^2) - exp(-2). Double precision (PoCL's CPU device has cl_khr_fp64) so the taps
 * inside the ellipse and their table entries are those of the float64 reference.
 *
 * Texels: every level's RGB rows, level after level, in one float array (MipMap._texels);
 * level k has width[k] x height[k] texels starting at texel base[k]. wrap: 0 repeat, 1 black,
 * 2 clamp (validation.TEXTURE_WRAPS's order).
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#define LUT_SIZE 128

inline double3 texel(__global const float *texels, __global const long *base, __global const long *width,
                     __global const long *height, int wrap, int level, int x, int y) {
    int w = (int)width[level], h = (int)height[level];
    double inside = 1.0;
    if (wrap == 0) {
        x %= w; if (x < 0) x += w;
        y %= h; if (y < 0) y += h;
    } else {
        if (wrap == 1 && (x < 0 || x >= w || y < 0 || y >= h)) inside = 0.0;
        x = clamp(x, 0, w - 1);
        y = clamp(y, 0, h - 1);
    }
    __global const float *p = texels + 3 * (base[level] + (long)y * w + x);
    return (double3)(p[0], p[1], p[2]) * inside;
}

inline double3 bilinear0(__global const float *texels, __global const long *base, __global const long *width,
                         __global const long *height, int wrap, double s, double t) {
    double x = s * width[0] - 0.5, y = t * height[0] - 0.5;
    double x0 = floor(x), y0 = floor(y);
    double fx = x - x0, fy = y - y0;
    int ix = (int)x0, iy = (int)y0;
    double3 top = texel(texels, base, width, height, wrap, 0, ix, iy) * (1 - fx)
                + texel(texels, base, width, height, wrap, 0, ix + 1, iy) * fx;
    double3 bottom = texel(texels, base, width, height, wrap, 0, ix, iy + 1) * (1 - fx)
                   + texel(texels, base, width, height, wrap, 0, ix + 1, iy + 1) * fx;
    return top * (1 - fy) + bottom * fy;
}

inline double3 ewa_level(__global const float *texels, __global const long *base, __global const long *width,
                         __global const long *height, int wrap, int levels, __global const double *lut,
                         long level, double s0, double t0_, double a0s, double a0t, double a1s, double a1t) {
    if (level >= levels) {
        __global const float *p = texels + 3 * base[levels - 1];
        return (double3)(p[0], p[1], p[2]);
    }
    double w = (double)width[level], h = (double)height[level];
    double s = s0 * w - 0.5, t = t0_ * h - 0.5;
    a0s *= w; a0t *= h; a1s *= w; a1t *= h;
    double a = a0t * a0t + a1t * a1t + 1;
    double b = -2 * (a0s * a0t + a1s * a1t);
    double c = a0s * a0s + a1s * a1s + 1;
    double inv_f = 1 / (a * c - b * b * 0.25);
    a *= inv_f; b *= inv_f; c *= inv_f;
    double det = 4 * a * c - b * b;
    double half_t = 2 * sqrt(a * det) / det;
    int y0 = (int)ceil(t - half_t), y1 = (int)floor(t + half_t);
    double3 sum = (double3)(0.0);
    double weights = 0.0;
    for (int y = y0; y <= y1; ++y) {
        double dt = y - t;
        double bb = b * dt;
        double root = sqrt(fmax(bb * bb - 4 * a * (c * dt * dt - 1), 0.0));
        int x0 = (int)ceil(s + (-bb - root) / (2 * a));
        int x1 = (int)floor(s + (-bb + root) / (2 * a));
        for (int x = x0; x <= x1; ++x) {
            double ds = x - s;
            double r2 = a * ds * ds + b * ds * dt + c * dt * dt;
            if (r2 < 1) {
                double weight = lut[min((int)(r2 * LUT_SIZE), LUT_SIZE - 1)];
                sum += texel(texels, base, width, height, wrap, (int)level, x, y) * weight;
                weights += weight;
            }
        }
    }
    return sum / fmax(weights, 1e-300);
}

__kernel void ewa(__global const float *texels, __global const long *base, __global const long *width,
                  __global const long *height, const int wrap, const int levels, const double max_anisotropy,
                  __global const double *lut, __global const double *st, __global const double *axis0,
                  __global const double *axis1, const int count, __global float *out) {
    int i = get_global_id(0);
    if (i >= count) return;
    double2 p = (double2)(st[2 * i], st[2 * i + 1]);
    double2 major = (double2)(axis0[2 * i], axis0[2 * i + 1]);
    double2 minor = (double2)(axis1[2 * i], axis1[2 * i + 1]);
    if (dot(major, major) < dot(minor, minor)) {
        double2 swap = major; major = minor; minor = swap;
    }
    double major_len = sqrt(dot(major, major)), minor_len = sqrt(dot(minor, minor));
    if (minor_len * max_anisotropy < major_len && minor_len > 0) {
        double stretch = major_len / fmax(minor_len * max_anisotropy, 1e-300);
        minor *= stretch;
        minor_len *= stretch;
    }
    double3 value;
    if (minor_len == 0) {
        value = bilinear0(texels, base, width, height, wrap, p.x, p.y);
    } else {
        double lod = fmax(0.0, levels - 1 + log2(fmax(minor_len, 1e-8)));
        double lower = floor(lod);
        double delta = lod - lower;
        value = ewa_level(texels, base, width, height, wrap, levels, lut, (long)lower, p.x, p.y,
                          major.x, major.y, minor.x, minor.y) * (1 - delta)
              + ewa_level(texels, base, width, height, wrap, levels, lut, (long)lower + 1, p.x, p.y,
                          major.x, major.y, minor.x, minor.y) * delta;
    }
    out[3 * i] = (float)value.x;
    out[3 * i + 1] = (float)value.y;
    out[3 * i + 2] = (float)value.z;
}
