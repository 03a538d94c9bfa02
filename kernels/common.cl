/* Functions kernels/lens.cl and kernels/shade.cl share; each includes it where it needs them
 * (a textual include the host expands: realistic.device.opencl.kernel_source). Random numbers: lowbias32 and the top 24 bits as a float, bit-identical to
 * realistic/core/rng.py, and the pieces of its light-sample Sobol' sequence; the concentric disk map of realistic/core/warp.py (float32 rounding). */

#define QUARTER_PI_F 0.785398163397448f

inline uint hash32(uint x) {
    x ^= x >> 16;
    x *= 0x7FEB352Du;
    x ^= x >> 15;
    x *= 0x846CA68Bu;
    x ^= x >> 16;
    return x;
}

/* The 32 bits of x in reverse order (realistic.core.rng.reverse_bits). */
inline __attribute__((always_inline)) uint reverse_bits(uint x) {
    x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
    x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
    x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
    x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
    return (x >> 16) | (x << 16);
}

/* Hashed Owen scramble of base-2 digits stored lowest bit first (realistic.core.rng.owen_scramble_digits). */
inline __attribute__((always_inline)) uint owen_scramble_digits(uint v, uint key) {
    v ^= v * 0x3D20ADEAu;
    v += key;
    v *= (key >> 16) | 1u;
    v ^= v * 0x05526C56u;
    v ^= v * 0x53A22864u;
    return v;
}

/* Sobol's second dimension of an index, digits lowest bit first: the XOR over bit supersets
 * (realistic.core.rng.sobol2_digits; the first dimension's digits are the index itself). */
inline __attribute__((always_inline)) uint sobol1_digits(uint x) {
    x ^= (x >> 1) & 0x55555555u;
    x ^= (x >> 2) & 0x33333333u;
    x ^= (x >> 4) & 0x0F0F0F0Fu;
    x ^= (x >> 8) & 0x00FF00FFu;
    x ^= (x >> 16) & 0x0000FFFFu;
    return x;
}

/* Top 24 bits as a float in [0, 1). */
inline float to_unit(uint bits) { return (float)(bits >> 8) * (1.0f / 16777216.0f); }

/* sin and cos of |x| <= pi/4 by Taylor polynomials (error below 3e-9, under float32 rounding). */
inline __attribute__((always_inline)) void sincos_quarter(float x, float *s, float *c) {
    float x2 = x * x;
    *s = x * (1.0f + x2 * (-1.0f / 6 + x2 * (1.0f / 120 + x2 * (-1.0f / 5040 + x2 * (1.0f / 362880)))));
    *c = 1.0f + x2 * (-0.5f + x2 * (1.0f / 24 + x2 * (-1.0f / 720 + x2 * (1.0f / 40320 + x2 * (-1.0f / 3628800)))));
}

/* Shirley-Chiu concentric map of [0,1)^2 onto the unit disk, as realistic.core.warp.concentric_disk.
 * |a| and |b| are computed by different instruction sequences on purpose: two isomorphic chains
 * from u1 and u2 into one comparison let LLVM's SLP vectoriser pack them (back to the hashes) into
 * 2-wide vectors before PoCL's work-group vectoriser runs, and that stops the latter (LLVM 14
 * cannot widen instructions that already have a vector type). The choices are bit masks rather
 * than comparisons and selects for the same reason: a kernel that maps several samples (lens.cl,
 * several rays per work item) gave SLP their comparisons to pack side by side. a and b are
 * multiples of 2^-23, so the sign of |b| - |a| is exactly whether |a| > |b|, and den is 0 only
 * where a = b = 0 (then the ratio is 0, not 0 / 0). */
inline __attribute__((always_inline)) void concentric_disk(float u1, float u2, float *x, float *y) {
    float a = 2.0f * u1 - 1.0f;
    float b = 2.0f * u2 - 1.0f;
    float abs_a = a < 0.0f ? -a : a;
    float abs_b = as_float(as_uint(b) & 0x7FFFFFFFu);
    int first = -(int)(as_uint(abs_b - abs_a) >> 31);  /* all ones where |a| > |b| */
    float num = as_float((as_int(b) & first) | (as_int(a) & ~first));
    float den = as_float((as_int(a) & first) | (as_int(b) & ~first));
    uint magnitude = as_uint(den) << 1;
    int nonzero = -(int)((magnitude | (0u - magnitude)) >> 31);
    float ratio = as_float(as_int(num / den) & nonzero);
    float s, c;
    sincos_quarter(QUARTER_PI_F * ratio, &s, &c);
    /* first: phi = pi/4 b/a, (cos, sin); else phi = pi/2 - pi/4 a/b, (cos, sin) = (sin, cos) */
    *x = den * as_float((as_int(c) & first) | (as_int(s) & ~first));
    *y = den * as_float((as_int(s) & first) | (as_int(c) & ~first));
}

/* cos(x) for 0 <= x <= 2 pi (the layer's phase for any wavelength above lambda0 / 2) as -cos(x - pi)
 * by its Taylor polynomial to the 18th power (error below 4e-9 for |x - pi| <= pi). One polynomial, not
 * sincos_quarter's pair and a choice of quadrant: the pair's twin chains were packed into 2-wide
 * vectors by LLVM's SLP vectoriser, and the choice became a switch; either stops PoCL's work-group
 * vectoriser. The coating layers' phase in kernels/lens.cl and kernels/ghost.cl. */
inline __attribute__((always_inline)) float cos_phase(float x) {
    float y = x - 3.14159265358979f;
    float y2 = y * y;
    return -(1.0f + y2 * (-0.5f + y2 * (1.0f / 24 + y2 * (-1.0f / 720 + y2 * (1.0f / 40320 + y2 * (-1.0f / 3628800 +
        y2 * (1.0f / 479001600 + y2 * (-1.0f / 87178291200.0f + y2 * (1.0f / 20922789888000.0f +
        y2 * (-1.0f / 6402373705728000.0f))))))))));
}

#ifdef CAMERA_SAMPLES
/* Camera sampling shared by the camera kernels, which define CAMERA_SAMPLES before including this
 * file (kernels/lens.cl, kernels/thin_lens.cl): a launch's sample addresses, R4's stratified values
 * (thin_lens.cl's; lens.cl has its own, with its SPECTRAL R5) and the pixel filter's film offsets.
 * The host defines FILTER_KIND, FILTER_RX, FILTER_RY and a tabulated filter's tables
 * (realistic.camera.opencl_host.filter_lines). */

#define R4_GOLDEN 0x9E3779B9u
#define R4_KRONECKER_0 0xDB4F0B91u
#define R4_KRONECKER_1 0xBBE05633u
#define R4_KRONECKER_2 0xA0F2EC76u
#define R4_KRONECKER_3 0x89E18285u

/* Pixel and sample index within the pixel of work item gid of a launch over a slice of each
 * pixel's samples (realistic.camera.base.SampleBlock): pixels get slice_width samples each, from
 * slice_start, and the launch starts `offset` pairs into pixel first_pixel's slice. The host keeps
 * offset < slice_width and checks offset + launch size < 2^32, so the uint sum cannot wrap. */
inline void sample_address(uint first_pixel, uint offset, uint slice_start, uint slice_width, uint gid,
                           uint *pixel, uint *sample) {
    uint s = offset + gid;
    uint q = s / slice_width;
    *pixel = first_pixel + q;
    *sample = slice_start + (s - q * slice_width);
}

/* realistic.core.rng.stratified4's uint32 values: film x, film y, lens u, lens v. */
inline void stratified4(uint pixel, uint sample, uint seed, uint *b0, uint *b1, uint *b2, uint *b3) {
    uint h = hash32(hash32(seed + R4_GOLDEN) ^ pixel);
    h = hash32(h ^ 0xFFFFFFFFu);
    *b0 = sample * R4_KRONECKER_0 + hash32(h ^ 0u);
    *b1 = sample * R4_KRONECKER_1 + hash32(h ^ 1u);
    *b2 = sample * R4_KRONECKER_2 + hash32(h ^ 2u);
    *b3 = sample * R4_KRONECKER_3 + hash32(h ^ 3u);
}

/* realistic.core.pixel_filter.PixelFilter.offsets along x and y: the offset in pixels from the
 * pixel centre and the sample's factor along that axis in *w. The box offset (u - 1/2) 2r is exact,
 * so the 0.5-radius box gives the plain in-pixel jitter bit for bit. The x and y versions compute
 * the same values by different instruction sequences on purpose: two isomorphic chains let LLVM's
 * SLP vectoriser pack them into 2-wide vectors, which stops PoCL's work-group vectoriser (a
 * several-fold slower kernel). */
#if FILTER_KIND == 0
inline __attribute__((always_inline)) float filter_offset_x(float u, float *w) { *w = 1.0f; return (u - 0.5f) * (2.0f * FILTER_RX); }
inline __attribute__((always_inline)) float filter_offset_y(float u, float *w) { *w = 1.0f; return (u - 0.5f) * (2.0f * FILTER_RY); }
#elif FILTER_KIND == 1
/* Inverse CDF of the tent max(0, r - |x|): -1 + sqrt(2u) below u = 1/2, 1 - sqrt(2 - 2u) above. */
inline __attribute__((always_inline)) float filter_offset_x(float u, float *w) {
    *w = 1.0f;
    int left = u < 0.5f;
    float root = __builtin_sqrtf(left ? 2.0f * u : 2.0f - 2.0f * u);
    return FILTER_RX * (left ? root - 1.0f : 1.0f - root);
}
/* The same: 1 - 2|u - 1/2| is 2u or 2 - 2u exactly, and the sign of u - 1/2 is the offset's. */
inline __attribute__((always_inline)) float filter_offset_y(float u, float *w) {
    *w = 1.0f;
    float s = u - 0.5f;
    float root = __builtin_sqrtf(1.0f - 2.0f * as_float(as_uint(s) & 0x7FFFFFFFu));
    return FILTER_RY * as_float(as_uint(1.0f - root) ^ (as_uint(s) & 0x80000000u));
}
#else
/* The bin k with CDF[k] <= u < CDF[k + 1] by a branch-free binary search, unrolled (a loop here
 * stops the work-group vectoriser too), then u's place inside the bin. The search's first step
 * reads the middle of a table, a literal (about 0.5) on both axes once the compiler folds the
 * constant tables: written alike, the two comparisons were packed by LLVM's SLP vectoriser into a
 * 2-wide vector, back through both random numbers' hashes, which stopped the work-group
 * vectoriser. u - c >= 0 is exactly u >= c in IEEE arithmetic, so y compares by the sign of a
 * difference. */
#if FILTER_BINS != 256
#error "the unrolled bin search below is written for 256 bins"
#endif
#define SEARCH_X(step) k = FILTER_CDF_X[k + step] <= u ? k + step : k;
#define SEARCH_Y(step) k += step & (uint)(-(int)(u - FILTER_CDF_Y[k + step] >= 0.0f));
inline __attribute__((always_inline)) float filter_offset_x(float u, float *w) {
    int k = 0;
    SEARCH_X(128) SEARCH_X(64) SEARCH_X(32) SEARCH_X(16) SEARCH_X(8) SEARCH_X(4) SEARCH_X(2) SEARCH_X(1)
    float lo = FILTER_CDF_X[k], hi = FILTER_CDF_X[k + 1];
    *w = FILTER_WEIGHT_X[k];
    return -FILTER_RX + ((float)k + (u - lo) / (hi - lo)) * (2.0f * FILTER_RX / FILTER_BINS);
}
inline __attribute__((always_inline)) float filter_offset_y(float u, float *w) {
    uint k = 0;
    SEARCH_Y(128) SEARCH_Y(64) SEARCH_Y(32) SEARCH_Y(16) SEARCH_Y(8) SEARCH_Y(4) SEARCH_Y(2) SEARCH_Y(1)
    float lo = FILTER_CDF_Y[k];
    float t = (u - lo) * (1.0f / (FILTER_CDF_Y[k + 1] - lo));
    *w = FILTER_WEIGHT_Y[k];
    return (float)k * (2.0f * FILTER_RY / FILTER_BINS) + (t * (2.0f * FILTER_RY / FILTER_BINS) - FILTER_RY);
}
#endif
#endif

#if defined(STOP_MASKED) && STOP_MASKED
/* The stop's image mask (the host's STOP_MASK table, row 0 at +y), at the nearest pixel: the lens
 * and ghost kernels' STOP_INSIDE for a stop given as an image (realistic.camera.opencl_host.stop_lines). */
inline int stop_mask(float x, float y) {
    float fc = (x * (1.0f / STOP_DIAMETER_MM) + 0.5f) * (float)STOP_MASK_W;
    float fr = (0.5f - y * (1.0f / STOP_DIAMETER_MM)) * (float)STOP_MASK_H;
    int inside = (fc >= 0.0f) & (fc < (float)STOP_MASK_W) & (fr >= 0.0f) & (fr < (float)STOP_MASK_H);
    int c = inside ? (int)fc : 0;
    int r = inside ? (int)fr : 0;
    return inside & (STOP_MASK[r * STOP_MASK_W + c] != 0);
}
#endif
