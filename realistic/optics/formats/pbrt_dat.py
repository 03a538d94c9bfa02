"""pbrt-style prescription files (``.dat``): ``radius thickness n_d [V_d] aperture`` per row.

Rows run from the scene side to the film side (conventions in ``realistic.optics.lens``). Also read:
tab-separated tables with blank cells (the Kolb et al. form), a column-header line, CRLF or LF, and
pbrt-v4's 100 mm files whose column 2 is the distance from the *previous* surface.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

from realistic.errors import LensFileError, UserError
from realistic.optics.lens import MAX_SURFACES, LensSystem, build_lens, too_many_surfaces

COLUMN_NAMES_4 = ("radius", "thickness", "index", "aperture")
COLUMN_NAMES_5 = ("radius", "thickness", "index", "abbe V", "aperture")


@dataclass(frozen=True)
class _Row:
    line: int
    values: tuple[float | None, ...]


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?inf(inity)?$", re.IGNORECASE)


def _is_number(text: str) -> bool:
    return bool(_NUMBER.match(text))


def _split_fields(line: str) -> list[str]:
    """Whitespace-separated fields; a tab-separated row with blank cells keeps its blanks.

    The table form (as in Kolb et al.) leaves the index of air and the radius of the stop blank,
    so ``169.660<TAB>0.240<TAB><TAB><TAB>50.4`` has five positional cells.
    """
    fields = line.split()
    if len(fields) in (4, 5) or "\t" not in line:
        return fields
    cells = [c.strip() for c in line.strip("\n").split("\t")]
    if len(cells) in (4, 5):
        return cells
    return fields


_LINE_END = re.compile(r"\r\n|\r|\n")


def text_lines(text: str) -> Iterator[str]:
    """The lines of ``text`` one at a time (CR, LF or CRLF ends), without their line ends.

    Lazy, so that a reader which stops early (``MAX_SURFACES``) does not split a huge file.
    """
    start = 0
    for end in _LINE_END.finditer(text):
        yield text[start:end.start()]
        start = end.end()
    if start < len(text):
        yield text[start:]


def _parse_rows(text: str, path: str) -> list[_Row]:
    rows: list[_Row] = []
    width = None
    for number, raw in enumerate(text_lines(text), start=1):
        line = raw.split("#", 1)[0].rstrip()
        if not line.strip():
            continue
        fields = _split_fields(line)
        if not rows and not any(_is_number(f) for f in fields if f):
            continue  # a column header such as "radius thick n_d V-no ap"
        if len(rows) == MAX_SURFACES:
            raise LensFileError(path, number, too_many_surfaces(MAX_SURFACES + 1, at_least=True))
        if len(fields) not in (4, 5):
            raise LensFileError(path, number, f"expected 4 columns (radius thickness index aperture) "
                                f"or 5 (with Abbe V before aperture), found {len(fields)}: {line.strip()!r}")
        if width is not None and len(fields) != width:
            raise LensFileError(path, number, f"row has {len(fields)} columns but earlier rows have {width}")
        width = len(fields)
        names = COLUMN_NAMES_5 if width == 5 else COLUMN_NAMES_4
        values: list[float | None] = []
        for name, field in zip(names, fields):
            if field == "":
                values.append(None)
            elif _is_number(field):
                values.append(float(field))
            else:
                raise LensFileError(path, number, f"{name} {field!r} is not a number")
        rows.append(_Row(number, tuple(values)))
    if not rows:
        raise LensFileError(path, None, "no surface rows (the file is empty or all comments)")
    return rows


def _is_shifted_convention(thickness: list[float]) -> bool:
    """True for files whose column 2 is the distance from the *previous* surface.

    pbrt-v4's 100 mm files (``dgauss.dat`` etc.) write 0 on the first row and the last surface's
    distance on the last row. In the distance-to-next convention a first-row 0 is impossible (two
    surfaces at one place), so the pattern identifies the convention without guessing.
    """
    return len(thickness) > 1 and thickness[0] == 0 and all(t > 0 for t in thickness[1:])


def parse_prescription(text: str, path: str = "<string>", name: str | None = None) -> LensSystem:
    """Parse and validate a prescription; raise LensFileError naming file, line and value."""
    rows = _parse_rows(text, path)
    five = len(rows[0].values) == 5
    radius, thickness, index, abbe, aperture = [], [], [], [], []
    for row in rows:
        r, t, n = row.values[0], row.values[1], row.values[2]
        v = row.values[3] if five else None
        a = row.values[-1]
        if t is None or a is None:
            raise LensFileError(path, row.line, "thickness and aperture may not be blank")
        radius.append(0.0 if r is None else r)
        thickness.append(t)
        index.append(0.0 if n is None else n)
        abbe.append(0.0 if v is None else v)
        aperture.append(a)

    note = ""
    if _is_shifted_convention(thickness):
        thickness = thickness[1:] + [0.0]
        note = ("column 2 read as the distance from the previous surface (first row is 0): "
                "the pbrt-v4 100 mm convention, shifted to distance-to-next")
    return build_lens(path, [row.line for row in rows], radius, thickness, index, abbe, aperture,
                      name=name, note=note)


def format_prescription(lens: LensSystem) -> str:
    """``lens`` as a pbrt-style ``.dat`` table (5 columns when a glass has a V number), floats
    written exactly. Aspheres cannot be written: the format has no column for them."""
    if not lens.stop_is_flat_in_air:
        raise UserError(f"{lens.name}: its stop is curved or has glass on one side, and in a .dat prescription "
                        f"the stop is a flat row in air: convert to .zmx or .seq")
    lens.refuse_paraxial(".dat")
    if lens.aspheric.any():
        surface = int(lens.aspheric.argmax())
        raise UserError(f"{lens.name}: surface {surface} is aspheric and a .dat prescription has no columns for "
                        f"aspheres: convert to .json, .zmx or .seq")
    five = lens.has_dispersion
    lines = [f"# {lens.name}"] + [f"# {line}" for line in lens.description.splitlines() if line.strip()]
    lines.append("# radius thickness n_d V_d aperture" if five else "# radius thickness n_d aperture")
    for i in range(lens.surface_count):
        radius = 0.0 if i == lens.stop else float(lens.radius_mm[i])
        values = [radius, float(lens.thickness_mm[i]), float(lens.index_d[i])]
        values += [float(lens.abbe_v[i])] if five else []
        lines.append("\t".join(repr(v) for v in values + [float(lens.aperture_mm[i])]))
    return "\n".join(lines) + "\n"
