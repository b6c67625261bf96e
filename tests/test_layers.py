"""Every import of the package points down the layers of bwr_twin.layers, never up or sideways.

Each module is parsed, not imported: every import counts, at module level, inside a function, under
`if TYPE_CHECKING`, relative or absolute.
"""

import ast
from pathlib import Path

import pytest

from bwr_twin.layers import LAYERS

PACKAGE = Path(__file__).resolve().parents[1] / "bwr_twin"
LEVEL = {unit: i for i, layer in enumerate(LAYERS) for unit in layer}


def module_name(path: Path) -> str:
    """'bwr_twin.sim.lockstep' for PACKAGE/sim/lockstep.py, 'bwr_twin.sim' for its __init__.py."""
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def unit_of(module: str) -> str:
    """The unit a module belongs to: its sub-package or top-level module; 'bwr_twin' for the package."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def imported(tree: ast.AST, module: str, is_package: bool) -> list[tuple[int, str]]:
    """(line, module) of every bwr_twin module `tree` imports; `from bwr_twin import x` counts as
    bwr_twin.x, since x may be a sub-package or a module."""
    package = module if is_package else module.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            if source == "bwr_twin":
                found += [(node.lineno, f"bwr_twin.{alias.name}") for alias in node.names]
            else:
                found.append((node.lineno, source))
    return [(line, name) for line, name in found if name == "bwr_twin" or name.startswith("bwr_twin.")]


def violations(source: str, path: str, module: str, is_package: bool = False) -> list[str]:
    """One line per import in `source` (the text of `module`, at `path`) that runs up or sideways."""
    unit = unit_of(module)
    if unit not in LEVEL:
        return [f"{path}: {unit} is in no layer of bwr_twin.layers.LAYERS"]
    found = []
    for line, name in imported(ast.parse(source, path), module, is_package):
        target = unit_of(name)
        if target == unit:
            continue
        if target not in LEVEL:
            found.append(f"{path}:{line}: imports {name}, whose {target} is in no layer")
        elif LEVEL[target] >= LEVEL[unit]:
            way = "up" if LEVEL[target] > LEVEL[unit] else "sideways"
            found.append(f"{path}:{line}: {unit} (layer {LEVEL[unit]}) imports {name} from {target} "
                         f"(layer {LEVEL[target]}): {way}")
    return found


def test_every_import_of_the_package_points_down():
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        found += violations(path.read_text(encoding="utf-8"), str(path.relative_to(PACKAGE.parent)),
                            module_name(path), path.name == "__init__.py")
    assert not found, "\n".join(found)


def test_every_unit_of_the_package_has_one_layer():
    units = {unit_of(module_name(path)) for path in PACKAGE.rglob("*.py")}
    declared = [unit for layer in LAYERS for unit in layer]
    assert len(declared) == len(set(declared)), "a unit in two layers"
    assert units == set(declared), f"undeclared: {sorted(units - set(declared))}, gone: {sorted(set(declared) - units)}"


UP_IMPORTS = {
    "module level": "from bwr_twin.sim.lockstep import simulate\n",
    "plain import": "import bwr_twin.results.rundir\n",
    "in a function": "def f():\n    from bwr_twin.sim.twin import Twin\n    return Twin\n",
    "type checking": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from bwr_twin.sim.record import RunResult\n",
    "relative": "from ..sim import lockstep\n",
    "relative module": "from ..collision.monitor import PileClearance\n",
    "the package": "from bwr_twin import sim\n",
}


@pytest.mark.parametrize("source", UP_IMPORTS.values(), ids=UP_IMPORTS.keys())
def test_an_up_import_is_caught(source):
    found = violations(source, "bwr_twin/model/fake.py", "bwr_twin.model.fake")
    assert len(found) == 1, found
    model = next(i for i, layer in enumerate(LAYERS) if "model" in layer)
    assert found[0].startswith("bwr_twin/model/fake.py:") and f"model (layer {model})" in found[0] and " up" in found[0]


def test_a_sideways_import_is_caught():
    found = violations("x = 1\nfrom bwr_twin.collision.pile import PileClearance\n", "bwr_twin/sensing/fake.py",
                       "bwr_twin.sensing.fake")
    assert found == [f"bwr_twin/sensing/fake.py:2: sensing (layer {LEVEL['sensing']}) imports bwr_twin.collision.pile "
                     f"from collision (layer {LEVEL['collision']}): sideways"]


def test_imports_within_a_unit_and_down_pass():
    source = "from . import machine\nfrom .spec import Drawing\nfrom bwr_twin.errors import ModelError\nimport numpy\n"
    assert violations(source, "bwr_twin/model/fake.py", "bwr_twin.model.fake") == []
    assert violations("from .model import machine\n", "bwr_twin/__init__.py", "bwr_twin", is_package=True) == []
