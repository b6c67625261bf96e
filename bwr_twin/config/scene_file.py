"""A scene file's tables as TOML gives them, before they are typed: the scene it extends laid under
it, alternatives and `replace` applied, paths made absolute, overrides laid over it.
"""

from __future__ import annotations

import copy
import functools
from pathlib import Path
from typing import Any

from bwr_twin.config.faults import check_fault_count
from bwr_twin.config.plugins import CONTROLLERS, INTERLOCKS, RATE_CONTROLS, is_file_reference
from bwr_twin.config.sections import TABLE_NAMES
from bwr_twin.errors import SceneError
from bwr_twin.textfile import version
from bwr_twin.tomlfile import read_toml, set_dotted


def scene_tables(path: Path, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The scene file's tables, named as Scene's fields, with `overrides` (dotted keys; relative
    paths in them relative to the cwd) laid over them: one of ALTERNATIVES' keys replaces the
    others, as in a file that extends."""
    raw = copy.deepcopy(_read_raw_once(path, version(path)))
    for key, value in (overrides or {}).items():
        if _is_path_key(key):
            value = _resolve_paths(value, Path.cwd())
        elif key in CLASS_KEYS:
            value = _resolve_class_reference(value, Path.cwd())
        try:
            set_dotted(raw, key, copy.deepcopy(value))
        except ValueError as exc:
            raise SceneError(f"{path}: override '{key}': {exc}") from None
        _drop_alternatives(raw, key)
    return _rename_tables(raw)


@functools.lru_cache(maxsize=32)
def _read_raw_once(path: Path, stamp: tuple) -> dict:
    """_read_raw, once per version of a file: a sweep loads one base scene for every run."""
    return _read_raw(path, ())


def _read_raw(path: Path, extended_by: tuple[Path, ...]) -> dict:
    """The file's tables, paths made absolute, merged over the scene it extends."""
    if extended_by and not path.is_file():
        raise SceneError(f"{path}: scene file not found (extended by {extended_by[-1]})")
    raw = read_toml(path, "scene", check_text=check_fault_count)  # the faults counted before a table is parsed
    base = raw.pop("extends", None)
    replace = raw.pop("replace", [])
    raw = _resolve_paths(raw, path.parent)
    if base is None:
        if replace:
            raise SceneError(f"{path}: 'replace' names tables of the scene it extends, but it has no 'extends'")
        return raw
    if not isinstance(base, str):
        raise SceneError(f"{path}: 'extends' must be a file path or a shipped scene's name, got {base!r}")
    if not (isinstance(replace, list) and all(isinstance(t, str) and t for t in replace)):
        raise SceneError(f"{path}: 'replace' must be a list of table names, e.g. [\"digging\"], got {replace!r}")
    base_path = _extended(path, base)
    chain = extended_by + (path.resolve(),)
    if base_path in chain:
        raise SceneError(f"{path}: 'extends' makes a cycle through {base_path.name}")
    base_raw = _read_raw(base_path, chain)
    merged = _merged(base_raw, raw)
    named = raw.get("controller", {}).get("type") if isinstance(raw.get("controller"), dict) else None
    if named is not None and named != _controller_type(base_raw):
        merged["controller"] = raw["controller"]  # another controller: none of the base's settings
    for dotted, keys in ALTERNATIVES.items():
        given, inherited = _table(raw, dotted), _table(merged, dotted)
        if given is not None and inherited is not None and any(k in given for k in keys):
            for key in keys:
                if key not in given:
                    inherited.pop(key, None)  # one alternative replaces the base's other
    for dotted in replace:
        *parents, name = dotted.split(".")
        node, own = merged, _table(raw, ".".join(parents)) if parents else raw
        for parent in parents:
            node = node.get(parent) if isinstance(node, dict) else None
        if isinstance(node, dict) and name in node:
            node.pop(name)  # this file's table, or none: nothing of the base's
            if own is not None and name in own:
                node[name] = own[name]
    return merged


# Keys of a table that exclude each other: a scene that extends another and gives one of them
# replaces whichever of them its base gave ("" is the top level).
ALTERNATIVES = {
    "": ("path", "reclaim", "stacking"),
    "stockpile": ("windrow", "surface_file"),
    "reclaim.stop": ("benches", "tonnes", "time"),
}


def _drop_alternatives(raw: dict, dotted: str) -> None:
    """An override of one of ALTERNATIVES' keys replaces the others, as an extending file's does."""
    parent, _, name = dotted.rpartition(".")
    table = _table(raw, parent)
    if table is not None and name in ALTERNATIVES.get(parent, ()):
        for other in ALTERNATIVES[parent]:
            if other != name:
                table.pop(other, None)


def _table(raw: dict, dotted: str) -> dict | None:
    node: Any = raw
    for name in filter(None, dotted.split(".")):
        node = node.get(name) if isinstance(node, dict) else None
    return node if isinstance(node, dict) else None


def _extended(path: Path, base: str) -> Path:
    """The scene file `extends` names: relative to the scene's folder, or else a shipped scene's
    name, as on the command line ("heavy_reclaim"); relative paths win."""
    from bwr_twin.shipped import SCENES

    local = (path.parent / base).resolve()
    if local.is_file():
        return local
    for shipped in (SCENES / base, SCENES / f"{base}.toml"):
        if shipped.is_file():
            return shipped.resolve()
    raise SceneError(f"{path}: 'extends' names {base!r}, neither a file beside it ({local}) nor a shipped "
                     "scene (python -m bwr_twin.run lists them for a name it does not know)")


def _controller_type(raw: dict) -> str:
    """The controller type a raw scene names, or the default one."""
    table = raw.get("controller")
    return table.get("type", CONTROLLERS.default) if isinstance(table, dict) else CONTROLLERS.default


def _merged(base: dict, over: dict) -> dict:
    """`over` laid over `base`: tables merge key by key, anything else replaces."""
    out = dict(base)
    for key, value in over.items():
        out[key] = _merged(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _rename_tables(raw: dict) -> dict:
    out = dict(raw)
    for attr, table in TABLE_NAMES.items():
        if table in out:
            out[attr] = out.pop(table)
    return out


# Keys whose values are files, relative to the scene file that gives them: these, any key that
# ends in "_file", and the file part of a controller type "my_controller.py:MyController".
PATH_KEYS = frozenset({"mjcf", "controller_mjcf", "rule_base"})
# Keys that name a class, built in or "file.py:ClassName" relative to the scene file.
CLASS_KEYS = (CONTROLLERS.key, RATE_CONTROLS.key, INTERLOCKS.key)


def _is_path_key(dotted: str) -> bool:
    key = dotted.rsplit(".", 1)[-1]
    return key in PATH_KEYS or key.endswith("_file")


def _resolve_class_reference(value: Any, base: Path) -> Any:
    if not (isinstance(value, str) and is_file_reference(value)):
        return value
    file, _, name = value.rpartition(":")
    return f"{(base / file).resolve()}:{name}"


def _resolve_paths(raw: Any, base: Path) -> Any:
    """Make the path-valued keys absolute, relative to `base`."""
    if isinstance(raw, str):
        return str((base / raw).resolve())
    if not isinstance(raw, dict):
        return raw
    resolved = {
        k: (
            str((base / v).resolve())
            if _is_path_key(k) and isinstance(v, str)
            else _resolve_paths(v, base)
            if isinstance(v, dict)
            else v
        )
        for k, v in raw.items()
    }
    for dotted in CLASS_KEYS:
        *tables, key = dotted.split(".")
        node = resolved
        for table in tables:
            node = node.get(table) if isinstance(node, dict) else None
        if isinstance(node, dict) and key in node:
            node[key] = _resolve_class_reference(node[key], base)
    return resolved
