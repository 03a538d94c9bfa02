"""Every shell and Python block of README.md and docs/*.md runs as written (issue 33: a README that runs).

Blocks fenced as ``sh``, ``bash``, ``console`` (its ``$ `` lines) or ``python`` run in a fresh folder
laid out as a clone after the quick start: the repository's files linked in (``bench/`` as a folder
of its own, so a documented bench writes its JSON there and not into the repository), ``.venv`` and
``python`` the interpreter running the tests, the repository on PYTHONPATH, and ``../shared`` the
project's reference data (a block that names it skips when it is absent). A Python block runs after
the Python blocks above it in its file, as a reader runs them. A block naming the TLS scheduler
``tls://127.0.0.1:8786`` gets one there, with certificates under the names the block gives.

What is run is what is documented: a slow example is made smaller in the document, never here.
``EXCLUDED`` lists the blocks that cannot run here and why; ``KNOWN_FAILURES`` the documented
commands that fail today, each with the message it fails with (an entry whose block passes fails,
so that it is removed when the fix lands).
"""

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

#: (document, text the block holds) -> the message it fails with today, and why.
KNOWN_FAILURES = {
    ("README.md", "--checkpoint-every 60 --resume"): "no checkpoint to resume",
    ("farm.md", "--resume   # after a crash"): "no checkpoint to resume",
}

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
    """Each exclusion and known failure picks exactly one block, so none outlives its block."""
    for key in [*EXCLUDED, *KNOWN_FAILURES]:
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
                                       dashboard_address=None)
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


def run(block: Block, repo: Path) -> subprocess.CompletedProcess:
    """``block`` run in the clone ``repo`` (Python after the Python blocks above it in its document), with
    ``python`` on PATH this interpreter (a script that runs it: a link would lose its virtual environment)."""
    tools = repo.parent / "bin"
    tools.mkdir()
    for name in ("python", "python3"):
        (tools / name).write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
        (tools / name).chmod(0o755)
    env = dict(os.environ, PATH=f"{tools}{os.pathsep}{os.environ['PATH']}", PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    if block.language == "python":
        earlier = [b.text for b in BLOCKS if b.document == block.document and b.language == "python"
                   and b.line <= block.line]
        command = [sys.executable, "-c", "\n".join(earlier)]
    else:
        script = console_commands(block.text) if block.language == "console" else block.text
        command = ["bash", "-euo", "pipefail", "-c", script]
    return subprocess.run(command, cwd=repo, env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("block", BLOCKS, ids=[block.id for block in BLOCKS])
def test_documented_block_runs(block: Block, tmp_path: Path, request: pytest.FixtureRequest) -> None:
    for key, reason in EXCLUDED.items():
        if block.holds(key):
            pytest.skip(f"not run: {reason}")
    if "../shared" in block.text and not SHARED.is_dir():
        pytest.skip(f"names ../shared, the project's reference data, which is not at {SHARED}")
    repo = clone(tmp_path)
    if TLS_SCHEDULER in block.text:
        files = request.getfixturevalue("tls_scheduler")
        for part, name in TLS_FILES.items():
            shutil.copy(files[part], repo / name)
    done = run(block, repo)
    output = f"{block.id} ({block.language}) exited {done.returncode}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    failure = next((message for key, message in KNOWN_FAILURES.items() if block.holds(key)), None)
    if failure is None:
        assert done.returncode == 0, output
    else:
        assert done.returncode != 0, f"{block.id} passes now: remove it from KNOWN_FAILURES"
        assert failure in done.stderr, output
        pytest.xfail(f"fails as known: {failure}")
