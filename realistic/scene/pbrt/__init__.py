"""The pbrt scene language (v1 to v4 subset), read in three steps.

- ``lexer``: tokens with the file and line they came from.
- ``parser``: directives into plain records (graphics state, transforms, instancing); knows
  pbrt's grammar but nothing of how we render.
- ``importer``: records into our ``Scene`` and camera (scene assembly: materials, textures, shapes
  placed and instanced, area lights); reports once, with file and line, what it cannot honour.
  Each job beside it has its module: ``camera`` (the Camera directive and each version's
  conventions), ``film`` (Film, Sampler, PixelFilter), ``shapes`` (shapes tessellated or loaded as
  meshes), ``lights`` (light sources and the integrator), ``materials``, ``imagemap`` (the imagemap
  texture's parameters); ``values`` reads parameter values and locates errors; ``dialect`` decides
  the pbrt version and its conventions.
"""
