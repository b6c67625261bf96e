"""Which controller a scene's `[controller] type` names: a built-in one, or a class in a Python
file beside the scene ("my_controller.py:MyController")."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path

from bwr_twin.control.interface import Controller
from bwr_twin.errors import SceneError

BUILT_IN = {
    "fuzzy_model": "bwr_twin.control.controller:FuzzyModelController",
    "pid": "bwr_twin.control.pid:PidController",
    "computed_torque": "bwr_twin.control.computed_torque:ComputedTorqueController",
}
DEFAULT = "fuzzy_model"  # the paper's controller


def is_file_reference(name: str) -> bool:
    """'folder/my_controller.py:MyController' rather than a built-in name."""
    file, _, _ = name.rpartition(":")
    return file.endswith(".py")


def controller_class(name: str) -> type[Controller]:
    """The class `name` stands for; SceneError (without the scene's path) if there is none."""
    if name in BUILT_IN:
        module, _, attribute = BUILT_IN[name].partition(":")
        return getattr(importlib.import_module(module), attribute)
    if not is_file_reference(name):
        raise SceneError(f"'controller.type' must be one of {', '.join(BUILT_IN)} or "
                         f"\"file.py:ClassName\", got {name!r}")
    file, _, attribute = name.rpartition(":")
    cls = class_in_file(Path(file), attribute, Controller, "controller.type")
    settings = getattr(cls, "Settings", None)
    if not (isinstance(settings, type) and dataclasses.is_dataclass(settings)):
        raise SceneError(f"{file}: {attribute}.Settings must be a dataclass of its scene keys")
    return cls


@functools.cache
def class_in_file(file: Path, attribute: str, base: type, key: str) -> type:
    """The class `attribute` of the Python file `file`, derived from `base`; SceneError naming
    the scene's `key` or the file if there is none."""
    if not file.is_file():
        raise SceneError(f"'{key}': {file} does not exist")
    # A module name of its own per file, so two files may both hold `MyController`.
    module_name = f"bwr_twin_user_controller_{hashlib.sha256(str(file).encode()).hexdigest()[:12]}"
    spec = importlib.util.spec_from_file_location(module_name, file)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        raise SceneError(f"{file}:{exc.lineno}: {exc.msg}") from None
    except Exception as exc:  # noqa: BLE001 - the engineer's file failed to import: say where
        raise SceneError(f"{file}: importing it raised {type(exc).__name__}: {exc}") from None
    sys.modules[module_name] = module  # dataclasses and pickling look classes up by module
    cls = getattr(module, attribute, None)
    if not (isinstance(cls, type) and issubclass(cls, base)):
        package = base.__module__.rpartition(".")[0]  # as the package exports it
        raise SceneError(f"{file}: has no class {attribute!r} derived from {package}.{base.__name__}")
    return cls
