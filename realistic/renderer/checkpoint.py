"""Checkpoints of a render in progress, and the identity that says which render one belongs to.

A checkpoint (``OUT.exr.partial``, beside the output) holds the film sums and sample counts of the
passes added in order, the sums of passes finished out of order, the lens flare's film and splats
(``film.Splats``) when the render has flare, and the render's identity: content hashes of the scene
and the camera, the seed, resolution, spp, pass size, backend, light samples, crop, AOVs and flare.
Resuming refuses, in one line, a checkpoint whose identity differs in any of them. It is an
uncompressed NumPy ``.npz`` written atomically (``core.atomic_files``), so a kill mid-write leaves
the previous checkpoint whole.

A checkpoint is untrusted input (it may have been edited, truncated or made by anyone): every field
is checked on load against the render's own pass plan (the pass index in range, each pixel's sample
count exactly what the passes taken give it, sums finite and within ``MAX_SUM``, each waiting pass's
shape), and anything else is a one-line UserError naming the file. A render without ``resume``
refuses to start over an existing checkpoint (``refuse_unless_resuming``) rather than replace it.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from realistic.camera.base import Camera, SampleBlock
from realistic.core.atomic_files import write_atomically
from realistic.errors import UserError
from realistic.renderer.crop import PixelBounds
from realistic.renderer.film import Film, PassFilm, Splats
from realistic.scene.model import Scene

#: 2: passes are slices of every pixel's samples (``pass_plan``); a format-1 plan numbered other passes.
FORMAT = "realistic checkpoint 2"
#: Largest film sum a checkpoint may hold: far beyond any render (a pixel's value is its sum over
#: its samples) and far from float64's overflow, so adding passes to it stays finite.
MAX_SUM = 1e30


def content_hash(value: object) -> str:
    """SHA-256 (hex) of a value's content: dataclass fields, arrays' dtype, shape and bytes, numbers,
    strings, containers (sets and dict keys sorted), other objects' attributes; the same in every
    process, unlike ``pickle`` or ``hash``. Cached properties are not fields and do not count."""
    digest = hashlib.sha256()
    _feed(digest, value, set())
    return digest.hexdigest()


class _Digest(Protocol):
    """What ``_feed`` needs of a hashlib object."""

    def update(self, data: bytes, /) -> None: ...


def _feed(digest: _Digest, value: object, seen: set[int]) -> None:
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
    crop: str = ""  # the pixel bounds "x0 x1 y0 y1" of a cropped render; "" for the whole image
    aovs: str = ""  # comma-separated, in ``validation.AOV_NAMES`` order; "" for none
    flare: str = ""  # "ghosts >= THRESHOLD" when the render has lens flare; "" for none

    @classmethod
    def of(cls, scene: Scene, camera: Camera, seed: int, pass_samples: int, backend: str,
           light_samples: int, crop: PixelBounds | None = None, aovs: tuple[str, ...] = (),
           flare_threshold: float | None = None) -> RenderIdentity:
        """The identity of rendering ``scene`` through ``camera`` (its ``camera`` and ``metadata``, which
        names the file as it was given, not counted), cropped to ``crop`` when given, with lens flare
        through the ghosts of at least ``flare_threshold`` (None: none)."""
        scene_fields = {f.name: getattr(scene, f.name) for f in dataclasses.fields(scene)
                        if f.name not in ("camera", "metadata")}
        camera_hash = content_hash(dataclasses.replace(camera, spp=1))
        return cls(f"{camera.width}x{camera.height}", int(seed), content_hash(scene_fields), camera_hash,
                   int(camera.spp), int(pass_samples), backend, int(light_samples), "" if crop is None else str(crop),
                   ",".join(aovs), "" if flare_threshold is None else f"ghosts >= {flare_threshold!r}")


#: How a mismatch is named in the refusal.
_NAMES = {"resolution": "resolution", "seed": "seed", "scene": "scene", "camera": "camera", "spp": "spp",
          "pass_samples": "pass size", "backend": "backend", "light_samples": "light samples", "crop": "crop",
          "aovs": "set of AOVs", "flare": "flare setting"}
#: What a field missing from a checkpoint's header means: one written before crops, AOVs or flare had none.
_ABSENT = {"crop": "", "aovs": "", "flare": ""}


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
        _, sums, splats = film.waiting[index]
        arrays[f"waiting_{index}"] = sums
        if splats is not None:
            arrays[f"waiting_flare_pixel_{index}"], arrays[f"waiting_flare_{index}"] = splats.pixel, splats.value
    if film.film.flare is not None:
        arrays["flare"] = film.film.flare
    header = json.dumps({"format": FORMAT, "next_pass": film.next_pass, **dataclasses.asdict(identity)})

    def write(temporary: str) -> None:
        with open(temporary, "wb") as handle:
            entries: dict[str, Any] = {"header": np.array(header), **arrays}
            np.savez(handle, **entries)

    write_atomically(Path(path), write)


def refuse_unless_resuming(path: Path) -> None:
    """UserError (one line) if a checkpoint is at ``path``: a render that does not resume it would
    replace the work it holds."""
    if os.path.lexists(path):  # False for a name the system refuses: its write says why
        raise UserError(f"{path}: a checkpoint of an earlier render is there: continue it with --resume "
                        "or remove the file to start afresh")


def load_checkpoint(path: Path, identity: RenderIdentity, passes: list[SampleBlock], *,
                    crop: PixelBounds | None = None, columns: int = 3, flare: bool = False) -> PassFilm:
    """The film (of ``columns`` sums per pixel: ``aov.AovLayout.columns``; showing ``crop``, the
    render's; holding lens flare when ``flare``) saved at ``path``; UserError (one line) if it is
    missing, unreadable, made for another render, or holds anything the render's pass plan
    ``passes`` does not give."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no checkpoint to resume (render without --resume to start)")
    width, height = (int(v) for v in identity.resolution.split("x"))
    header, saved = _read(path, width * height, columns, flare)
    for name, label in _NAMES.items():
        theirs, ours = header.get(name, _ABSENT.get(name)), getattr(identity, name)
        if type(theirs) is not type(ours) or theirs != ours:
            width = 12 if name in ("scene", "camera") else 40  # the file's text, escaped: it is untrusted
            shown = (theirs if isinstance(theirs, str) and theirs.isprintable() else ascii(theirs))[:width]
            raise UserError(f"{path}: cannot resume: the checkpoint is for another {label} ({shown or 'none'}, "
                            f"this render has {str(ours)[:width] or 'none'}); remove it or render without --resume")
    film = PassFilm(Film(width, height, identity.spp, bounds=crop, columns=columns, flare=flare), passes)
    problem = _fill(film, header, saved)
    if problem:
        raise UserError(f"{path}: cannot resume: the checkpoint is damaged ({problem}); remove it to start afresh")
    return film


def _read(path: Path, pixels: int, columns: int, flare: bool) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of the checkpoint at ``path`` for a film of ``pixels`` pixels of
    ``columns`` sums each, and its flare when ``flare``."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if not hasattr(data, "files"):
                raise ValueError("not an .npz archive")
            # the members' sizes before any is read: a few arrays of the film's size at most, and with
            # flare its flare film and each waiting pass's splats (at most one pixel index and RGB per pixel)
            members = data.zip.infolist()
            splats = sum(info.filename.startswith("waiting_flare_pixel_") for info in members) if flare else 0
            limit = 24 * (columns + 3 * flare) * pixels + 32 * splats * pixels + (1 << 20)
            if sum(info.file_size for info in members) > limit:
                raise ValueError("larger than a checkpoint of this film")
            header = json.loads(str(data["header"]))
            if not isinstance(header, dict) or not str(header.get("format")).startswith("realistic checkpoint"):
                raise ValueError("not a checkpoint")
            if header["format"] != FORMAT:
                raise ValueError(f"{ascii(header['format'])[1:-1][:40]}, this version reads {FORMAT}")
            waiting = [f"waiting_{index}" for index in data["waiting_index"].tolist()] \
                if "waiting_index" in data.files and data["waiting_index"].ndim == 1 else []
            if flare:
                waiting += [f"waiting_flare{part}_{name[len('waiting_'):]}" for name in waiting
                            for part in ("", "_pixel")]
            names = ["sums", "samples", "waiting_index", "waiting_first_pixel", *waiting, *(["flare"] if flare else [])]
            saved = {name: data[name] for name in names if name in data.files}
    except Exception as err:  # numpy's and zipfile's readers raise many types for a damaged file
        text = " ".join(str(err).split())
        reason = (text if text.isprintable() else ascii(text))[:120] if text else type(err).__name__
        raise UserError(f"{path}: cannot resume: not a readable checkpoint ({reason})") from None
    return header, saved


def _fill(film: PassFilm, header: dict, saved: dict[str, np.ndarray]) -> str | None:
    """Put the checkpoint's state into the fresh ``film``; what is wrong with it, or None."""
    passes, pixels, columns = film.passes, film.film.width * film.film.height, film.film.sums.shape[1]
    next_pass = header.get("next_pass")
    if type(next_pass) is not int or not 0 <= next_pass <= len(passes):
        return f"pass index {ascii(next_pass)[:20]} is not 0 to {len(passes)}"
    missing = [name for name in ("sums", "samples", "waiting_index", "waiting_first_pixel") if name not in saved]
    if missing:
        return f"no {missing[0]}"
    sums, samples = saved["sums"], saved["samples"]
    problem = _sums_problem(sums, (pixels, columns), "film sums")
    if problem:
        return problem
    if samples.shape != (pixels,) or samples.dtype.kind not in "iu":
        return "sample counts of the wrong shape or type"
    expected = np.zeros(pixels, np.int64)
    for block in passes[:next_pass]:
        expected[block.first_pixel:block.first_pixel + block.pixel_count] += block.samples_per_pixel()
    if not np.array_equal(samples, expected):
        return f"sample counts are not those of its {next_pass} passes"
    if np.any(sums[expected == 0] != 0):
        return "sums in pixels without samples"
    index, first = saved["waiting_index"], saved["waiting_first_pixel"]
    if index.ndim != 1 or first.shape != index.shape or index.dtype.kind not in "iu" or first.dtype.kind not in "iu":
        return "waiting passes of the wrong shape or type"
    if len(set(index.tolist())) != len(index) or np.any(index <= next_pass) or np.any(index >= len(passes)):
        return "waiting pass indices out of range or repeated"
    film.film.sums[:], film.film.samples[:] = sums, samples
    film.next_pass = next_pass
    if film.film.flare is not None:
        flare = saved.get("flare")
        if flare is None:
            return "no flare"
        problem = _sums_problem(flare, (pixels, 3), "flare")
        if problem:
            return problem
        if next_pass == 0 and np.any(flare != 0):
            return "flare before any pass"
        film.film.flare[:] = flare
    for number, first_pixel in zip(index.tolist(), first.tolist(), strict=True):
        block, waiting = passes[number], saved.get(f"waiting_{number}")
        if first_pixel != block.first_pixel or waiting is None:
            return f"waiting pass {number} does not start at its pixel or has no sums"
        problem = _sums_problem(waiting, (block.pixel_count, columns), f"waiting pass {number}")
        if problem:
            return problem
        splats = None
        if film.film.flare is not None:
            splats, problem = _splats(saved.get(f"waiting_flare_pixel_{number}"), saved.get(f"waiting_flare_{number}"),
                                      pixels, f"waiting pass {number}")
            if problem:
                return problem
        film.waiting[number] = (first_pixel, waiting.astype(np.float64), splats)
    return None


def _splats(pixel: np.ndarray | None, value: np.ndarray | None, pixels: int,
            what: str) -> tuple[Splats | None, str | None]:
    """A waiting pass's flare splats from their arrays, or what is wrong with them."""
    if pixel is None or value is None:
        return None, f"{what} has no flare"
    if pixel.ndim != 1 or pixel.dtype.kind not in "iu" or (len(pixel) and (
            pixel.min() < 0 or pixel.max() >= pixels or np.any(np.diff(pixel) <= 0))):
        return None, f"{what}'s flare pixels are not ascending film pixels"
    problem = _sums_problem(value, (len(pixel), 3), f"{what}'s flare")
    return (None, problem) if problem else (Splats(pixel.astype(np.int64), value), None)


def _sums_problem(sums: np.ndarray, shape: tuple[int, int], what: str) -> str | None:
    """What is wrong with film sums that must have ``shape``, or None."""
    if sums.shape != shape or sums.dtype != np.float64:
        return f"{what} of the wrong shape or type"
    if not np.all(np.isfinite(sums)) or np.any(np.abs(sums) > MAX_SUM):
        return f"{what} not finite or beyond {MAX_SUM:g}"
    return None
