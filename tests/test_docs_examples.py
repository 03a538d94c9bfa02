"""Every shell and Python block of README.md and docs/*.md runs as written (issue 33: a README that runs).

Blocks fenced as ``sh``, ``bash``, ``console`` (its ``$ `` lines) or ``python`` run in a fresh folder
laid out as a clone after the quick start: the repository's files linked in (``bench/`` as a folder
of its own, so a documented bench writes its JSON there and not into the repository), ``.venv`` and
``python`` the interpreter running the tests, the repository on PYTHONPATH, and ``../shared`` the
project's reference data (a block that names it skips when it is absent). A Python block runs after
the Python blocks above it in its file, as a reader runs them. A block naming the TLS scheduler
``tls://127.0.0.1:8786`` gets one there, with certificates under the names the block gives.

What is run is what is documented: a slow example is made smaller in the document, never here.
``EXCLUDED`` lists the blocks that cannot run here and why.
"""

import importlib
import importlib.util
import json
import os
import re
import shutil
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from conftest import SHARED
from tls_helpers import certificates

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELLS = {"sh", "bash", "console"}
FENCE = re.compile(r"^(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`\s]*)")

#: (document, text the block holds) -> why the block is not run.
EXCLUDED = {
    ("README.md", "pip install"): "the quick start installs the package into a new venv and runs the whole suite: "
                                  "CI's .ci/run does exactly that on every clean clone",
    ("farm.md", 'pip install ".[farm]"'): "installs the farm extra, which the test extra (installed to run this) holds",
    ("robustness.md", "--hypothesis-profile=long"): "the long fuzzing search (5,000 examples a test) is for hand "
                                                    "runs; CI runs the same tests at the ci profile",
    ("farm.md", "bench/farm.py                       #"): "the measurement behind farm.md's tables takes many "
                                                           "minutes; the next block runs the same script small",
}

#: (document, text the block holds) -> the message it fails with today. Both: ``--resume`` without a
#: checkpoint is refused, which h-cli is changing (issue 33); the resume line ends its block, so every
#: command above it has run when the block fails there.
TLS_SCHEDULER = "tls://127.0.0.1:8786"
#: The certificate files the TLS examples name, made for the test's scheduler.
TLS_FILES = {"ca": "ca.pem", "cert": "client.pem", "key": "client-key.pem"}


@dataclass(frozen=True)
class Block:
    """One fenced block: its document (relative to the repository), the line of its opening fence,
    its language and its text."""

    document: Path
    line: int
    language: str
    text: str

    @property
    def id(self) -> str:
        return f"{self.document}:{self.line}"

    def holds(self, key: tuple[str, str]) -> bool:
        """Whether ``key`` (document name, text) picks this block."""
        return self.document.name == key[0] and key[1] in self.text


def fenced_blocks(path: Path) -> Iterator[Block]:
    """The fenced blocks of a Markdown file whose language is a shell or Python."""
    lines = path.read_text(encoding="utf-8").splitlines()
    opened: tuple[int, str, str] | None = None  # line, fence, language
    body: list[str] = []
    for number, line in enumerate(lines, 1):
        match = FENCE.match(line.strip())
        if opened is None:
            if match:
                opened, body = (number, match["fence"], match["info"].lower()), []
        elif match and line.strip().startswith(opened[1]) and not match["info"]:
            start, _, language = opened
            if language in SHELLS or language == "python":
                yield Block(path.relative_to(ROOT), start, language, "\n".join(body) + "\n")
            opened = None
        else:
            body.append(line)


def console_commands(text: str) -> str:
    """The commands of a ``console`` block: its ``$ `` lines and their continuation lines."""
    commands: list[str] = []
    continued = False
    for line in text.splitlines():
        if continued or line.startswith("$ "):
            commands.append(line if continued else line[2:])
            continued = line.rstrip().endswith("\\")
    return "\n".join(commands) + "\n"


BLOCKS = [block for path in DOCUMENTS for block in fenced_blocks(path)]


def test_every_listed_block_exists() -> None:
    """Each exclusion picks exactly one block, so none outlives its block."""
    for key in EXCLUDED:
        assert sum(block.holds(key) for block in BLOCKS) == 1, f"{key} should pick one block"


@pytest.fixture(scope="module")
def tls_scheduler(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    """A one-worker TLS cluster at ``TLS_SCHEDULER``; the certificate files it accepts."""
    distributed = pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")
    if shutil.which("openssl") is None:
        pytest.skip("the openssl command makes the test certificates")
    host, port = TLS_SCHEDULER.removeprefix("tls://").split(":")
    with socket.socket() as probe:
        if probe.connect_ex((host, int(port))) == 0:
            pytest.skip(f"{TLS_SCHEDULER}, which the examples name, is taken by another program")
    files = certificates(tmp_path_factory.mktemp("tls"), "docs")
    security = distributed.security.Security(
        tls_ca_file=files["ca"], tls_scheduler_cert=files["cert"], tls_scheduler_key=files["key"],
        tls_worker_cert=files["cert"], tls_worker_key=files["key"], tls_client_cert=files["cert"],
        tls_client_key=files["key"], require_encryption=True)
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, protocol="tls://",
                                       host=host, scheduler_port=int(port), security=security,
                                       dashboard_address=":0")  # any free port: 8787 may be taken
    yield files
    cluster.close()


def clone(folder: Path) -> Path:
    """``folder/repo``: the repository's files linked in, ``bench/`` a folder of links less its results,
    ``.venv`` this interpreter's environment and ``folder/shared`` the reference data when present."""
    repo = folder / "repo"
    repo.mkdir()
    for entry in ROOT.iterdir():
        if entry.name not in {".git", ".venv", "bench"}:
            (repo / entry.name).symlink_to(entry)
    (repo / "bench").mkdir()
    for entry in (ROOT / "bench").iterdir():
        if entry.name != "results":
            (repo / "bench" / entry.name).symlink_to(entry)
    (repo / ".venv").symlink_to(sys.prefix)
    if SHARED.is_dir():
        (folder / "shared").symlink_to(SHARED)
    return repo


def script(block: Block) -> str:
    """What running ``block`` runs: a Python block after the Python blocks above it in its document,
    a console block's commands, a shell block as it is."""
    if block.language == "python":
        return "\n".join(b.text for b in BLOCKS if b.document == block.document and b.language == "python"
                         and b.line <= block.line)
    return console_commands(block.text) if block.language == "console" else block.text


def run(block: Block, repo: Path) -> subprocess.CompletedProcess:
    """``block``'s script run in the clone ``repo``, with ``python`` on PATH this interpreter (a script
    that runs it: a link would lose its virtual environment)."""
    tools = repo.parent / "bin"
    tools.mkdir()
    for name in ("python", "python3"):
        (tools / name).write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
        (tools / name).chmod(0o755)
    env = dict(os.environ, PATH=f"{tools}{os.pathsep}{os.environ['PATH']}", PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    shell = [sys.executable, "-c"] if block.language == "python" else ["bash", "-euo", "pipefail", "-c"]
    return subprocess.run([*shell, script(block)], cwd=repo, env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("block", BLOCKS, ids=[block.id for block in BLOCKS])
def test_documented_block_runs(block: Block, tmp_path: Path, request: pytest.FixtureRequest) -> None:
    for key, reason in EXCLUDED.items():
        if block.holds(key):
            pytest.skip(f"not run: {reason}")
    if "../shared" in script(block) and not SHARED.is_dir():
        pytest.skip(f"names ../shared, the project's reference data, which is not at {SHARED}")
    repo = clone(tmp_path)
    if TLS_SCHEDULER in script(block):
        files = request.getfixturevalue("tls_scheduler")
        for part, name in TLS_FILES.items():
            shutil.copy(files[part], repo / name)
    done = run(block, repo)
    output = f"{block.id} ({block.language}) exited {done.returncode}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    assert done.returncode == 0, output


def _read(document: str) -> str:
    """A document's text with its line breaks and runs of spaces as single spaces."""
    return " ".join((ROOT / document).read_text(encoding="utf-8").split())


def _layers() -> int:
    return sum((entry / "__init__.py").is_file() for entry in (ROOT / "realistic").iterdir())


def _kernels_named() -> bool:
    layout = _read("README.md").split("## Layout", 1)[1]
    return all(f"`{kernel.name}`" in layout for kernel in (ROOT / "kernels").glob("*.cl"))


def _library_lenses() -> int:
    from realistic.optics.formats import BUNDLED_LENSES, bundled_lens_files

    return len(bundled_lens_files()) - len(BUNDLED_LENSES)


def _aspheric_short_names() -> int:
    from realistic.optics.formats import BUNDLED_LENSES, load_lens

    return sum(load_lens(name).asphere_count > 0 for name in BUNDLED_LENSES)


def _without_dispersion() -> set[str]:
    from realistic.optics.formats import bundled_lens_files, load_lens

    return {name for name in bundled_lens_files() if not load_lens(name).has_dispersion}


def _dgauss100_gap() -> float:
    from realistic.optics.formats import load_lens

    return load_lens("dgauss100").film_gap_mm


def _parser_default(option: str) -> object:
    from realistic.cli import build_parser

    return getattr(build_parser().parse_args(["render"]), option)


def _slices(pixels: int, spp: int) -> list[int]:
    from realistic.renderer.pass_plan import DEFAULT_PASS_SAMPLES, slice_bounds

    return slice_bounds(pixels, spp, DEFAULT_PASS_SAMPLES)


def _first_pass_pixels(pixels: int, spp: int) -> int:
    from realistic.renderer.pass_plan import plan_passes

    return plan_passes(pixels, spp)[0].pixel_count


def _frames(out: str, count: int) -> tuple[str, str]:
    """The first and last frame files of a ``count``-frame sweep to ``out``."""
    from realistic.renderer.sweep import frame_path

    return frame_path(Path(out), 0).name, frame_path(Path(out), count - 1).name


def _task_passes() -> int:
    from realistic.renderer.farm import DEFAULT_TASK_SAMPLES
    from realistic.renderer.pass_plan import DEFAULT_PASS_SAMPLES

    return DEFAULT_TASK_SAMPLES // DEFAULT_PASS_SAMPLES


def _constant(module: str, names: str) -> object:
    """``module``'s constant ``names``, or a tuple of them for a comma-separated list."""
    imported = importlib.import_module(module)
    values = tuple(getattr(imported, name.strip()) for name in names.split(","))
    return values if len(values) > 1 else values[0]


#: (document, phrase, what the phrase says, computed): numbers the documents state that the code fixes.
FACTS = [
    ("README.md", "the package in seven layers", 7, _layers),
    ("README.md", "`kernels/` holds the OpenCL kernels (`lens.cl`", True, _kernels_named),
    ("README.md", "The library holds 18 more prescriptions", 18, _library_lenses),
    ("README.md", "three bundled aspheric lenses", 3, _aspheric_short_names),
    ("README.md", "every bundled lens but `wide`, `fisheye`, `telephoto` and `tessar.100mm`",
     {"wide", "fisheye", "telephoto", "tessar.100mm"}, _without_dispersion),
    ("README.md", "its 72.228 mm film gap", 72.228, _dgauss100_gap),
    ("README.md", "(`--wavelengths-per-sample`, default 3)", 3,
     lambda: _constant("realistic.core.spectrum", "DEFAULT_WAVELENGTHS_PER_SAMPLE")),
    ("README.md", "`--maxdepth N` (pbrt's `maxdepth`, default 5)", 5,
     lambda: _constant("realistic.scene.pbrt.lights", "DEFAULT_MAX_DEPTH")),
    ("docs/farm.md", "by default 2^19 camera and shadow rays' worth: 262,144 samples at one light sample",
     (2 ** 19, 262_144), lambda: (_constant("realistic.renderer.pass_plan", "PASS_RAYS"),
                                  _constant("realistic.renderer.pass_plan", "DEFAULT_PASS_SAMPLES"))),
    ("docs/farm.md", "the slices are samples [0,1), [1,2), [2,4) ... [32,64), the first pass a whole 1-spp frame",
     ([0, 1, 2, 4, 8, 16, 32, 64], 512 * 512), lambda: (_slices(512 * 512, 64), _first_pass_pixels(512 * 512, 64))),
    ("docs/farm.md", "At 3840x2160 and 1,024 spp that is 11 x 199 MB", (11, 199),
     lambda: (len(_slices(3840 * 2160, 1024)) - 1, round(3840 * 2160 * 24 / 1e6))),
    ("docs/farm.md", "(4 passes of the default size at one light sample)", 4, _task_passes),
    ("docs/farm.md", "(up to 262,144 pixels in a 1-sample slice", 262_144,
     lambda: _constant("realistic.renderer.pass_plan", "DEFAULT_PASS_SAMPLES")),
    ("README.md", "--sweep focus=0.5:5:8 --out pull.exr # pull_0001.exr .. pull_0008.exr",
     ("pull_0001.exr", "pull_0008.exr"), lambda: _frames("pull.exr", 8)),
    ("docs/farm.md", "(`render.exr` by default): `render_0001.exr` to `render_0006.exr`",
     ("render_0001.exr", "render_0006.exr"), lambda: _frames("render.exr", 6)),
    ("docs/farm.md", "Every `--checkpoint-every` seconds (default 60", 60, lambda: _parser_default("checkpoint_every")),
    ("docs/farm.md", "A sweep has at most 10,000 frames (`sweep.MAX_FRAMES`", 10_000,
     lambda: _constant("realistic.renderer.sweep", "MAX_FRAMES")),
    *[("docs/robustness.md", phrase, stated, lambda module=module, name=name: _constant(module, name))
      for phrase, stated, module, name in [
          ("| image side | 1 to 65,536 pixels |", 65_536, "realistic.core.validation", "MAX_IMAGE_SIDE"),
          ("| pixels | below 2^31 |", 2 ** 31 - 1, "realistic.core.validation", "MAX_PIXELS"),
          ("| samples per pixel | 1 to 2^24 |", 2 ** 24, "realistic.core.validation", "MAX_SPP"),
          ("| seed | 0 to 2^32 - 1 |", 2 ** 32 - 1, "realistic.core.validation", "MAX_SEED"),
          ("| light samples | 1 to 1024 |", 1024, "realistic.core.validation", "MAX_LIGHT_SAMPLES"),
          ("| maxanisotropy | 1 to 1024 |", 1024, "realistic.core.validation", "MAX_ANISOTROPY"),
          ("| film diagonal | above 0, at most 1000 mm |", 1000, "realistic.core.validation",
           "MAX_FILM_DIAGONAL_MM"),
          ("| blades | 3 to 64 |", (3, 64), "realistic.core.validation", "MIN_BLADES, MAX_BLADES"),
          ("| pixel filter radius | above 0, at most 16 pixels |", 16, "realistic.core.validation",
           "MAX_FILTER_RADIUS"),
          ("at most 1024 (`optics.lens.MAX_SURFACES`)", 1024, "realistic.optics.lens", "MAX_SURFACES"),
          ("depth at most 64 (`MAX_INCLUDE_DEPTH`)", 64, "realistic.scene.pbrt.parser", "MAX_INCLUDE_DEPTH"),
          ("shapes beyond 1e18 are skipped", 1e18, "realistic.scene.pbrt.values", "MAX_WORLD_COORDINATE"),
          ("magnitude at most 1e12 (`scene.meshes.MAX_COORDINATE`)", 1e12, "realistic.scene.meshes",
           "MAX_COORDINATE"),
          ("| shutter time | 1e-9 to 1e6 s |", (1e-9, 1e6), "realistic.core.validation",
           "MIN_SHUTTER_SECONDS, MAX_SHUTTER_SECONDS"),
          ("| ISO speed | 1 to 1e7 |", (1, 1e7), "realistic.core.validation", "MIN_ISO, MAX_ISO"),
          ("| preview exposure | -64 to +64 stops |", 64, "realistic.core.validation", "MAX_EXPOSURE_STOPS"),
          ("magnitude at most 1e30 (`checkpoint.MAX_SUM`)", 1e30, "realistic.renderer.checkpoint", "MAX_SUM"),
          ("| sweep frames | 1 to 10,000 (`sweep.MAX_FRAMES`) |", 10_000, "realistic.renderer.sweep", "MAX_FRAMES"),
      ]],
]


@pytest.mark.parametrize(("document", "phrase", "stated", "computed"), FACTS,
                         ids=[f"{document}:{phrase[:40]}" for document, phrase, _, _ in FACTS])
def test_documented_number_holds(document: str, phrase: str, stated: object, computed: object) -> None:
    assert phrase in _read(document), f"{document} no longer says {phrase!r}: update FACTS"
    assert computed() == stated, f"{document} says {phrase!r}; the code gives {computed()!r}"


def test_lens_library_table_is_what_lens_list_computes() -> None:
    """docs/lenses.md's table (EFL, f-number, image circle, elements) against ``lens list``'s numbers,
    each to the digits the table prints, and no aspheric surface, as the page says."""
    from realistic.optics.library import library_entry

    rows = re.findall(r"^\| `([^`]+)` \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| (\d+) \|",
                      (ROOT / "docs" / "lenses.md").read_text(encoding="utf-8"), re.MULTILINE)
    assert len(rows) == _library_lenses()
    for name, efl, f_number, circle, elements in rows:
        entry = library_entry(name)
        computed = (f"{entry['focal_length_mm']:.2f}", f"{entry['f_number']:.2f}", f"{entry['image_circle_mm']:.1f}",
                    str(entry["elements"]))
        assert (efl, f_number, circle, elements) == computed, name
        assert entry["aspheres"] == 0, name


def test_shipped_heart_is_what_its_script_makes() -> None:
    """examples/heart.png holds the levels examples/make_heart.py computes (decoded pixels, so another
    PNG encoder's bytes would do), and the stop it makes is open inside and closed at the corners."""
    import imageio.v3 as iio

    from realistic.optics.stop_shape import mask_stop

    spec = importlib.util.spec_from_file_location("make_heart", ROOT / "examples" / "make_heart.py")
    assert spec is not None and spec.loader is not None
    make_heart = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_heart)
    assert (iio.imread(ROOT / "examples" / "heart.png") == make_heart.heart()).all()
    mask = mask_stop(ROOT / "examples" / "heart.png").mask
    side = mask.shape[0]
    assert mask[side // 2, side // 2] and not mask[0, 0] and not mask[-1, -1] and not mask[-1, 0]


def test_shipped_rays_trace_as_readme_says(tmp_path: Path) -> None:
    """examples/rays.json: four rays from the film through ``dgauss`` at 36.77 mm, the last one blocked."""
    from realistic.cli import main

    out = tmp_path / "out.json"
    assert main(["lens", "trace", "dgauss", "--film-distance", "36.77", "--input", str(ROOT / "examples" / "rays.json"),
                 "--output", str(out)]) == 0
    rays = json.loads(out.read_text())["rays"]
    assert "holds four rays from the film, the last one blocked" in _read("README.md")
    assert len(rays) == 4 and ["blocked_by" in ray for ray in rays] == [False, False, False, True]
