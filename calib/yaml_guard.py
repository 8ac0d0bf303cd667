"""Reading a small hand-written YAML file so that no file can hurt the reader
(docs/decisions/files.md): every refusal is one line naming the line."""

from __future__ import annotations

import math
import os
import reprlib
from pathlib import Path
from typing import Any

import yaml

#: Largest file read: a rig profile is under 1 KiB; 64 KiB leaves room for any comments.
MAX_FILE_BYTES = 64 * 1024
#: Deepest nesting of collections: a profile needs 3 (top, joint, list); 8 refuses only abuse.
MAX_DEPTH = 8
#: Longest single scalar (characters): the longest field, a device path, is far below this.
MAX_SCALAR_CHARS = 1024
#: Longest quotation of a value in a message (characters).
MAX_SHOWN_CHARS = 60

_MERGE_TAG = "tag:yaml.org,2002:merge"
_REPR = reprlib.Repr()
_REPR.maxstring = MAX_SHOWN_CHARS
_REPR.maxother = MAX_SHOWN_CHARS
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 4
_REPR.maxlevel = 2


class YamlRefused(ValueError):
    """A YAML file was refused; the message is one line saying where and why."""


def shown(value: Any) -> str:
    """A ``repr`` of ``value`` of at most :data:`MAX_SHOWN_CHARS` characters (huge ints by size)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        # digits of |n| = floor(bit_length * log10(2)) + 1, up to one
        digits = int(value.bit_length() * math.log10(2)) + 1
        return f"<an integer of about {digits} digits>"
    text = _REPR.repr(value)
    if len(text) > MAX_SHOWN_CHARS:
        text = text[: MAX_SHOWN_CHARS - 3] + "..."
    return text


def _where(mark: yaml.Mark | None) -> str:
    return f"line {mark.line + 1}" if mark is not None else "somewhere"


class _GuardedLoader(yaml.SafeLoader):
    """PyYAML's safe loader (plain data only) with the refusals above."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise YamlRefused(
                f"{_where(event.start_mark)}: anchors and aliases (&name, *name) are not "
                f"allowed in this file; write each value out"
            )
        if isinstance(event, yaml.ScalarEvent) and len(event.value) > MAX_SCALAR_CHARS:
            raise YamlRefused(
                f"{_where(event.start_mark)}: a value of {len(event.value)} characters; "
                f"values in this file are at most {MAX_SCALAR_CHARS}"
            )
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise YamlRefused(
                    f"{_where(event.start_mark)}: nested more than {MAX_DEPTH} levels deep; "
                    f"this file needs only a few"
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        if isinstance(node, yaml.MappingNode):
            first_line: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == _MERGE_TAG:
                    raise YamlRefused(
                        f"{_where(key_node.start_mark)}: merge keys (<<) are not allowed in this "
                        f"file; write each key out"
                    )
                key = self.construct_object(key_node, deep=True)
                try:
                    previous = first_line.get(key)
                except TypeError:  # an unhashable key: PyYAML's own check names it below
                    continue
                line = key_node.start_mark.line + 1
                if previous is not None:
                    raise YamlRefused(
                        f"line {line}: key {shown(key)} appears twice (also on line "
                        f"{previous}); keep one, a later value would silently win"
                    )
                first_line[key] = line
        return super().construct_mapping(node, deep=deep)


def _one_line(exc: yaml.YAMLError) -> str:
    """PyYAML's multi-line error as one bounded line: what and where."""
    problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or "unreadable"
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    text = f"{where}{problem}"
    if len(text) > 2 * MAX_SHOWN_CHARS:
        text = text[: 2 * MAX_SHOWN_CHARS - 3] + "..."
    return text


def parse_yaml(text: str) -> Any:
    """Parse one YAML document with the guards above (YamlRefused: one line naming the line of
    the text and the problem)."""
    try:
        return yaml.load(text, Loader=_GuardedLoader)
    except YamlRefused:
        raise
    except yaml.YAMLError as exc:
        raise YamlRefused(f"not valid YAML ({_one_line(exc)})") from None
    except (ValueError, OverflowError) as exc:  # a constructor's own failure, e.g. 2001-02-30
        raise YamlRefused(f"a value cannot be read ({shown(str(exc))})") from None


def read_yaml(path: str | os.PathLike[str]) -> Any:
    """Read and parse the YAML file at ``path``, reading at most :data:`MAX_FILE_BYTES`.
    FileNotFoundError if it does not exist; YamlRefused if not a regular file, too large, not
    UTF-8, or refused by :func:`parse_yaml`; OSError if it cannot be read."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(path)
    if not path.is_file():
        raise YamlRefused("not a regular file")
    with open(path, "rb") as handle:
        blob = handle.read(MAX_FILE_BYTES + 1)
    if len(blob) > MAX_FILE_BYTES:
        raise YamlRefused(f"larger than {MAX_FILE_BYTES // 1024} KiB; this file is a few lines")
    try:
        text = blob.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise YamlRefused(f"not UTF-8 text (byte {exc.start})") from None
    return parse_yaml(text)
