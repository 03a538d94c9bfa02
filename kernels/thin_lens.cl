/* Camera rays of pbrt's perspective camera, a pinhole or an ideal thin lens: sample id -> world-space
 * ray, weight, pixel.
 *
 * OpenCL 1.2 C, float32, one work item per sample id. The float64 numpy reference is
 * realistic.camera.thin_lens.ThinLensCamera.generate_rays; the random numbers (R4), the sample
 * addresses and the pixel filter's offsets are kernels/common.cl's CAMERA_SAMPLES section, the same
 * arithmetic as kernels/lens.cl's, and the aperture point is common.cl's concentric_disk. Written
 * for PoCL's work-group vectoriser as lens.cl is (no builtin calls, no loops, no early exits).
 *
 * The host (realistic/camera/thin_lens_host.py) prepends the pixel filter's FILTER_* defines and
 * tables (realistic.camera.opencl_host.filter_lines); everything else is a kernel argument, so
 * one build serves every field of view, resolution, focus and lens radius.
 */

#define CAMERA_SAMPLES 1
#include "common.cl"  /* expanded by the host (realistic.device.opencl.kernel_source) */

/* Rays of the sample block the host lays out (sample_address), one per work item. out holds 7 rows
 * of `stride` floats: origin x, y, z, direction x, y, z (unit), weight (the pixel filter's factor),
 * in world space. world is the camera-to-world matrix, rows of (m0 m1 m2 t). pixel_rows is 1 / width
 * in double (see lens.cl's start_ray: the pixel's row without an integer division); screen_x and
 * screen_y are the screen window's half extents times tan(fov / 2), so that raster (x, y) in [0, 1]
 * looks along ((2x - 1) screen_x, (1 - 2y) screen_y, 1); the aperture point is lens_radius times
 * the concentric disk's, and the ray aims at the point of that line at depth focal_distance (the
 * host passes 1 for a pinhole, whose lens_radius is 0: the direction is then the line's own). */
__kernel void generate_rays(uint first_pixel, uint offset, uint slice_start, uint slice_width, uint seed,
                            __constant float *world, uint width, double pixel_rows, float inv_width,
                            float inv_height, float screen_x, float screen_y, float lens_radius,
                            float focal_distance, uint stride, __global float *out, __global int *pixel_out) {
    uint gid = get_global_id(0);
    uint pixel, sample;
    sample_address(first_pixel, offset, slice_start, slice_width, gid, &pixel, &sample);
    uint b0, b1, b2, b3;
    stratified4(pixel, sample, seed, &b0, &b1, &b2, &b3);

    uint py_i = (uint)(((double)pixel + 0.5) * pixel_rows);
    uint px_i = pixel - py_i * width;
    float filter_wx, filter_wy;
    float off_x = filter_offset_x(to_unit(b0), &filter_wx);
    float off_y = filter_offset_y(to_unit(b1), &filter_wy);
    float x = ((float)px_i + (0.5f + off_x)) * inv_width;
    float y = ((float)py_i + (0.5f + off_y)) * inv_height;
    float lx, ly;
    concentric_disk(to_unit(b2), to_unit(b3), &lx, &ly);
    lx = lx * lens_radius;
    ly = ly * lens_radius;
    float dx = (2.0f * x - 1.0f) * screen_x * focal_distance - lx;
    float dy = (1.0f - 2.0f * y) * screen_y * focal_distance - ly;
    float dz = focal_distance;

    float vx = world[0] * dx + world[1] * dy + world[2] * dz;
    float vy = world[4] * dx + world[5] * dy + world[6] * dz;
    float vz = world[8] * dx + world[9] * dy + world[10] * dz;
    float scale = 1.0f / __builtin_sqrtf(vx * vx + vy * vy + vz * vz);
    out[gid] = world[0] * lx + world[1] * ly + world[3];
    out[stride + gid] = world[4] * lx + world[5] * ly + world[7];
    out[2 * stride + gid] = world[8] * lx + world[9] * ly + world[11];
    out[3 * stride + gid] = vx * scale;
    out[4 * stride + gid] = vy * scale;
    out[5 * stride + gid] = vz * scale;
    out[6 * stride + gid] = filter_wx * filter_wy;
    pixel_out[gid] = (int)pixel;
}
