"""Saying what is wrong with a mesh file that trimesh cannot read, found in the file itself.

trimesh raises many kinds of errors for malformed files, often from deep inside (an ``IndexError``, a
missing optional module); none of that text means anything to a user. ``unreadable_message`` looks at
the file: a header line that is wrong, a face line that names a vertex the file does not have, byte
counts that disagree, and says so in one line with the file and, where it can, the line. Files over
``DIAGNOSIS_BYTES`` get a general reason instead of a line-by-line reading.
"""

from __future__ import annotations

import json
import re
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from realistic.errors import UserError

DIAGNOSIS_BYTES = 64 << 20  # files larger than this get a generic reason, not a line-by-line diagnosis
_PLY_TYPES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "float16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "int64": 8,
              "uint64": 8, "float64": 8, "double": 8}  # bytes
_PLY_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
_GENERIC = {
    "obj": "malformed vertex or face lines",
    "ply": "the data does not match the header",
    "stl": "malformed facets",
    "off": "malformed counts, vertex or face lines",
    "glb": "inconsistent or truncated accessors, buffer views or buffers",
    "gltf": "inconsistent accessors, buffer views or buffers",
}


def read_head(path: Path, limit: int | None = None) -> bytes:
    try:
        with open(path, "rb") as file:
            return file.read(-1 if limit is None else limit)
    except OSError as err:
        raise UserError(f"{path}: cannot read the file ({err.strerror or err})") from None


def _one_line(text: str, limit: int = 100) -> str:
    text = " ".join("".join(c if c.isprintable() else " " for c in text).split()).rstrip("!")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _chain(err: BaseException | None) -> Iterator[BaseException]:
    """``err`` and the errors it was raised from or while handling, each once."""
    seen = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        yield err
        err = err.__cause__ or err.__context__


def _trimesh_message(err: BaseException) -> str | None:
    """The text of an error trimesh raised on purpose (``raise ValueError("Not a ply file!")``), else None:
    a numpy or Python error from inside trimesh (``list index out of range``) says nothing to the user."""
    import traceback

    frames = traceback.extract_tb(err.__traceback__)
    if not frames or not isinstance(err, ValueError | NameError | NotImplementedError | KeyError):
        return None
    last = frames[-1]
    if "trimesh" not in Path(last.filename).parts or not (last.line or "").lstrip().startswith("raise "):
        return None
    text = _one_line(str(err))
    return text or None


def unreadable_message(path: Path, extension: str, err: BaseException) -> str:
    """The one-line message for a file trimesh failed on: what is wrong, found in the file where possible."""
    what = f"not a readable {extension.upper()} mesh"
    if isinstance(err, MemoryError):
        return f"{path}: too large to load (out of memory)"
    if isinstance(err, OSError) and err.strerror and err.filename is not None:  # opening a file failed
        other = Path(str(err.filename)).resolve() != path.resolve()
        target = f"{_one_line(str(err.filename))}, which it refers to" if other else "the file"
        return f"{path}: cannot read {target} ({err.strerror})"
    try:
        found = _DIAGNOSE[extension](path)
    except Exception:  # the diagnosis is best effort: never let it hide the real error
        found = None
    if found is None:
        reason = None
        for link in _chain(err):
            if isinstance(link, json.JSONDecodeError):
                reason = _json_message(link)
            elif isinstance(link, UnicodeDecodeError) or (isinstance(link, ImportError) and "charset" in str(link)):
                reason = "the text is not valid UTF-8"
            elif isinstance(link, FileNotFoundError) and not link.strerror:
                reason = f"it refers to {_one_line(str(link))!r}, which cannot be found"
            if reason:
                break
        found = None, reason or _trimesh_message(err) or _GENERIC[extension]
    line, reason = found
    return f"{path}{'' if line is None else f':{line}'}: {what} ({reason})"


def no_triangles_message(path: Path, extension: str) -> str:
    """The one-line message for a file trimesh read as holding no triangles: the file's own problem where
    the diagnosis finds one (trimesh decodes text that is not UTF-8 when ``charset_normalizer`` is
    installed, and then finds nothing in it; a cut ASCII STL is said as such first), else that it holds
    none."""
    if extension == "stl" and not binary_stl_sizes(path)[0]:
        data = read_head(path, DIAGNOSIS_BYTES)
        if re.search(rb"(?i)\bvertex\b", data) and not re.search(rb"(?i)\bendsolid\b", data):
            return f"{path}: not a readable STL mesh (ASCII STL without an 'endsolid' line: truncated?)"
    try:
        found = _DIAGNOSE[extension](path)
    except UnicodeDecodeError:
        found = None, "the text is not valid UTF-8"
    except Exception:  # best effort, as in unreadable_message
        found = None
    if found is not None:
        line, reason = found
        return f"{path}{'' if line is None else f':{line}'}: not a readable {extension.upper()} mesh ({reason})"
    return f"{path}: the file holds no triangles"


def _text(path: Path) -> str | None:
    """The file as text for a line-by-line diagnosis; None when it is too large to be worth it."""
    data = read_head(path, DIAGNOSIS_BYTES + 1)
    if len(data) > DIAGNOSIS_BYTES:
        return None
    return data.decode("utf-8")  # UnicodeDecodeError: the caller reports text that is not UTF-8


def _numbers(words: list[str]) -> list[float] | None:
    try:
        return [float(w) for w in words]
    except ValueError:
        return None


def _text_diagnosis(problem: Callable[[str], tuple[int | None, str] | None]
                    ) -> Callable[[Path], tuple[int | None, str] | None]:
    """A diagnosis of a text format: ``problem`` of the file's UTF-8 text (none for a file too large)."""
    def diagnose(path: Path) -> tuple[int | None, str] | None:
        try:
            text = _text(path)
        except UnicodeDecodeError:
            return None, "the text is not valid UTF-8"
        return None if text is None else problem(text)
    return diagnose


def _obj_problem(text: str) -> tuple[int | None, str] | None:
    lines = [line.split() for line in text.split("\n")]
    lines = [[] if words and words[0].startswith("#") else words for words in lines]
    kinds = {"v": "vertices", "vt": "texture coordinates", "vn": "normals"}
    totals = dict.fromkeys(kinds, 0)
    for words in lines:
        if words and words[0] in totals:
            totals[words[0]] += 1
    for number, words in enumerate(lines, start=1):
        if not words:
            continue
        if words[0] in (*kinds, "f") and any(w.startswith("#") for w in words):
            return number, f"a comment after a {words[0]} statement (not supported)"
        if words[0] in kinds:
            values = _numbers(words[1:])
            if values is None:
                return number, f"a {words[0]} line with a value that is not a number"
            if words[0] != "vt" and len(values) < 3:
                return number, f"a {words[0]} line needs three numbers"
        elif words[0] == "f":
            for token in words[1:]:
                parts = token.split("/")
                if len(parts) > 3 or not parts[0]:
                    return number, f"face vertex {_one_line(token, 30)!r} is not V, V/T, V//N or V/T/N"
                for kind, part in zip(kinds, parts):
                    if not part:
                        continue
                    try:
                        index = int(part)
                    except ValueError:
                        return number, f"face index {_one_line(part, 30)!r} is not an integer"
                    if index == 0 or abs(index) > totals[kind]:
                        return number, f"face index {index}, but the file has {totals[kind]} {kinds[kind]}"
    return None


@dataclass
class _PlyElement:
    """An ``element`` of a PLY header with its ``property`` lines."""

    name: str
    count: int
    properties: list[str] = field(default_factory=list)
    item_bytes: int = 0  # bytes per item at least (binary; a list property counts only its length field)


def _diagnose_ply(path: Path) -> tuple[int | None, str] | None:
    data = read_head(path, DIAGNOSIS_BYTES + 1)
    lines = data.split(b"\n")
    if lines[0].strip() != b"ply":
        return 1, "it does not start with a 'ply' line"
    end = next((i for i, line in enumerate(lines) if line.strip() == b"end_header"), None)
    if end is None:
        return None, "truncated or malformed header: no 'end_header' line"
    elements: list[_PlyElement] = []
    binary = False
    for number, raw in enumerate(lines[1:end], start=2):
        try:
            words = raw.decode("utf-8").split()
        except UnicodeDecodeError:
            return number, "the header is not UTF-8 text"
        if not words:
            return number, "a blank line in the header"
        if number == 2:
            if words[0] != "format" or len(words) != 3 or words[1] not in _PLY_FORMATS:
                return number, f"the format line must be 'format {'|'.join(_PLY_FORMATS)} 1.0'"
            binary = words[1] != "ascii"
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                return number, "an element line must be 'element NAME COUNT' with a count of 0 or more"
            elements.append(_PlyElement(words[1], int(words[2])))
        elif words[0] == "property":
            single = len(words) == 3 and words[1] in _PLY_TYPES
            listed = len(words) == 5 and words[1] == "list" and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES
            if not (single or listed):
                return number, "a property line must be 'property TYPE NAME' or 'property list TYPE TYPE NAME'"
            if not elements:
                return number, "a property before any element"
            elements[-1].properties.append(words[-1])
            elements[-1].item_bytes += _PLY_TYPES[words[2]] if listed else _PLY_TYPES[words[1]]
        elif words[0] not in ("comment", "obj_info"):
            return number, f"unknown header keyword {_one_line(words[0], 30)!r}"
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is not None and not {"x", "y", "z"} <= set(vertex.properties):
        return None, "the vertex element has no x, y and z properties"
    if binary:
        needed = sum(e.count * e.item_bytes for e in elements)
        available = path.stat().st_size - sum(len(line) + 1 for line in lines[:end + 1])
        if available < needed:
            return None, f"the header declares at least {needed} bytes of data, the file has {available}"
        return None
    if len(data) > DIAGNOSIS_BYTES:
        return None
    rows = [line for line in lines[end + 1:] if line.strip()]
    for number, row in enumerate(lines[end + 1:], start=end + 2):
        if _numbers(row.decode("utf-8", errors="replace").split()) is None:
            return number, "a value that is not a number"
    needed = sum(e.count for e in elements)
    if len(rows) < needed:
        return None, f"the header declares {needed} rows of data, the file has {len(rows)}"
    return None


def binary_stl_sizes(path: Path) -> tuple[bool, str]:
    """Whether the file is a binary STL by its size (as trimesh decides), and if not, why not."""
    size = path.stat().st_size
    head = read_head(path, 84)
    if len(head) < 84:
        return False, f"{size} bytes is too short for a binary STL"
    count = struct.unpack("<I", head[80:84])[0]
    expected = 84 + 50 * count
    return size == expected, f"a binary STL of {count} triangles would be {expected} bytes, not {size}"


def _stl_ascii_problem(text: str) -> tuple[int, str] | None:
    vertices, loop = 0, None
    for number, line in enumerate(text.split("\n"), start=1):
        words = line.lower().split()
        if not words:
            continue
        if words[0] == "vertex":
            values = _numbers(words[1:])
            if values is None or len(values) != 3:
                return number, "a vertex line needs three numbers"
            vertices += 1
        elif words[0] == "outer":
            vertices, loop = 0, number
        elif words[0] == "endloop" and vertices != 3:
            return loop or number, f"a facet of {vertices} vertices, not 3"
    return None


def _diagnose_stl(path: Path) -> tuple[int | None, str] | None:
    binary, why_not = binary_stl_sizes(path)
    if binary:
        return None
    try:
        text = _text(path)
    except UnicodeDecodeError:
        return None, f"neither binary ({why_not}) nor ASCII STL (not UTF-8 text)"
    if text is None:
        return None
    if not text.lstrip().lower().startswith("solid"):
        return None, f"neither binary ({why_not}) nor ASCII STL (no 'solid' line)"
    problem = _stl_ascii_problem(text)
    if problem is not None:
        return problem
    return None, f"neither binary ({why_not}) nor well-formed ASCII STL"


def _off_problem(text: str) -> tuple[int | None, str] | None:
    lines = [(n, line.split("#", 1)[0].split()) for n, line in enumerate(text.split("\n"), start=1)]
    lines = [(n, words) for n, words in lines if words]
    if not lines or lines[0][1][0] not in ("OFF", "COFF"):
        return (lines[0][0] if lines else None), "it does not start with 'OFF'"
    if len(lines[0][1]) > 1:  # the counts on the OFF line itself
        lines[0] = (lines[0][0], lines[0][1][1:])
    else:
        lines = lines[1:]
    if not lines:
        return None, "no 'VERTICES FACES EDGES' counts line"
    number, counts = lines[0]
    if len(counts) < 2 or not all(c.isdigit() for c in counts[:3]):
        return number, "the counts line must be 'VERTICES FACES EDGES' (integers of 0 or more)"
    vertex_count, face_count = int(counts[0]), int(counts[1])
    vertex_lines = lines[1:1 + vertex_count]
    if len(vertex_lines) < vertex_count:
        return None, f"the counts line declares {vertex_count} vertices, the file has {len(vertex_lines)}"
    for number, words in vertex_lines:
        values = _numbers(words)
        if values is None or len(values) < 3:
            return number, "a vertex needs three numbers"
    face_lines = lines[1 + vertex_count:1 + vertex_count + face_count]
    if len(face_lines) < face_count:
        return None, f"the counts line declares {face_count} faces, the file has {len(face_lines)}"
    for number, words in face_lines:
        if not words[0].isdigit() or len(words) < 1 + int(words[0]):
            return number, "a face line must be 'N I1 ... IN' with N vertex indices"
        for word in words[1:1 + int(words[0])]:
            if not word.isdigit() or int(word) >= vertex_count:
                return number, f"face index {_one_line(word, 30)!r}, but the file has {vertex_count} vertices"
    return None


def _json_message(err: json.JSONDecodeError) -> str:
    return f"malformed JSON: {err.msg.removesuffix(' at')} at line {err.lineno} column {err.colno}"


def _json_problem(text: bytes) -> tuple[None, str] | None:
    try:
        json.loads(text)
    except UnicodeDecodeError:
        return None, "the JSON is not valid UTF-8"
    except json.JSONDecodeError as err:
        return None, _json_message(err)
    except (ValueError, RecursionError):
        return None, "malformed JSON"
    return None


def _diagnose_glb(path: Path) -> tuple[int | None, str] | None:
    size = path.stat().st_size
    head = read_head(path, 20)
    if len(head) < 12 or head[:4] != b"glTF":
        return None, "no 'glTF' binary header"
    version, length = struct.unpack("<II", head[4:12])
    if version != 2:
        return None, f"glTF version {version}; only version 2 is read"
    if length != size:
        return None, f"the header gives a length of {length} bytes, the file has {size} (truncated?)"
    if len(head) < 20:
        return None, "no JSON chunk"
    chunk_length, chunk_type = struct.unpack("<I4s", head[12:20])
    if chunk_type != b"JSON":
        return None, "the first chunk is not JSON"
    if 20 + chunk_length > size:
        return None, "the JSON chunk runs past the end of the file (truncated?)"
    if chunk_length > DIAGNOSIS_BYTES:
        return None
    return _json_problem(read_head(path, 20 + chunk_length)[20:])


def _diagnose_gltf(path: Path) -> tuple[int | None, str] | None:
    data = read_head(path, DIAGNOSIS_BYTES + 1)
    if len(data) > DIAGNOSIS_BYTES:
        return None
    problem = _json_problem(data)
    if problem is not None:
        return problem
    from urllib.parse import unquote

    document = json.loads(data)
    folder = path.resolve().parent
    for entry in [*document.get("buffers", []), *document.get("images", [])]:
        uri = entry.get("uri") if isinstance(entry, dict) else None
        if not isinstance(uri, str) or uri.startswith("data:"):
            continue
        target = (folder / unquote(uri)).resolve()
        named = _one_line(uri, 60)
        if not target.is_relative_to(folder):
            return None, f"it refers to {named!r}, outside the file's folder"
        if not target.is_file():
            return None, f"it refers to {named!r}, which is {'not a file' if target.exists() else 'missing'}"
    return None


_DIAGNOSE = {"obj": _text_diagnosis(_obj_problem), "ply": _diagnose_ply, "stl": _diagnose_stl,
             "off": _text_diagnosis(_off_problem),
             "glb": _diagnose_glb, "gltf": _diagnose_gltf}
