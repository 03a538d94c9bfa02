"""Rendering: scene and camera in, film image out. Imports every layer below it.

- ``inputs``: ``RenderOptions`` (typed) to a ``Scene`` with its camera, for the CLI and the API.
- ``passes``: ``render``, ``render_passes`` and ``render_frames``: sample-id passes on threads or a
  Dask cluster, added to the film in pass order.
- ``pass_plan``: passes as sample-id ranges in progressive (bit-reversed) order.
- ``thread_count``: the default number of render threads (one per core).
- ``farm``: passes as Dask tasks (imported only for farm renders; needs the ``farm`` extra).
- ``checkpoint``: a render's identity (content hashes) and its checkpoint file.
- ``sweep``: ``--sweep`` sequences: one camera per frame.
- ``integrators``: which integrator a scene asks for (``make_integrator``).
- ``integrator``: direct lighting in numpy (area lights, shadow rays, Lambertian surfaces): the fast path.
- ``backends``: the backend object (numpy, or ``opencl_backend``: the kernels on one ``Device``) that
  the options' ``backend`` and ``cl_device`` strings name, once per process.
- ``shade_kernel``: the fast path's shading as an OpenCL kernel (``kernels/shade.cl``), backend "opencl".
- ``path``: MIS direct lighting and path tracing over any BSDF and light, one embree batch per bounce.
- ``light_sampler``: every light picked by power, sampled, with densities for MIS.
- ``footprint``: a camera ray's pixel footprint on a surface, as two uv axes for texture filtering.
- ``film``: per-pixel accumulation of pass sums, in pass-index order (``PassFilm``).
- ``timing``: per-stage thread-seconds.
- ``convergence``: render at several sample counts and measure the error (``bench`` command);
  ``convergence_plot`` draws it.
"""
