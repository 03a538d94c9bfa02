"""The pbrt scene language read into plain records: directives, transforms and graphics state.

This module knows pbrt's grammar and state rules (CTM, attribute and transform stacks, named
coordinate systems, object instancing, textures, materials, area lights, and pbrt-v4's additions:
``Attribute`` defaults, ``Import``, ``Option``, ``ColorSpace``, media, ``ActiveTransform``) but
nothing of how we render; ``realistic.scene.pbrt.importer`` turns the records into our scene and
camera. What it cannot honour it reports once with file and line and carries on; a syntax error
stops with file, line and what was expected.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, overload

import numpy as np

from realistic.core.input_files import input_file
from realistic.core.transforms import look_at, rotate, scale, translate
from realistic.errors import UserError
from realistic.scene.pbrt.lexer import PbrtSyntaxError, Token, read_scene_text, tokenize

#: Deepest chain of Include/Import (a file including a file ...); a cycle is reported as soon as it closes.
MAX_INCLUDE_DEPTH = 64

PARAM_TYPES = {"integer", "float", "point", "point2", "point3", "vector", "vector2", "vector3", "normal",
               "normal3", "color", "rgb", "spectrum", "xyz", "blackbody", "string", "bool", "texture"}


#: One value of a parameter: a quoted string (or a bare word), a number, or a bool of a "bool" parameter.
ParamValue = str | float | bool


@dataclass(frozen=True)
class Param:
    type: str
    name: str
    values: tuple[ParamValue, ...]
    where: str


class ParamDict(dict[str, Param]):
    """A directive's parameters by name, remembering every name looked up (``get``, ``[]``, ``in``),
    as pbrt-v4 marks each parameter ``lookedUp`` and reports the rest (``ParameterDictionary::
    ReportUnused``, src/pbrt/paramdict.cpp). A lookup also counts for ``sources``: the dicts this
    one was merged from (an entity's own parameters under pbrt-v4's Attribute defaults). A lookup of
    a parameter given an empty list (``"float radius" []``) is an error naming its file and line, as
    pbrt-v4's ``ParameterDictionary::lookupSingle`` refuses one ("No values provided for parameter",
    src/pbrt/paramdict.cpp) where pbrt-v3 read it as absent."""

    def __init__(self, items: dict[str, Param] | None = None, sources: tuple[ParamDict, ...] = ()):
        super().__init__(items or {})
        self.looked_up: set[str] = set()
        self.naming: set[str] = set()  # parameters that say what the directive makes: read when it is parsed
        self.sources = sources

    def _note(self, name: object) -> None:
        if isinstance(name, str):
            param = super().get(name)
            if param is not None and not param.values:
                raise PbrtSyntaxError(*_split_where(param.where), f'"{param.type} {param.name}" [] is an empty '
                                      f"list: give it a value or leave it out (pbrt-v4 refuses one)")
            self.looked_up.add(name)
            for source in self.sources:
                source._note(name)

    def mark_naming(self, name: str) -> None:
        """``name`` says what the directive makes (MakeNamedMaterial's "type"): read when the file
        is parsed, it neither counts as the entity being built nor is ever unused."""
        self.naming.add(name)
        for source in self.sources:
            source.mark_naming(name)

    def get(self, name: str, default: Any = None) -> Any:
        self._note(name)
        return super().get(name, default)

    def __getitem__(self, name: str) -> Param:
        self._note(name)
        return super().__getitem__(name)

    def __contains__(self, name: object) -> bool:
        self._note(name)
        return super().__contains__(name)

    def peek(self, name: str) -> Param | None:
        """The parameter ``name`` without counting the lookup: for reading what a directive says about
        the file (which pbrt wrote it) without building what it declares."""
        return super().get(name)

    def unused(self) -> list[Param]:
        """The parameters no lookup asked for, when any lookup was made (an entity never built, such
        as a material no shape uses, was not looked at, so nothing in it is called unused)."""
        if not self.looked_up - self.naming:
            return []
        return [param for name, param in super().items() if name not in self.looked_up | self.naming]


@dataclass
class Params:
    """A directive's parameter list with typed getters (unknown names stay available for reporting)."""

    items: ParamDict = field(default_factory=ParamDict)

    def __post_init__(self) -> None:
        if not isinstance(self.items, ParamDict):
            self.items = ParamDict(self.items)

    def has(self, name: str) -> bool:
        return name in self.items

    @overload
    def get_floats(self, name: str) -> list[float] | None: ...
    @overload
    def get_floats(self, name: str, default: list[float]) -> list[float]: ...

    def get_floats(self, name: str, default: list[float] | None = None) -> list[float] | None:
        """The numbers of ``name``, ``default`` when it is not given; a syntax error when they are not numbers."""
        p = self.items.get(name)
        if p is None:
            return default
        floats = [v for v in p.values if isinstance(v, float)]
        if len(floats) != len(p.values):
            raise PbrtSyntaxError(*_split_where(p.where), f'"{p.name}" expects numbers')
        return floats

    @overload
    def get_float(self, name: str) -> float | None: ...
    @overload
    def get_float(self, name: str, default: float) -> float: ...

    def get_float(self, name: str, default: float | None = None) -> float | None:
        """The first number of ``name``, ``default`` when it gives none."""
        values = self.get_floats(name)
        return default if not values else values[0]

    def get_required_float(self, name: str) -> float:
        """The first number of ``name``, a parameter the directive must give: a UserError when it gives none."""
        values = self.get_floats(name, [])
        if not values:
            raise UserError(f'"{name}" needs a number')
        return values[0]

    def with_defaults(self, defaults: dict[str, Param]) -> Params:
        """These parameters, and each of ``defaults`` that they do not give (pbrt-v4's ``Attribute``
        values: ``src/pbrt/scene.cpp`` builds each entity's ParameterDictionary from its own
        parameters followed by the graphics state's attributes, and a lookup takes the first match)."""
        if not defaults:
            return self
        return Params(ParamDict({**defaults, **self.items}, sources=(self.items,)))

    @overload
    def get_string(self, name: str) -> str | None: ...
    @overload
    def get_string(self, name: str, default: str) -> str: ...

    def get_string(self, name: str, default: str | None = None) -> str | None:
        """The first string of ``name``, ``default`` when it gives none; a syntax error when it is not a string."""
        p = self.items.get(name)
        if p is None or not p.values:
            return default
        if not isinstance(p.values[0], str):
            raise PbrtSyntaxError(*_split_where(p.where), f'"{p.name}" expects a string')
        return p.values[0]


def _split_where(where: str) -> tuple[str, int]:
    path, line = where.rsplit(":", 1)
    return path, int(line)


@dataclass(frozen=True)
class Declaration:
    """A typed directive that is state rather than geometry: Material, AreaLightSource."""

    type: str
    params: Params
    where: str


@dataclass(frozen=True)
class TextureDef:
    name: str
    kind: str  # "float" or "color"/"spectrum"
    cls: str  # "imagemap", "scale", "checkerboard", "constant", ...
    params: Params
    directory: Path  # where relative file names are looked up
    where: str


@dataclass(frozen=True)
class ShapeRecord:
    type: str
    params: Params
    transform: np.ndarray  # object to world (to the instance's space inside ObjectBegin)
    material: Declaration
    area_light: Declaration | None
    reverse_orientation: bool
    directory: Path
    where: str


@dataclass(frozen=True)
class Directive:
    """Camera, Film, Sampler, PixelFilter or LightSource: type, parameters and the CTM when it was given."""

    type: str
    params: Params
    transform: np.ndarray
    where: str


@dataclass
class PbrtScene:
    path: Path
    film: Directive | None = None
    sampler: Directive | None = None
    camera: Directive | None = None
    pixel_filter: Directive | None = None
    integrator: Directive | None = None  # Integrator (v3/v4) or SurfaceIntegrator (v1/v2)
    shapes: list[ShapeRecord] = field(default_factory=list)
    objects: dict[str, list[ShapeRecord]] = field(default_factory=dict)
    instances: list[tuple[str, np.ndarray, str]] = field(default_factory=list)
    lights: list[Directive] = field(default_factory=list)
    textures: dict[str, TextureDef] = field(default_factory=dict)
    named_materials: dict[str, Declaration] = field(default_factory=dict)  # for mix materials' parts
    materials: list[Declaration] = field(default_factory=list)  # every Material directive, used or not
    warnings: list[str] = field(default_factory=list)
    world_begin: str | None = None  # where WorldBegin was, if anywhere
    directives: dict[str, str] = field(default_factory=dict)  # each directive name -> where it first appeared
    world_end: str | None = None  # where WorldEnd was, if anywhere
    parameter_lists: list[ParamDict] = field(default_factory=list)  # every directive's, for unused ones

    def report_unused_parameters(self) -> None:
        """Warn, at its file and line, of each parameter of a directive we built that nothing read:
        a misspelt name, another pbrt version's name, or one we do not implement."""
        for params in self.parameter_lists:
            for param in params.unused():
                self.warn(param.where, f'"{param.name}": parameter not used here (ignored)')

    def warn(self, where: str, message: str) -> None:
        """Report something not honoured, once per distinct message."""
        text = f"{where}: unsupported: {message}"
        if not any(w.split(": unsupported: ", 1)[1] == message for w in self.warnings):
            self.warnings.append(text)


#: pbrt-v4's ``Attribute`` targets (``src/pbrt/scene.cpp``, BasicSceneBuilder::Attribute).
ATTRIBUTE_TARGETS = ("shape", "light", "material", "medium", "texture")
#: ``ActiveTransform`` arguments (pbrt-v3/v4 parser): which of the two motion-blur transforms later
#: transform directives change.
ACTIVE_TRANSFORMS = ("All", "StartTime", "EndTime")


@dataclass
class _State:
    ctm: np.ndarray
    material: Declaration
    area_light: Declaration | None = None
    reverse_orientation: bool = False
    # pbrt-v4 Attribute defaults per target; each update replaces the inner dict, so copies may share it
    attributes: dict[str, dict[str, Param]] = field(default_factory=dict)
    # False after ActiveTransform EndTime: transforms then change only the shutter-close transform,
    # which we do not render (shapes stay where the shutter-open transform puts them)
    start_active: bool = True

    def copy(self) -> _State:
        return _State(self.ctm.copy(), self.material, self.area_light, self.reverse_orientation,
                      dict(self.attributes), self.start_active)

    def defaults(self, target: str) -> dict[str, Param]:
        return self.attributes.get(target, {})


DEFAULT_MATERIAL = Declaration("matte", Params(), "<default>")


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False for names the system cannot even look up (too long, say)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def resolve_file(name: str, directory: Path, search_paths: list[Path]) -> Path | None:
    """A file a scene names: relative to the naming file's folder, else in a search path; None
    where there is none. A name that is found only as something else (a directory, a FIFO, a
    device) is a UserError saying what it is (``core.input_files``): opening a FIFO would block."""
    candidates = [folder / name for folder in [directory, *search_paths]]
    for candidate in candidates:
        if _is_file(candidate):
            return candidate
    for candidate in candidates:
        if _exists(candidate):
            input_file(candidate, "file")  # raises: it exists and is not a regular file
    return None


def _exists(path: Path) -> bool:
    """``path.exists()``, False for names the system cannot even look up."""
    try:
        return path.exists()
    except (OSError, ValueError):
        return False


def _identity(path: Path) -> str:
    """One name per file however it is reached (relative, through links), for finding Include cycles."""
    try:
        return str(path.resolve())
    except (OSError, RuntimeError):
        return str(path.absolute())


@dataclass
class _Frame:
    """The tokens of one file being read; the frames below it are the files that included it."""

    tokens: list[Token]
    label: str  # the file as the scene named it (the top file: as given)
    identity: str
    pos: int = 0
    restore: tuple[_State, int] | None = None  # Import: the graphics state and stack depth to go back to


def _bare_bool(token: Token) -> bool:
    return token.kind == "word" and token.text in ("true", "false")


class _Parser:
    def __init__(self, path: Path, search_paths: list[Path], transform_blocks_keep_all: bool = False):
        self.search_paths = search_paths
        self.transform_blocks_keep_all = transform_blocks_keep_all
        self.scene = PbrtScene(path)
        self.state = _State(np.eye(4), DEFAULT_MATERIAL)
        self.stack: list[tuple[str, _State, str]] = []  # (block kind, saved state, where it began)
        self.named_frames: dict[str, np.ndarray] = {}
        self.current_object: str | None = None
        self.named_materials = self.scene.named_materials
        self.frames: list[_Frame] = []
        self.finished_imports: list[tuple[str, tuple[_State, int]]] = []  # (label, restore), as they ended
        self.last: Token | None = None

    # ---- token access -------------------------------------------------------------------------
    def _load(self, path: Path) -> list[Token]:
        return list(tokenize(read_scene_text(path), path))

    def peek(self) -> Token | None:
        """The next token, read on into the including file when an included one is used up."""
        while self.frames:
            frame = self.frames[-1]
            if frame.pos < len(frame.tokens):
                return frame.tokens[frame.pos]
            if len(self.frames) == 1:
                return None
            finished = self.frames.pop()
            if finished.restore is not None:
                self.finished_imports.append((finished.label, finished.restore))
        return None

    def end_imports(self) -> None:
        """Imported files used up (by the directive before, whose parameters may have run to their
        end) give back the graphics state they were given: pbrt-v4 ``src/pbrt/parser.cpp`` parses an
        Import with a copy of the state (``BasicSceneBuilder::CopyForImport``) and keeps only its
        shapes, instances, named materials and textures."""
        for label, restore in self.finished_imports:  # innermost first, so the outermost's state is the one kept
            self.end_of(label, restore)
        self.finished_imports.clear()

    def end_of(self, label: str, restore: tuple[_State, int]) -> None:
        """Close the blocks an imported file (``label``) left open and give back the state it was given."""
        state, depth = restore
        while len(self.stack) > depth:
            kind, _, where = self.stack.pop()
            self.scene.warn(where, f"{kind}Begin without a matching {kind}End in the imported file "
                                   f"{label} (closed at its end)")
            if kind == "Object":
                self.current_object = None
        self.state = state

    def advance(self) -> None:
        """Step past the token ``peek`` returned."""
        frame = self.frames[-1]
        self.last = frame.tokens[frame.pos]
        frame.pos += 1

    def next(self, expected: str) -> Token:
        token = self.peek()
        if token is None:
            last = self.last
            raise PbrtSyntaxError(last.path if last else self.scene.path, last.line if last else 1,
                                  f"unexpected end of file, expected {expected}")
        self.advance()
        return token

    def expect(self, kind: str, what: str, directive: Token) -> Token:
        """The next token, which must be of ``kind`` (described as ``what`` in the error)."""
        token = self.next(f"{what} after {directive.text}")
        if token.kind != kind:
            raise PbrtSyntaxError(token.path, token.line, f"expected {what} after {directive.text}, "
                                  f"found {token.text}")
        return token

    def number(self, directive: Token) -> float:
        return float(self.expect("number", "a number", directive).value)

    def numbers(self, directive: Token, count: int) -> list[float]:
        """``count`` numbers, bare or inside one pair of brackets."""
        bracketed = (token := self.peek()) is not None and token.kind == "["
        if bracketed:
            self.advance()
        values = [self.number(directive) for _ in range(count)]
        if bracketed:
            close = self.next("]")
            if close.kind != "]":
                raise PbrtSyntaxError(close.path, close.line, f"expected ] after {count} numbers of "
                                      f"{directive.text}, found {close.text}")
        return values

    def string(self, directive: Token) -> str:
        return str(self.expect("string", "a quoted string", directive).value)

    def params(self) -> Params:
        params = Params()
        self.scene.parameter_lists.append(params.items)
        while (token := self.peek()) is not None and token.kind == "string":
            self.advance()
            parts = str(token.value).split()
            if len(parts) != 2 or parts[0] not in PARAM_TYPES:
                raise PbrtSyntaxError(token.path, token.line, f'expected a parameter "type name", found {token.text}')
            values = self.param_values(token)
            params.items[parts[1]] = Param(parts[0], parts[1], tuple(values), token.where())
        return params

    def param_values(self, declaration: Token) -> list[str | float] | list[bool]:
        """The values after a parameter's declaration: one bare, or a bracketed list; bools for a "bool" one."""
        first = self.next(f"a value for {declaration.text}")
        values: list[str | float]
        if _bare_bool(first):  # pbrt-v4 writes bool values unquoted (src/pbrt/parser.cpp, parseParameters)
            values = [first.text]
        elif first.kind in ("string", "number"):
            values = [first.value]
        elif first.kind != "[":
            raise PbrtSyntaxError(first.path, first.line, f"expected a value or [ for {declaration.text}, "
                                  f"found {first.text}")
        else:
            values = []
            while (token := self.next(f"] closing the values of {declaration.text}")).kind != "]":
                if _bare_bool(token):
                    values.append(token.text)
                    continue
                if token.kind not in ("string", "number"):
                    raise PbrtSyntaxError(token.path, token.line, f"expected ] closing the values of "
                                          f"{declaration.text}, found {token.text}")
                values.append(token.value)
        if str(declaration.value).split()[0] == "bool":
            return self._booleans(declaration, values)
        return values

    @staticmethod
    def _booleans(declaration: Token, values: list[str | float]) -> list[bool]:
        for value in values:
            if value not in ("true", "false"):
                shown = f'"{value}"' if isinstance(value, str) else f"{value:g}"
                raise PbrtSyntaxError(declaration.path, declaration.line, f'{declaration.text} expects "true" or '
                                      f'"false", found {shown}')
        return [value == "true" for value in values]

    # ---- directives ---------------------------------------------------------------------------
    def run(self) -> PbrtScene:
        self.frames = [_Frame(self._load(self.scene.path), str(self.scene.path), _identity(self.scene.path))]
        while (token := self.peek()) is not None:
            self.end_imports()
            self.advance()
            if token.kind != "word":
                raise PbrtSyntaxError(token.path, token.line, f"expected a directive, found {token.text}")
            self.scene.directives.setdefault(token.text, token.where())
            handler = getattr(self, f"d_{token.text}", None)
            if handler is None:
                self.skip_unknown(token)
            else:
                try:
                    handler(token)
                except ValueError as err:
                    raise PbrtSyntaxError(token.path, token.line, f"{token.text}: {err}") from None
        self.end_imports()
        self.close_open_blocks("by the end of the file")
        return self.scene

    def close_open_blocks(self, when: str) -> None:
        """Blocks still open at WorldEnd or the end of the file: pbrt complains and closes them; so do we."""
        while self.stack:
            kind, saved, where = self.stack.pop()
            self.scene.warn(where, f"{kind}Begin without a matching {kind}End {when} (closed there)")
            self.state = saved
            if kind == "Object":
                self.current_object = None

    def skip_unknown(self, token: Token) -> None:
        """An unknown directive: report it and skip its arguments up to the next directive."""
        self.scene.warn(token.where(), f"directive {token.text} (ignored)")
        while (nxt := self.peek()) is not None and nxt.kind != "word":
            self.advance()

    def set_ctm(self, matrix: np.ndarray) -> None:
        if not np.all(np.isfinite(matrix)):
            raise ValueError("the transform overflows (values beyond a double's range)")
        if self.state.start_active:
            self.state.ctm = matrix

    def apply(self, matrix: np.ndarray) -> None:
        with np.errstate(over="ignore", invalid="ignore"):  # judged by set_ctm
            self.set_ctm(self.state.ctm @ matrix)

    def d_Include(self, token: Token) -> None:
        name = self.string(token)
        # pbrt-v3/v4 resolve a relative name against the first scene file's folder (ResolveFilename,
        # src/pbrt/util/file.cpp); pbrt-v1/v2 and most scenes mean the including file's: try both
        try:
            path = resolve_file(name, token.path.parent, [self.scene.path.parent, *self.search_paths])
        except UserError as err:
            raise PbrtSyntaxError(token.path, token.line, f'{token.text} "{name}": {err}') from None
        if path is None:
            self.scene.warn(token.where(), f'{token.text} "{name}": no such file in {token.path.parent} or the '
                                       f'search paths (skipped)')
            return
        identity = _identity(path)
        chain = [frame.identity for frame in self.frames]
        if identity in chain:
            labels = [frame.label for frame in self.frames[chain.index(identity):]] + [name]
            raise PbrtSyntaxError(token.path, token.line, f'{token.text} "{name}" makes a cycle: '
                                  f'{" -> ".join(labels)}')
        if len(self.frames) > MAX_INCLUDE_DEPTH:
            raise PbrtSyntaxError(token.path, token.line, f'{token.text} "{name}" nests files more than '
                                  f"{MAX_INCLUDE_DEPTH} deep (the limit)")
        restore = (self.state.copy(), len(self.stack)) if token.text == "Import" else None
        self.frames.append(_Frame(self._load(path), name, identity, restore=restore))

    d_Import = d_Include

    def d_Identity(self, token: Token) -> None:
        self.set_ctm(np.eye(4))

    def d_Translate(self, token: Token) -> None:
        self.apply(translate(*self.numbers(token, 3)))

    def d_Scale(self, token: Token) -> None:
        self.apply(scale(*self.numbers(token, 3)))

    def d_Rotate(self, token: Token) -> None:
        angle, *axis = self.numbers(token, 4)
        if not any(axis):
            raise ValueError("zero rotation axis")
        axis = np.array(axis) / np.max(np.abs(axis))  # so that its length cannot overflow
        self.apply(rotate(angle, axis))

    def d_LookAt(self, token: Token) -> None:
        n = self.numbers(token, 9)
        v = np.array(n)
        eye, target, up = v[0:3], v[3:6], (n[6], n[7], n[8])
        if np.array_equal(eye, target):
            raise ValueError("LookAt eye and target coincide")
        if not np.any(np.cross(up, target - eye)):
            raise ValueError("LookAt up vector is parallel to the viewing direction")
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # judged by apply
            self.apply(np.linalg.inv(look_at(eye, target, up)))  # pbrt's LookAt gives world to camera

    def d_Transform(self, token: Token) -> None:
        self.set_ctm(np.array(self.numbers(token, 16)).reshape(4, 4).T)  # pbrt lists column-major

    def d_ConcatTransform(self, token: Token) -> None:
        self.apply(np.array(self.numbers(token, 16)).reshape(4, 4).T)

    def d_CoordinateSystem(self, token: Token) -> None:
        self.named_frames[self.string(token)] = self.state.ctm.copy()

    def d_CoordSysTransform(self, token: Token) -> None:
        name = self.string(token)
        if name not in self.named_frames:
            raise PbrtSyntaxError(token.path, token.line,
                                  f'CoordSysTransform "{name}": no coordinate system of that name')
        self.set_ctm(self.named_frames[name].copy())

    def _directive(self, token: Token) -> Directive:
        kind = self.string(token)
        return Directive(kind, self.params(), self.state.ctm.copy(), token.where())

    def d_Film(self, token: Token) -> None:
        self.scene.film = self._directive(token)

    def d_Sampler(self, token: Token) -> None:
        self.scene.sampler = self._directive(token)

    def d_PixelFilter(self, token: Token) -> None:
        self.scene.pixel_filter = self._directive(token)

    def d_Camera(self, token: Token) -> None:
        camera = self._directive(token)
        if not np.array_equal(self.state.ctm[3], [0.0, 0.0, 0.0, 1.0]):  # pbrt's cameras are affine
            row = " ".join(f"{v:g}" for v in self.state.ctm[3])
            raise ValueError(f"the camera transform is projective (its bottom row is {row}, not 0 0 0 1), which "
                             f"no camera model here or in pbrt places")
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                world_from_camera = np.linalg.inv(self.state.ctm)
        except np.linalg.LinAlgError:
            world_from_camera = None
        if world_from_camera is None or not np.all(np.isfinite(world_from_camera)):
            raise ValueError("the camera transform is singular (a Scale by 0, say), so the camera has no position")
        self.scene.camera = camera
        self.named_frames["camera"] = world_from_camera

    def _ignored(self, token: Token) -> None:
        kind = self.string(token)
        self.params()
        self.scene.warn(token.where(), f'{token.text} "{kind}" (ignored)')

    def d_Integrator(self, token: Token) -> None:
        self.scene.integrator = self._directive(token)

    d_SurfaceIntegrator = d_Integrator
    d_VolumeIntegrator = d_Accelerator = d_Renderer = _ignored

    # ---- pbrt-v4 (src/pbrt/parser.cpp for the grammar, src/pbrt/scene.cpp for the meaning) --------
    def d_Attribute(self, token: Token) -> None:
        """``Attribute "target" params``: defaults for the target's later directives in this block."""
        target = self.string(token)
        if target not in ATTRIBUTE_TARGETS:
            raise PbrtSyntaxError(token.path, token.line, f'Attribute "{target}": unknown target (pbrt-v4 has '
                                  f'{", ".join(ATTRIBUTE_TARGETS)})')
        params = self.params()
        self.state.attributes = {**self.state.attributes,
                                 target: {**self.state.defaults(target), **params.items}}

    def d_Option(self, token: Token) -> None:
        """``Option "name" value``: a renderer setting given as one token (pbrt-v4's command-line options)."""
        name = self.string(token)
        value = self.next(f'a value for Option "{name}"')
        if value.kind not in ("string", "number", "word"):
            raise PbrtSyntaxError(value.path, value.line, f'expected a value for Option "{name}", found {value.text}')
        self.scene.warn(token.where(), f'Option "{name}" {value.text} (renderer options are ours to set; ignored)')

    def d_ColorSpace(self, token: Token) -> None:
        name = self.string(token)
        if name.lower() != "srgb":
            self.scene.warn(token.where(), f'ColorSpace "{name}" (RGB values are read as sRGB primaries)')

    def d_MakeNamedMedium(self, token: Token) -> None:
        name = self.string(token)
        self.params().with_defaults(self.state.defaults("medium"))
        self.scene.warn(token.where(), f'MakeNamedMedium "{name}" (participating media are not rendered; ignored)')

    def d_MediumInterface(self, token: Token) -> None:
        """``MediumInterface "inside" ["outside"]`` (one name means both, as pbrt-v4's parser reads it)."""
        names = [self.string(token)]
        if (nxt := self.peek()) is not None and nxt.kind == "string":
            self.advance()
            names.append(str(nxt.value))
        shown = " ".join(f'"{n}"' for n in names)
        if any(names):
            self.scene.warn(token.where(), f"MediumInterface {shown} (participating media are not rendered; "
                                           f"ignored)")

    def d_ActiveTransform(self, token: Token) -> None:
        which = self.next(f"All, StartTime or EndTime after {token.text}")
        if which.kind != "word" or which.text not in ACTIVE_TRANSFORMS:
            raise PbrtSyntaxError(which.path, which.line, f"expected All, StartTime or EndTime after "
                                  f"{token.text}, found {which.text}")
        self.state.start_active = which.text != "EndTime"
        if which.text != "All":
            self.scene.warn(token.where(), "ActiveTransform StartTime/EndTime (motion blur is not rendered; "
                                           "shapes and camera stay at the shutter-open transform)")

    def d_TransformTimes(self, token: Token) -> None:
        self.numbers(token, 2)
        self.scene.warn(token.where(), "TransformTimes (motion blur is not rendered)")

    def d_WorldBegin(self, token: Token) -> None:
        # an error in pbrt-v3 (src/core/api.cpp) and pbrt-v4 (src/pbrt/scene.cpp): VERIFY_OPTIONS
        if self.scene.world_begin is not None:
            raise PbrtSyntaxError(token.path, token.line, f"WorldBegin again (the world began at "
                                                          f"{self.scene.world_begin})")
        self.named_frames["world"] = np.eye(4)
        self.state.ctm = np.eye(4)
        self.state.start_active = True  # pbrt-v4 scene.cpp: WorldBegin makes all transforms active
        self.scene.world_begin = token.where()

    def d_WorldEnd(self, token: Token) -> None:
        self.close_open_blocks("before WorldEnd")
        self.scene.world_end = token.where()

    def _push(self, kind: str, token: Token) -> None:
        self.stack.append((kind, self.state.copy(), token.where()))

    def _pop(self, token: Token, kind: str) -> _State:
        if not self.stack:
            raise PbrtSyntaxError(token.path, token.line, f"{token.text} without a matching {kind}Begin")
        opened, saved, where = self.stack.pop()
        if opened != kind:
            raise PbrtSyntaxError(token.path, token.line, f"{token.text} closes the {opened}Begin at {where}")
        return saved

    def d_AttributeBegin(self, token: Token) -> None:
        self._push("Attribute", token)

    def d_AttributeEnd(self, token: Token) -> None:
        self.state = self._pop(token, "Attribute")

    def d_TransformBegin(self, token: Token) -> None:
        self._push("Transform", token)

    def d_TransformEnd(self, token: Token) -> None:
        saved = self._pop(token, "Transform")
        if self.transform_blocks_keep_all:
            self.state = saved
        else:
            self.state.ctm = saved.ctm

    def d_ReverseOrientation(self, token: Token) -> None:
        self.state.reverse_orientation = not self.state.reverse_orientation

    def d_ObjectBegin(self, token: Token) -> None:
        name = self.string(token)
        if self.current_object is not None:
            self.scene.warn(token.where(), f'ObjectBegin inside the definition of object "{self.current_object}" '
                                           f"(its shapes go to the inner object)")
        self._push("Object", token)
        self.current_object = name
        if name in self.scene.objects:
            # pbrt: instances made so far keep the old definition; keep it for them under another name
            kept = f"{name} (defined before {token.where()})"
            self.scene.objects[kept] = self.scene.objects[name]
            self.scene.instances = [(kept if n == name else n, m, w) for n, m, w in self.scene.instances]
            self.scene.warn(token.where(), f'ObjectBegin "{name}" redefines an object (later instances use the '
                                           f"new definition)")
        self.scene.objects[name] = []

    def d_ObjectEnd(self, token: Token) -> None:
        self.state = self._pop(token, "Object")
        self.current_object = None

    def d_ObjectInstance(self, token: Token) -> None:
        name = self.string(token)
        if name not in self.scene.objects:
            raise PbrtSyntaxError(token.path, token.line, f'ObjectInstance "{name}": no object of that name')
        if self.current_object is not None:
            self.scene.warn(token.where(), "ObjectInstance inside an object definition (ignored, as pbrt does)")
            return
        self.scene.instances.append((name, self.state.ctm.copy(), token.where()))

    def d_Texture(self, token: Token) -> None:
        name, kind, cls = self.string(token), self.string(token), self.string(token)
        params = self.params().with_defaults(self.state.defaults("texture"))
        self.scene.textures[name] = TextureDef(name, kind, cls, params, token.path.parent, token.where())

    def d_Material(self, token: Token) -> None:
        kind = self.string(token)
        self.state.material = Declaration(kind, self.params().with_defaults(self.state.defaults("material")),
                                          token.where())
        self.scene.materials.append(self.state.material)

    def d_MakeNamedMaterial(self, token: Token) -> None:
        name = self.string(token)
        params = self.params().with_defaults(self.state.defaults("material"))
        params.items.mark_naming("type")
        self.named_materials[name] = Declaration(params.get_string("type", "matte"), params, token.where())

    def d_NamedMaterial(self, token: Token) -> None:
        name = self.string(token)
        if name not in self.named_materials:
            raise PbrtSyntaxError(token.path, token.line, f'NamedMaterial "{name}": no material of that name')
        self.state.material = self.named_materials[name]

    def d_AreaLightSource(self, token: Token) -> None:
        kind = self.string(token)
        self.state.area_light = Declaration(kind, self.params().with_defaults(self.state.defaults("light")),
                                            token.where())

    def d_LightSource(self, token: Token) -> None:
        kind = self.string(token)
        params = self.params().with_defaults(self.state.defaults("light"))
        self.scene.lights.append(Directive(kind, params, self.state.ctm.copy(), token.where()))

    def d_Shape(self, token: Token) -> None:
        kind = self.string(token)
        params = self.params().with_defaults(self.state.defaults("shape"))
        record = ShapeRecord(kind, params, self.state.ctm.copy(), self.state.material,
                             self.state.area_light, self.state.reverse_orientation, token.path.parent, token.where())
        if self.current_object is not None:
            self.scene.objects[self.current_object].append(record)
        else:
            self.scene.shapes.append(record)


def parse_pbrt(path: str | Path, search_paths: list[Path] | None = None,
               transform_blocks_keep_all: bool = False) -> PbrtScene:
    """Read a pbrt scene file (with its Includes) into records.

    ``TransformEnd`` restores only the transform (pbrt-v1 to v3), or, with
    ``transform_blocks_keep_all``, the whole graphics state: pbrt-v4's parser reads the deprecated
    TransformBegin/End as AttributeBegin/End (``src/pbrt/parser.cpp``)."""
    path = Path(path)
    if not _is_file(path):
        try:
            what = "is a directory, not a scene file" if path.is_dir() else "no such scene file"
        except (OSError, ValueError) as err:
            what = f"cannot read scene file: {getattr(err, 'strerror', None) or err}"
        raise UserError(f"{path}: {what}")
    return _Parser(path, list(search_paths or []), transform_blocks_keep_all).run()
