"""Cameras: sample ids in, world-space rays out. Imports ``device``, ``optics``, ``core`` and ``errors``.

- ``base``: the ``Camera`` protocol every camera implements, ``RayBatch``, the sample-id split.
- ``lens_camera``: ``LensCamera``, a real lens traced surface by surface (numpy reference).
- ``opencl_host``: the lens kernel's host: builds ``kernels/lens.cl`` for a ``LensCamera`` on a ``Device``.
- ``thin_lens``: ``ThinLensCamera``, pbrt's perspective camera (pinhole or thin lens).
- ``autofocus``: the focus distance that makes what a pixel sees sharp (real-ray search).
- ``exposure``: shutter, ISO and exposure value for photographic output.
"""
