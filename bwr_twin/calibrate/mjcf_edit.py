"""The engineer's MJCF with each fitted number changed in place, as text: an attribute of the
joint or the body's `<inertial>` set (added if a default class gave it), and a comment beside the
element giving the log, the date, the value before and the 95 % interval. Everything else (the
comments, the layout, the default classes) stays as it was written."""

from __future__ import annotations

import re

from bwr_twin.errors import BwrError

_ATTRIBUTE = r'(\s{name}\s*=\s*)(["\'])(.*?)\2'


def _tag(text: str, kind: str, name: str) -> re.Match:
    """The start tag `<kind ... name="name" ...>`; BwrError if the file lacks it."""
    pattern = re.compile(rf'<{kind}\b[^>]*?\sname\s*=\s*(["\']){re.escape(name)}\1[^>]*?/?>', re.DOTALL)
    found = pattern.search(text)
    if found is None:
        raise BwrError(f"the MJCF has no <{kind} name=\"{name}\"> to write a fitted value into")
    return found


def _inertial_after(text: str, body: re.Match, name: str) -> re.Match:
    """The `<inertial>` of the body whose start tag is `body`: the first before any child body."""
    found = re.compile(r"<(inertial|body)\b[^>]*?/?>", re.DOTALL).search(text, body.end())
    if found is None or found.group(1) != "inertial":
        raise BwrError(f"the body '{name}' has no <inertial> of its own to write a fitted mass into")
    return found


def set_attribute(tag: str, attribute: str, value: str, index: int = 0) -> str:
    """The start tag with `attribute`'s `index`-th number set to `value` (added if absent)."""
    found = re.search(_ATTRIBUTE.format(name=re.escape(attribute)), tag)
    if found is None:
        head = tag[:-2] if tag.endswith("/>") else tag[:-1]
        end = tag[len(head):]
        return f'{head.rstrip()} {attribute}="{value}"{end}'
    numbers = found.group(3).split()
    while len(numbers) <= index:
        numbers.append("0")
    numbers[index] = value
    return tag[:found.start(3)] + " ".join(numbers) + tag[found.end(3):]


def edit(text: str, changes: list[tuple[str, str, str, int, str, str]], prefix: str = "") -> str:
    """`text` with each change made: (element kind "joint" or "body", its name, attribute, index in
    the attribute, new value, note). A body's "mass" goes into its `<inertial>`. The notes of one
    tag make one comment after it, in the order given, after `prefix`."""
    grouped: dict[tuple[str, str, str], list[tuple[str, int, str, str]]] = {}
    for kind, name, attribute, index, value, note in changes:
        inner = "inertial" if kind == "body" and attribute == "mass" else kind
        grouped.setdefault((kind, name, inner), []).append((attribute, index, value, note))
    for (kind, name, inner), edits in grouped.items():
        tag = _tag(text, kind, name)
        if inner == "inertial":
            tag = _inertial_after(text, tag, name)
        new = tag.group(0)
        for attribute, index, value, _ in edits:
            new = set_attribute(new, attribute, value, index)
        comment = (prefix + "; ".join(note for *_, note in edits)).replace("--", "- -")  # a comment may not hold '--'
        text = text[:tag.start()] + new + f" <!-- {comment} -->" + text[tag.end():]
    return text
