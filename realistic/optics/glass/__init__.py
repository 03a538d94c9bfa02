"""Optical glass catalogues: Schott, Ohara, Hoya and CDGM glasses by name, with their makers' formulas.

- ``catalogue``: ``find_glass`` (a name, optionally with its catalogue, to a ``GlassFormula``) and
  ``closest_names`` for the message when a name is unknown.
- ``data/``: one CSV per catalogue (name, formula, n_d, V_d, six coefficients), extracted by
  ``tools/extract_glass_catalogues.py`` from the makers' spreadsheets; sources in ``catalogue``.
"""
