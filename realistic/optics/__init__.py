"""The lens: its model, analysis and real-ray tracing. Imports only ``core`` and ``errors``.

Frames and units are set out in ``lens``: millimetres, surfaces numbered from the front, the lens
frame with the film at z = 0 and +z toward the scene.

- ``lens``: ``LensSystem`` (surfaces as arrays) and ``build_lens``, the one validation of a lens.
- ``asphere``: the even-asphere sag (conic and A4 .. A20) and its slope.
- ``formats/``: file readers and writers (pbrt ``.dat``, Zemax ``.zmx``, isetlens/omni ``.json``,
  CODE V ``.seq``) and the bundled prescriptions; ``load_lens`` dispatches there. Readers import
  the model, never the reverse.
- ``stop_shape``: the aperture stop's shape (circle, blades, image mask).
- ``dispersion``: refractive index against wavelength: catalogue formulas (Sellmeier, Schott), or
  Cauchy from n_d and V_d.
- ``glass/``: the Schott, Ohara, Hoya and CDGM catalogues (glass name to formula).
- ``paraxial``: first-order data (EFL, BFL, pupils, f-number) and thick-lens focusing.
- ``tracer``: the float64 real-ray tracer (film to scene), the production tracer and the kernel's
  oracle.
- ``sampling``: where camera rays are aimed (exit-pupil table, rear element) and their weight;
  tables are cached in memory and on disk (``core.disk_cache``).
- ``pupil_search``: finds the exit-pupil boxes by tracing grids and bisecting their edges.
- ``field_curves``: relative illumination, vignetting and distortion against field.
- ``report``: what ``lens info`` reports.
- ``ray_json``: the JSON rays of ``lens trace``.
- ``drawing``: matplotlib drawings (cross-section with ray fans, field curves); drawing only.
"""
