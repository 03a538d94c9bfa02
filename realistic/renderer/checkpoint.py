"""Checkpoints of a render in progress, and the identity that says which render one belongs to.

A checkpoint (``OUT.exr.partial``, beside the output) holds the film sums and sample counts of the
passes added in order, the sums of passes finished out of order, and the render's identity: content
hashes of the scene and the camera, the seed, resolution, spp, pass size, backend and light samples.
Resuming refuses, in one line, a checkpoint whose identity differs in any of them. It is an
uncompressed NumPy ``.npz`` written atomically (``core.atomic_files``), so a kill mid-write leaves
the previous checkpoint whole.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.camera.base import SampleBlock
from realistic.core.atomic_files import write_atomically
from realistic.errors import UserError
from realistic.renderer.film import Film, PassFilm

#: 2: passes are slices of every pixel's samples (``pass_plan``); a format-1 plan numbered other passes.
FORMAT = "realistic checkpoint 2"


def content_hash(value: object) -> str:
    """SHA-256 (hex) of a value's content: dataclass fields, arrays' dtype, shape and bytes, numbers,
    strings, containers (sets and dict keys sorted), other objects' attributes; the same in every
    process, unlike ``pickle`` or ``hash``. Cached properties are not fields and do not count."""
    digest = hashlib.sha256()
    _feed(digest, value, set())
    return digest.hexdigest()


def _feed(digest, value: object, seen: set[int]) -> None:
    put = digest.update
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes, np.generic)):
        put(f"{type(value).__name__}:{value!r};".encode())
    elif isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
        put(f"array:{array.dtype.str}:{array.shape};".encode())
        put(array.tobytes() if array.dtype != object else repr(array.tolist()).encode())
    elif isinstance(value, (Path, enum.Enum)):
        put(f"{type(value).__name__}:{value};".encode())
    elif id(value) in seen:
        put(b"cycle;")
    elif isinstance(value, (list, tuple)):
        seen.add(id(value))
        put(f"{type(value).__name__}[{len(value)}];".encode())
        for item in value:
            _feed(digest, item, seen)
    elif isinstance(value, (set, frozenset)):
        put(f"set[{len(value)}];".encode())
        for item in sorted(content_hash(item) for item in value):
            put(item.encode())
    elif isinstance(value, dict):
        seen.add(id(value))
        put(f"dict[{len(value)}];".encode())
        for key in sorted(value, key=repr):
            _feed(digest, key, seen)
            _feed(digest, value[key], seen)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        seen.add(id(value))
        put(f"{type(value).__qualname__}(".encode())
        for item in dataclasses.fields(value):
            put(item.name.encode())
            _feed(digest, getattr(value, item.name), seen)
        put(b")")
    elif callable(value) and not hasattr(value, "__dict__"):
        put(f"callable:{getattr(value, '__qualname__', type(value).__qualname__)};".encode())
    else:
        seen.add(id(value))
        put(f"{type(value).__qualname__}{{".encode())
        attributes = getattr(value, "__dict__", None)
        if attributes is None:
            put(repr(value).encode())
        else:
            _feed(digest, attributes, seen)
        put(b"}")


@dataclass(frozen=True)
class RenderIdentity:
    """What must match for a checkpoint to continue a render (fields in the order they are checked)."""

    resolution: str
    seed: int
    scene: str  # content hash
    camera: str  # content hash
    spp: int
    pass_samples: int
    backend: str
    light_samples: int

    @classmethod
    def of(cls, scene: object, camera, seed: int, pass_samples: int, backend: str,
           light_samples: int) -> RenderIdentity:
        """The identity of rendering ``scene`` through ``camera`` (its ``camera`` and ``metadata``, which
        names the file as it was given, not counted)."""
        scene_fields = {f.name: getattr(scene, f.name) for f in dataclasses.fields(scene)
                        if f.name not in ("camera", "metadata")}
        camera_hash = content_hash(dataclasses.replace(camera, spp=1) if dataclasses.is_dataclass(camera) else camera)
        return cls(f"{camera.width}x{camera.height}", int(seed), content_hash(scene_fields), camera_hash,
                   int(camera.spp), int(pass_samples), backend, int(light_samples))


#: How a mismatch is named in the refusal.
_NAMES = {"resolution": "resolution", "seed": "seed", "scene": "scene", "camera": "camera", "spp": "spp",
          "pass_samples": "pass size", "backend": "backend", "light_samples": "light samples"}


def checkpoint_path(out: Path) -> Path:
    """Where the checkpoint of a render to ``out`` goes: ``out`` + ``.partial``."""
    out = Path(out)
    return out.with_name(out.name + ".partial")


def save_checkpoint(path: Path, identity: RenderIdentity, film: PassFilm) -> None:
    """Write ``film``'s state and ``identity`` to ``path`` atomically."""
    waiting = sorted(film.waiting)
    arrays = {"sums": film.film.sums, "samples": film.film.samples,
              "waiting_index": np.array(waiting, dtype=np.int64),
              "waiting_first_pixel": np.array([film.waiting[i][0] for i in waiting], dtype=np.int64)}
    for index in waiting:
        arrays[f"waiting_{index}"] = film.waiting[index][1]
    header = json.dumps({"format": FORMAT, "next_pass": film.next_pass, **dataclasses.asdict(identity)})

    def write(temporary: str) -> None:
        with open(temporary, "wb") as handle:
            np.savez(handle, header=np.array(header), **arrays)

    write_atomically(Path(path), write)


def load_checkpoint(path: Path, identity: RenderIdentity, passes: list[SampleBlock]) -> PassFilm:
    """The film saved at ``path``; UserError (one line) if it is missing, unreadable or made for another render."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no checkpoint to resume (render without --resume to start)")
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(str(data["header"]))
            if not isinstance(header, dict) or not str(header.get("format")).startswith("realistic checkpoint"):
                raise ValueError("not a checkpoint")
            if header["format"] != FORMAT:
                raise ValueError(f"{header['format']}, this version reads {FORMAT}")
            saved = {name: data[name] for name in data.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise UserError(f"{path}: cannot resume: not a readable checkpoint ({reason})") from None
    for name, label in _NAMES.items():
        theirs, ours = header.get(name), getattr(identity, name)
        if theirs != ours:
            show = (lambda v: str(v)[:12]) if name in ("scene", "camera") else str
            raise UserError(f"{path}: cannot resume: the checkpoint is for another {label} ({show(theirs)}, this "
                            f"render has {show(ours)}); remove it or render without --resume")
    width, height = (int(v) for v in identity.resolution.split("x"))
    film = PassFilm(Film(width, height, identity.spp), passes)
    try:
        film.film.sums[:], film.film.samples[:] = saved["sums"], saved["samples"]
        film.next_pass = int(header["next_pass"])
        for index, first_pixel in zip(saved["waiting_index"], saved["waiting_first_pixel"], strict=True):
            film.waiting[int(index)] = (int(first_pixel), saved[f"waiting_{index}"])
    except (KeyError, ValueError, TypeError) as err:
        raise UserError(f"{path}: cannot resume: the checkpoint is damaged ({type(err).__name__})") from None
    return film
