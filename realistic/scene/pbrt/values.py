"""pbrt parameter values read as our types, the renderer's coordinate limit, and errors located at
the directive they came from; shared by the camera, film, shape and scene-assembly modules."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager

from realistic.errors import LensFileError, UserError
from realistic.scene.model import RGB
from realistic.scene.pbrt.lexer import PbrtSyntaxError
from realistic.scene.pbrt.parser import Params

GREY: RGB = (0.5, 0.5, 0.5)
#: Farthest a shape or the camera may reach from the world origin: the renderer intersects in single
#: precision, where products of larger coordinates overflow (float32 holds up to 3.4e38).
MAX_WORLD_COORDINATE = 1e18


def rgb(params: Params, name: str, default: RGB | None) -> RGB | None:
    """An RGB triple (one value: grey); None for what we cannot read as RGB (spectra, other counts)."""
    p = params.items.get(name)
    if p is None:
        return default
    if p.type in ("spectrum", "blackbody", "xyz") or len(p.values) not in (1, 3):
        return None
    values = params.get_floats(name, [])  # a syntax error naming the parameter when they are not numbers
    return (values[0], values[0], values[0]) if len(values) == 1 else (values[0], values[1], values[2])


def whole_number(params: Params, name: str, default: float, where: str) -> int:
    """An integer parameter, which must hold a whole number."""
    value = params.get_float(name, default)
    if value != int(value):
        raise UserError(f'{where}: "{name}" must be a whole number, got {value:g}')
    return int(value)


#: A message that starts with a file and line number ("scene.pbrt:12: ...").
_LOCATED = re.compile(r"^[^\n]+?:\d+: ")


@contextmanager
def located(where: str) -> Iterator[None]:
    """Prefix ``where`` (a scene file:line) to a UserError that does not already name a file and line
    (its own, or another's: a texture's line where a material uses it)."""
    try:
        yield
    except (LensFileError, PbrtSyntaxError):
        raise
    except UserError as err:
        message = str(err)
        if message.startswith(f"{where}:") or _LOCATED.match(message):
            raise
        raise UserError(f"{where}: {message}") from None
