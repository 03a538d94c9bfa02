"""Checks of a mesh file's text for what trimesh would silently read wrong.

- OBJ: a face index 0 (OBJ counts from 1; trimesh would take it as the first vertex) and statements
  trimesh skips without a word (indented, or a tab after the keyword); checked before loading.
- ASCII STL: a facet without exactly 3 vertex lines of 3 numbers (trimesh would shift every later
  vertex); checked after loading, for files up to ``DIAGNOSIS_BYTES``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.scene.mesh_diagnosis import DIAGNOSIS_BYTES, binary_stl_sizes, read_head

_OBJ_ZERO_INDEX = re.compile(rb"^[ \t]*f[ \t][^\n#]*?(?<![^\s/])[-+]?0+(?![^\s/])", re.MULTILINE)
_OBJ_SKIPPED = re.compile(rb"[ \t]+(?:v[nt]?|f)[ \t]|(?:v[nt]?|f)\t")  # at a line's start
_INDEX_BEFORE = np.isin(np.arange(256), np.frombuffer(b" \t/", dtype=np.uint8))  # bytes that may precede an index
_INDEX_AFTER = np.isin(np.arange(256), np.frombuffer(b" \t/\r\n", dtype=np.uint8))  # ... and follow one


def check_obj_text(path: Path, block: int = 1 << 24) -> None:
    """What trimesh would read wrong without a word, in blocks of whole lines: a face index 0 (OBJ counts
    from 1, negative indices back from the last vertex; trimesh takes 0 as the first vertex), and
    statements it skips (indented, or a tab after the keyword), which drops faces or shifts indices."""
    try:
        with open(path, "rb") as file:
            line, rest = 0, b""
            while True:
                data = file.read(block)
                text = rest + data
                end = len(text) if not data else text.rfind(b"\n") + 1  # whole lines only, until the end
                found = _obj_text_problem(text[:end])
                if found is not None:
                    raise UserError(f"{path}:{line + found[0]}: {found[1]}")
                if not data:
                    return
                line += text.count(b"\n", 0, end)
                rest = text[end:]
    except OSError as err:
        raise UserError(f"{path}: cannot read the file ({err.strerror or err})") from None


def _obj_text_problem(data: bytes) -> tuple[int, str] | None:
    """(line from 1, message) of the first problem ``check_obj_text`` looks for in OBJ text, else None.
    Vectorised, as it reads every OBJ: bytes after each newline, and runs of '0' that make a whole index
    ("0", "-0", "00" between spaces or slashes); regular expressions only on the few lines found."""
    a = np.frombuffer(b"\n" + data + b"\n\n\n\n", dtype=np.uint8)
    newlines = np.flatnonzero(a == ord("\n"))
    newlines = newlines[newlines <= len(data)]  # newlines[i] ends line i: line i + 1 starts after it
    after = [a[newlines + k] for k in (1, 2, 3)]
    keyword = (after[0] == ord("v")) | (after[0] == ord("f"))
    tab = keyword & (after[1] == ord("\t"))
    tab |= (after[0] == ord("v")) & ((after[1] == ord("n")) | (after[1] == ord("t"))) & (after[2] == ord("\t"))
    indented = np.flatnonzero((after[0] == ord(" ")) | (after[0] == ord("\t")) | tab)
    skipped = next((line + 1 for line in indented if _OBJ_SKIPPED.match(data, newlines[line])), None)
    zero = a == ord("0")
    edges = np.flatnonzero(zero[1:] != zero[:-1]) + 1  # alternately a run's first '0' and the byte after it
    starts, ends = edges[0::2], edges[1::2]
    before = a[starts - 1]
    signed = (before == ord("-")) | (before == ord("+"))
    before[signed] = a[starts[signed] - 2]
    candidates = starts[_INDEX_BEFORE[before] & _INDEX_AFTER[a[ends]]]
    lines = np.unique(np.searchsorted(newlines, candidates))  # the line numbers (from 1) holding one
    if skipped is not None:
        lines = lines[lines < skipped]
    lines = lines[np.isin(a[newlines[lines - 1] + 1], np.frombuffer(b"f \t", dtype=np.uint8))]
    for line in lines:
        start = newlines[line - 1]  # an offset into data: a has one byte more in front
        end = data.find(b"\n", start)
        if _OBJ_ZERO_INDEX.match(data, start, len(data) if end < 0 else end):
            return int(line), "invalid face index 0 (OBJ indices start at 1)"
    if skipped is not None:
        return int(skipped), ("not a readable OBJ mesh (an indented statement, or a tab after its keyword: "
                              "it would be skipped)")
    return None


def check_ascii_stl(path: Path) -> None:
    """trimesh reads ASCII STL as one stream of numbers: a facet of 2 vertices next to one of 4, or a vertex
    of 2 numbers next to one of 4, would shift later vertices silently. Every facet must have 3 vertex lines
    of 3 numbers (files over ``DIAGNOSIS_BYTES`` are not checked)."""
    if binary_stl_sizes(path)[0]:
        return
    data = read_head(path, DIAGNOSIS_BYTES + 1)
    if len(data) > DIAGNOSIS_BYTES:
        return
    problem = _stl_structure_problem(data)
    if problem is not None:
        raise UserError(f"{path}:{problem[0]}: not a readable STL mesh ({problem[1]})")


def _stl_structure_problem(data: bytes) -> tuple[int, str] | None:
    """(line, reason) of the first vertex line without 3 numbers or facet without 3 vertex lines (vectorised:
    lines classed by their first letter, v: vertex, o: outer loop, e..l: endloop)."""
    a = np.frombuffer(data, dtype=np.uint8)
    space = a <= ord(" ")
    tokens = np.flatnonzero(space[:-1] & ~space[1:]) + 1  # where each word starts
    if len(a) and not space[0]:
        tokens = np.concatenate(([0], tokens))
    bounds = np.concatenate(([-1], np.flatnonzero(a == ord("\n")), [len(a)]))  # line i: bounds[i] to bounds[i + 1]
    per_line = np.searchsorted(tokens, bounds)
    counts = np.diff(per_line)  # words on each line
    lines = np.flatnonzero(counts)  # non-blank lines (from 0)
    first = tokens[per_line[lines]]
    head, counts = a[first] | 0x20, counts[lines]  # lower case
    vertex = head == ord("v")
    bad = vertex & (counts != 4)
    if bad.any():
        return int(lines[np.argmax(bad)]) + 1, "a vertex line needs three numbers"
    kind = np.zeros(len(head) + 4, dtype=np.int8)
    kind[: len(head)][vertex] = 1
    kind[: len(head)][(head == ord("e")) & (a[np.minimum(first + 3, len(a) - 1)] | 0x20 == ord("l"))] = 2  # endloop
    loops = np.flatnonzero(head == ord("o"))
    good = (kind[loops + 1] == 1) & (kind[loops + 2] == 1) & (kind[loops + 3] == 1) & (kind[loops + 4] == 2)
    if not good.all():
        return int(lines[loops[np.argmin(good)]]) + 1, "a facet without exactly three vertex lines"
    if vertex.sum() != 3 * len(loops):
        return int(lines[np.flatnonzero(vertex)[-1]]) + 1, "a vertex line outside a facet's loop"
    return None
