"""The classes a scene names by a string: its controller, its reclaim rate control and its
anti-collision interlock.

`[controller] type`, `[reclaim.rate_control] type` and `[interlock] type` name a built-in class
("pid") or a class in
a Python file beside the scene ("my_controller.py:MyController"). The built-ins are held as
"module:Class" strings and imported only where a class is used (a lockstep being built, a
controller's scene keys being checked against its `Settings`), so the configuration layer has no
import of controller code.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib
import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path

from bwr_twin.config import plugin_guard
from bwr_twin.config.plugin_guard import Exited, Overrun, watch
from bwr_twin.errors import PluginError, SceneError


@dataclass(frozen=True)
class Slot:
    """A place in a scene that names a class.

    Attributes:
        key: the dotted scene key that names it, for messages.
        base: "module:Class" that every class in the slot derives from.
        built_in: name -> "module:Class".
        default: the built-in name a scene without the key gets.
    """

    key: str
    base: str
    built_in: dict[str, str]
    default: str


CONTROLLERS = Slot(
    key="controller.type",
    base="bwr_twin.control.interface:Controller",
    built_in={
        "fuzzy_model": "bwr_twin.control.controller:FuzzyModelController",
        "pid": "bwr_twin.control.pid:PidController",
        "computed_torque": "bwr_twin.control.computed_torque:ComputedTorqueController",
    },
    default="fuzzy_model",  # the paper's controller
)
RATE_CONTROLS = Slot(
    key="reclaim.rate_control.type",
    base="bwr_twin.control.rate:RateControl",
    built_in={
        "open_loop": "bwr_twin.control.rate:RateControl",
        "belt_scale": "bwr_twin.control.rate:BeltScale",
        "wheel_power": "bwr_twin.control.rate:WheelPower",
        "power_and_scale": "bwr_twin.control.rate:PowerAndScale",
    },
    default="open_loop",
)


INTERLOCKS = Slot(
    key="interlock.type",
    base="bwr_twin.collision.interlock:Interlock",
    built_in={"zones": "bwr_twin.collision.interlock:ZoneInterlock"},
    default="zones",
)


def is_file_reference(name: str) -> bool:
    """'folder/my_controller.py:MyController' rather than a built-in name."""
    file, _, _ = name.rpartition(":")
    return file.endswith(".py")


def plugin_class(slot: Slot, name: str) -> type:
    """The class `name` stands for in `slot`; SceneError (without the scene's path) if there is none."""
    if name in slot.built_in:
        return _imported(slot.built_in[name])
    if not is_file_reference(name):
        raise SceneError(f"'{slot.key}' must be one of {', '.join(slot.built_in)} or "
                         f"\"file.py:ClassName\", got {name!r}")
    file, _, attribute = name.rpartition(":")
    return class_in_file(Path(file), attribute, _imported(slot.base), slot.key)


def controller_class(name: str) -> type:
    """The controller class a scene's `controller.type` names, its `Settings` a dataclass.

    Imports bwr_twin.fis.convert as well, which adds the .fis reader to the rule base's readers
    (bwr_twin.control.rulebase.READERS): a fuzzy_model controller's rule base may be a .fis file.
    """
    import bwr_twin.fis.convert  # noqa: F401 - its reader of .fis rule bases, added on import

    cls = plugin_class(CONTROLLERS, name)
    settings = getattr(cls, "Settings", None)
    if not (isinstance(settings, type) and dataclasses.is_dataclass(settings)):
        file, _, attribute = name.rpartition(":")
        raise SceneError(f"{file}: {attribute}.Settings must be a dataclass of its scene keys")
    return cls


def rate_control_class(name: str) -> type:
    """The rate control class a scene's `reclaim.rate_control.type` names."""
    return plugin_class(RATE_CONTROLS, name)


def interlock_class(name: str) -> type:
    """The interlock class a scene's `interlock.type` names."""
    return plugin_class(INTERLOCKS, name)


def _imported(reference: str) -> type:
    module, _, attribute = reference.partition(":")
    return getattr(importlib.import_module(module), attribute)


@functools.cache
def class_in_file(file: Path, attribute: str, base: type, key: str) -> type:
    """The class `attribute` of the Python file `file`, derived from `base`; SceneError naming
    the scene's `key` or the file if there is none."""
    if not file.is_file():
        raise SceneError(f"'{key}': {file} does not exist")
    # A module name of its own per file, so two files may both hold `MyController`.
    module_name = f"bwr_twin_user_class_{hashlib.sha256(str(file).encode()).hexdigest()[:12]}"
    spec = importlib.util.spec_from_file_location(module_name, file)
    module = importlib.util.module_from_spec(spec)
    plugin_guard.start()  # sys.exit, os._exit and a hang at import become errors naming the file
    watch.call = current = (str(file), "import", 0.0)
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        raise SceneError(f"{file}:{exc.lineno}: {exc.msg}") from None
    except SystemExit as exc:
        raise PluginError(f"{file}: importing it called sys.exit({'' if exc.code is None else repr(exc.code)}) "
                          f"('{key}'): a plug-in must not end the twin") from None
    except Exited as exc:
        raise PluginError(f"{file}: importing it called os._exit({exc.code!r}) ('{key}'): a plug-in must not end "
                          "the twin") from None
    except Overrun:
        raise PluginError(f"{file}: importing it ran longer than the budget of {watch.budget:g} s a plug-in call "
                          f"('{key}'); set {plugin_guard.BUDGET_VARIABLE} (s, 0 for none) to give it longer") from None
    except Exception as exc:  # noqa: BLE001 - the engineer's file failed to import: say where
        raise SceneError(f"{file}: importing it raised {type(exc).__name__}: {exc}") from None
    finally:
        if watch.call is current:
            watch.call = None
    sys.modules[module_name] = module  # dataclasses and pickling look classes up by module
    cls = getattr(module, attribute, None)
    if not (isinstance(cls, type) and issubclass(cls, base)):
        package = base.__module__.rpartition(".")[0]  # as the package exports it
        raise SceneError(f"{file}: has no class {attribute!r} derived from {package}.{base.__name__}")
    return cls
