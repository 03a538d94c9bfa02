"""Scenes: what the camera looks at. Imports ``camera``, ``optics``, ``core`` and ``errors``.

- ``model``: ``Scene`` and its plain parts (meshes, instances, materials, textures, area lights).
- ``lights``: point, spot, distant and infinite lights (environment maps) and emitting instances.
- ``shapes``: analytic shapes tessellated into meshes.
- ``loop_subdivision``: pbrt's Loop subdivision (loopsubdiv) to the limit surface, with pbrt's normals.
- ``meshes``: mesh files through trimesh (OBJ, PLY, STL, GLB/GLTF, OFF), refusing what would render wrong;
  ``mesh_text_checks`` reads the text trimesh would misread, ``mesh_diagnosis`` says why a file is
  unreadable.
- ``materials``: the non-Lambertian materials (plastic, conductor, mirror, dielectric, substrate, diffuse
  transmission, measured, mix) as frozen descriptions; ``measured`` reads pbrt-v2's measured-BRDF
  files; ``metals`` holds pbrt's copper spectra.
- ``textures``: materials' albedo at surface points, batched (image textures filtered over footprints).
- ``mipmap``: MIP maps of images and their batched lookups (point, bilinear, trilinear, EWA).
- ``intersect``: the embree scene built from a ``Scene``; closest-hit and occlusion queries.
- ``staging``: a mesh on a grid floor under a light, the default scene, framing a subject.
- ``pbrt/``: the pbrt scene language: ``lexer`` (tokens), ``parser`` (records and graphics
  state), ``importer`` (records to ``Scene`` and camera), ``materials`` (material types per version),
  ``lights`` (LightSource and Integrator).
"""
