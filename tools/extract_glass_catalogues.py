"""Write ``realistic/optics/glass/data/*.csv`` from the manufacturers' catalogue spreadsheets.

The spreadsheets are the ones the ``opticalglass`` package (BSD-3-Clause, M. J. Hayford) ships in
``opticalglass/data``: SCHOTT.xls, OHARA.xlsx, HOYA.xlsx and CDGM.xls, each the manufacturer's own
download. Run once per catalogue update, in an environment with ``xlrd`` and ``openpyxl``:
``python tools/extract_glass_catalogues.py PATH/TO/opticalglass/data``. Each row keeps the glass
name, its formula (``sellmeier``: n^2 - 1 = sum B_i l^2 / (l^2 - C_i); ``schott``: n^2 = A0 + A1 l^2
+ A2 l^-2 + A3 l^-4 + A4 l^-6 + A5 l^-8; l in um), six coefficients, and the catalogue's n_d and V_d.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path
from typing import Any

import openpyxl  # type: ignore[import-untyped]
import xlrd  # type: ignore[import-untyped]

OUT = Path(__file__).resolve().parent.parent / "realistic" / "optics" / "glass" / "data"


def _column(letters: str) -> int:
    """0-based index of a spreadsheet column name (A, B, ..., AA, ...)."""
    index = 0
    for letter in letters:
        index = index * 26 + ord(letter) - ord("A") + 1
    return index - 1


def _rows_xls(path: Path, sheet: int = 0) -> list[list[Any]]:
    table = xlrd.open_workbook(str(path)).sheet_by_index(sheet)
    return [table.row_values(i) for i in range(table.nrows)]


def _rows_xlsx(path: Path, sheet: int = 0) -> list[list[Any]]:
    book = openpyxl.load_workbook(str(path), read_only=True, data_only=True)
    return [list(row) for row in book.worksheets[sheet].iter_rows(values_only=True)]


#: Per catalogue: file, reader, first data row (0-based), name, n_d, V_d columns, formula, coefficient columns.
CATALOGUES: dict[str, tuple[str, Any, int, str, str, str, str, list[str]]] = {
    "schott": ("SCHOTT.xls", _rows_xls, 4, "A", "B", "D", "sellmeier", ["G", "H", "I", "J", "K", "L"]),
    "ohara": ("OHARA.xlsx", _rows_xlsx, 2, "B", "Q", "Y", "sellmeier", ["BI", "BJ", "BK", "BL", "BM", "BN"]),
    "hoya": ("HOYA.xlsx", _rows_xlsx, 4, "C", "E", "F", "schott",
             ["AC", "AD", "AE", "AF", "AG", "AH", "AI", "AJ", "AK", "AL", "AM", "AN"]),
    "cdgm": ("CDGM.xls", _rows_xls, 2, "A", "J", "R", "schott", ["V", "W", "X", "Y", "Z", "AA"]),
}


def _number(value: Any) -> float | None:
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def extract(source: Path, catalogue: str) -> list[list[str]]:
    """The rows (name, formula, n_d, V_d, six coefficients) of one catalogue."""
    file, read, first, name_col, nd_col, vd_col, formula, columns = CATALOGUES[catalogue]
    out = []
    for row in read(source / file)[first:]:
        name = str(row[_column(name_col)] or "").replace(" ", "")  # Ohara writes "S-BSL 7" for S-BSL7
        values = [_number(row[_column(c)]) for c in columns]
        nd, vd = _number(row[_column(nd_col)]), _number(row[_column(vd_col)])
        if not name or nd is None or vd is None or any(v is None for v in values):
            continue
        coefficients = [float(v) for v in values if v is not None]
        if len(coefficients) == 12:  # Hoya: mantissa and power of ten in pairs
            coefficients = [float(f"{m!r}e{int(p)}") for m, p in zip(coefficients[::2], coefficients[1::2])]
        out.append([name, formula, repr(nd), repr(vd), *(repr(c) for c in coefficients)])
    return out


def main() -> None:
    source = Path(sys.argv[1])
    OUT.mkdir(parents=True, exist_ok=True)
    for catalogue in CATALOGUES:
        with open(OUT / f"{catalogue}.csv", "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(["glass", "formula", "nd", "vd", "c1", "c2", "c3", "c4", "c5", "c6"])
            writer.writerows(extract(source, catalogue))


if __name__ == "__main__":
    main()
