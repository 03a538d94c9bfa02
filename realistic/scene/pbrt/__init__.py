"""The pbrt scene language (v1 to v4 subset), read in three steps.

- ``lexer``: tokens with the file and line they came from.
- ``parser``: directives into plain records (graphics state, transforms, instancing); knows
  pbrt's grammar but nothing of how we render.
- ``importer``: records into our ``Scene`` and camera; reports once, with file and line, what it
  cannot honour; ``imagemap`` reads the imagemap texture's parameters; ``dialect`` decides the
  pbrt version and its conventions.
"""
