"""The package's layering: each subpackage imports only the layers below it (docs/architecture.md).

Every ``import`` in every module is read from the source (function-level and type-checking
imports included), so a new dependency that points the wrong way fails here.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "realistic"
#: Layer -> the layers its modules may import, lowest first.
ALLOWED = {
    "core": {"errors", "core"},
    "device": {"errors", "core", "device"},  # the OpenCL device, between core and camera
    "optics": {"errors", "core", "optics"},
    "camera": {"errors", "core", "device", "optics", "camera"},
    "scene": {"errors", "core", "device", "optics", "camera", "scene"},
    "renderer": {"errors", "core", "device", "optics", "camera", "scene", "renderer"},
}


def imported_layers(path: Path) -> set[str]:
    layers = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = [node.module or ""] if isinstance(node, ast.ImportFrom) else (
            [alias.name for alias in node.names] if isinstance(node, ast.Import) else [])
        for name in names:
            parts = name.split(".")
            if parts[0] == "realistic" and len(parts) > 1:
                layers.add(parts[1])
    return layers


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_imports_only_the_layers_below_it(layer):
    modules = sorted((PACKAGE / layer).rglob("*.py"))
    assert modules, f"no modules in {layer}/"
    wrong = {str(m.relative_to(PACKAGE)): sorted(imported_layers(m) - ALLOWED[layer]) for m in modules}
    assert not {m: w for m, w in wrong.items() if w}


def test_lens_model_knows_no_file_format():
    assert not any("formats" in name for name in _module_imports(PACKAGE / "optics" / "lens.py"))


def _module_imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
