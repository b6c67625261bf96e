"""A scene's TOML tables built into its typed sections: every key checked against the dataclass's
field types (bwr_twin.config.sections), each refusal one line naming the file and the key. A key
the file leaves out takes its value from the shipped defaults (scenes/defaults/scene_defaults.toml),
and a table the defaults hold may be left out whole.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from pathlib import Path
from typing import Any, Literal

from bwr_twin.config.plugins import CONTROLLERS, controller_class
from bwr_twin.config.sections import TABLE_NAMES, ControllerSection
from bwr_twin.errors import SceneError
from bwr_twin.shipped import SCENE_DEFAULTS
from bwr_twin.tomlfile import MISSING, at_dotted, read_toml
from bwr_twin.values import is_integer, is_number

# Keys that have moved: old dotted key -> new dotted key.
MOVED_KEYS = {
    "controller.velocity_source": "encoders.velocity_source",
    "controller.velocity_filter": "encoders.velocity_filter",
}


@functools.cache
def _defaults() -> dict[str, Any]:
    return read_toml(SCENE_DEFAULTS, "defaults")


def build(cls: type, table: Any, path: Path, where: str) -> Any:
    """Build dataclass `cls` from a TOML table, checking keys and types."""
    if not isinstance(table, dict):
        raise SceneError(f"{path}: [{where}] must be a table")
    for key in table:
        if _join(where, key) in MOVED_KEYS:
            raise SceneError(f"{path}: '{_join(where, key)}' has moved: write it as '{MOVED_KEYS[_join(where, key)]}'")
    hints = _type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    shown = {TABLE_NAMES.get(n, n): n for n in fields}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        key = TABLE_NAMES.get(unknown[0], unknown[0])
        valid = ", ".join(sorted(shown))
        raise SceneError(f"{path}: unknown key '{_join(where, key)}' (valid here: {valid})")
    kwargs = {}
    for name, f in fields.items():
        key = _join(where, TABLE_NAMES.get(name, name))
        value = table.get(name, MISSING)
        if value is MISSING:
            if f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING:
                continue  # a choice, or "none"
            value = at_dotted(_defaults(), key)
            if isinstance(value, dict):
                value = {}  # a table the defaults hold: built from them alone
            elif value is MISSING:
                raise SceneError(f"{path}: missing key '{key}'")
        kwargs[name] = _convert(hints[name], value, path, key)
    return cls(**kwargs)


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)  # evaluates the annotations' text: slow, and never changes


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _convert(hint: Any, value: Any, path: Path, key: str) -> Any:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _convert(inner, value, path, key)
    if hint is ControllerSection:
        return _build_controller(value, path, key)
    if dataclasses.is_dataclass(hint):
        return build(hint, value, path, key)
    if origin is Literal:
        if value not in args:
            raise SceneError(f"{path}: '{key}' must be one of {list(args)}, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise SceneError(f"{path}: '{key}' must be a list, got {type(value).__name__}")
        if args[-1] is Ellipsis:
            return tuple(_convert(args[0], v, path, f"{key}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            meaning = " (travel, slew, luff)" if len(args) == 3 else ""
            raise SceneError(f"{path}: '{key}' must hold {len(args)} values{meaning}, got {len(value)}")
        return tuple(_convert(a, v, path, f"{key}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if hint is float:
        if not is_number(value):
            raise SceneError(f"{path}: '{key}' must be a finite number, got {value!r}")
        return float(value)
    if hint is int:
        if not is_integer(value):
            raise SceneError(f"{path}: '{key}' must be an integer, got {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise SceneError(f"{path}: '{key}' must be true or false, got {value!r}")
        return value
    if hint is Path:
        if not isinstance(value, str):
            raise SceneError(f"{path}: '{key}' must be a file path, got {value!r}")
        return Path(value)
    if hint is str:
        if not isinstance(value, str):
            raise SceneError(f"{path}: '{key}' must be a string, got {value!r}")
        return value
    raise TypeError(f"unsupported scene field type {hint}")  # a bug here, not in the file


def _build_controller(table: Any, path: Path, where: str) -> ControllerSection:
    """[controller]: its `type` picks the Settings dataclass that the other keys must fill."""
    from bwr_twin.control.interface import SettingsError

    if not isinstance(table, dict):
        raise SceneError(f"{path}: [{where}] must be a table")
    type_name = table.get("type", CONTROLLERS.default)
    if not isinstance(type_name, str):
        raise SceneError(f"{path}: '{where}.type' must be a string, got {type_name!r}")
    try:
        cls = controller_class(type_name)
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None
    settings = build(cls.Settings, {k: v for k, v in table.items() if k != "type"}, path, where)
    try:
        getattr(settings, "validate", lambda: None)()
    except SettingsError as exc:
        raise SceneError(f"{path}: '{where}.{exc.key}' {exc.message}") from None
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - an engineer's validate(): say whose
        raise SceneError(f"{path}: controller {type_name}: {cls.__name__}.Settings.validate() raised "
                         f"{type(exc).__name__}" + (f": {exc}" if str(exc) else "")) from None
    return ControllerSection(type_name, settings)

