"""Glass names to dispersion formulas, from the makers' published catalogues.

Sources, one CSV per catalogue in ``data/`` (each the maker's own catalogue spreadsheet, as
redistributed in the ``opticalglass`` package 1.1.1 by M. J. Hayford, BSD-3-Clause, whose
``data/`` holds these files; extracted by ``tools/extract_glass_catalogues.py``):

* ``schott.csv``: SCHOTT optical glass data table, SCHOTT.xls (2018-06), Sellmeier coefficients.
* ``ohara.csv``: OHARA optical glass catalogue, OHARA.xlsx (recommended glasses sheet), Sellmeier.
* ``hoya.csv``: HOYA optical glass data table, HOYA.xlsx (2018-12-15), Schott power-series
  coefficients A0 .. A5 (the sheet writes each as a mantissa and a power of ten).
* ``cdgm.csv``: CDGM optical glass catalogue, CDGM.xls (2018-09), Schott power series A0 .. A5.

Names are matched without regard to case, spaces or hyphens (Zemax writes ``N-BK7``, CODE V
``NBK7_SCHOTT``: the same glass). A name found in several catalogues resolves to the first of
``CATALOGUES`` that holds it, unless the caller names the catalogue.
"""

from __future__ import annotations

import csv
import difflib
import functools
from importlib import resources

from realistic.optics.dispersion import FORMULAS, GlassFormula

#: File stem -> the catalogue's name, in the order a name found in several is resolved.
CATALOGUES = {"schott": "Schott", "ohara": "Ohara", "hoya": "Hoya", "cdgm": "CDGM"}


def _key(name: str) -> str:
    """A name as looked up: upper case, without spaces or hyphens (CODE V writes N-BK7 as NBK7)."""
    return name.replace(" ", "").replace("-", "").upper()


@functools.cache
def _catalogue(stem: str) -> dict[str, GlassFormula]:
    """The glasses of one catalogue by ``_key`` of their names."""
    text = (resources.files(__package__) / "data" / f"{stem}.csv").read_text(encoding="utf-8")
    glasses = {}
    for row in csv.DictReader(text.splitlines()):
        if row["formula"] not in FORMULAS:
            raise ValueError(f"{stem}.csv: glass {row['glass']} has unknown formula {row['formula']!r}")
        c = [float(row[f"c{i}"]) for i in range(1, 7)]
        glasses[_key(row["glass"])] = GlassFormula(row["glass"], CATALOGUES[stem], row["formula"],
                                                   (c[0], c[1], c[2], c[3], c[4], c[5]))
    return glasses


def catalogue_stem(name: str) -> str | None:
    """The file stem of catalogue ``name`` (``SCHOTT``, ``Ohara``, ...), or None when it is not one."""
    return name.lower() if name.lower() in CATALOGUES else None


def find_glass(name: str, catalogue: str | None = None) -> GlassFormula | None:
    """The glass called ``name`` (in ``catalogue``, a key of ``CATALOGUES``, when given), or None."""
    stems = [catalogue] if catalogue else list(CATALOGUES)
    for stem in stems:
        glass = _catalogue(stem).get(_key(name))
        if glass is not None:
            return glass
    return None


def closest_names(name: str, count: int = 3) -> list[str]:
    """The catalogue names closest to ``name`` (for the message that it is unknown)."""
    names = {g.name: _key(g.name) for stem in CATALOGUES for g in _catalogue(stem).values()}
    by_key = {key: label for label, key in names.items()}
    return [by_key[k] for k in difflib.get_close_matches(_key(name), list(by_key), n=count, cutoff=0.5)]


def unknown_glass(name: str) -> str:
    """The one-line message for a glass name no catalogue holds."""
    close = closest_names(name)
    hint = f"; closest: {', '.join(close)}" if close else ""
    return f"glass {name!r} is in none of the catalogues ({', '.join(CATALOGUES.values())}){hint}"
