"""Foundations every other part uses; imports nothing from the rest of the package but ``errors``.

- ``rng``: counter-based random numbers, bit-identical in numpy and ``kernels/lens.cl``.
- ``jit``: loops compiled by numba on first use (``nogil``, cached on disk).
- ``warp``: maps from the unit square (the concentric disk).
- ``distribution``: a 2-D piecewise-constant distribution (environment-map importance sampling).
- ``pixel_filter``: pbrt's pixel filters, their integrals and the film offsets sampled from them.
- ``vectors``: row-wise dot products and normalisation of (N, 3) batches.
- ``transforms``: 4x4 matrices (translate, scale, rotate, look-at) and applying them to points.
- ``film_geometry``: film size from diagonal and resolution; the full-frame diagonal.
- ``spectrum``: wavelengths per sample, RGB to spectrum, spectrum to linear sRGB.
- ``atomic_files``: writability checks and atomic writes.
- ``disk_cache``: arrays cached on disk under a hash of what they were computed from.
- ``image_files``: EXR and PNG out, EXR and other images in.
- ``data_files``: the kernel and default scene, in a checkout or an installation.
"""
