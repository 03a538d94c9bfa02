"""Rendering: scene and camera in, film image out. Imports every layer below it.

- ``inputs``: ``RenderOptions`` (typed) to a ``Scene`` with its camera, for the CLI and the API.
- ``job``: ``RenderJob`` (what to render, as data), ``RenderResult``, ``RenderObserver`` and the
  ``PassExecutor`` protocol (where passes run, and what a pass task gets and returns).
- ``passes``: ``render(job, executor, observer)``: sample-id passes on an executor (``ThreadPasses``:
  threads in this process), added to the film in pass order.
- ``runner``: ``PassRunner``, one pass task's work (rays, hits, shading, per-pixel sums), for both executors.
- ``output``: ``save``: a finished render's EXR (with its header), PNG preview and rescue write.
- ``image``: ``Image``, the API's film image that a notebook displays tone-mapped, and ``show``.
- ``from_dict``: ``load_dict``, a scene and its camera from one plain description (the API's).
- ``pass_plan``: passes as sample-id ranges in progressive (bit-reversed) order.
- ``thread_count``: the default number of render threads (one per core).
- ``farm``: ``DaskPasses``, passes as Dask tasks (imported only for farm renders; needs the ``farm`` extra).
- ``checkpoint``: a render's identity (content hashes) and its checkpoint file.
- ``sweep``: ``--sweep`` sequences: one camera per frame.
- ``integrators``: which integrator a scene asks for (``make_integrator``).
- ``direct_lighting``: direct lighting in numpy (area lights, shadow rays, Lambertian surfaces): the fast path.
- ``backends``: the backend object (numpy, or ``opencl_backend``: the kernels on one ``Device``) that
  the options' ``backend`` and ``cl_device`` strings name, once per process.
- ``shade_kernel``: the fast path's shading as an OpenCL kernel (``kernels/shade.cl``), backend "opencl".
- ``path``: MIS direct lighting and path tracing over any BSDF and light, one embree batch per bounce.
- ``bsdf_kernel``: the path tracer's BSDFs as an OpenCL kernel (``kernels/bsdf.cl``), backend "opencl".
- ``light_sampler``: every light picked by power, sampled, with densities for MIS.
- ``area_lights``: the area lights' table and points drawn on them by area, for both integrators.
- ``footprint``: a camera ray's pixel footprint on a surface, as two uv axes for texture filtering.
- ``film``: per-pixel accumulation of pass sums, in pass-index order (``PassFilm``).
- ``timing``: per-stage thread-seconds.
- ``convergence``: render at several sample counts and measure the error (``bench`` command);
  ``convergence_plot`` draws it.
"""
