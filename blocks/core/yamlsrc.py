"""YAML loading that remembers line numbers, so errors can point at them."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .errors import GraphError, SemmapError


class LineDict(dict):
    """A mapping that knows its own line and the line of each key."""

    line: int = 0
    key_lines: dict

    def line_of(self, key: Any) -> int:
        return self.key_lines.get(key, self.line) if hasattr(self, "key_lines") else self.line


class LineList(list):
    """A sequence that knows its own line and the line of each item."""

    line: int = 0
    item_lines: list

    def line_of(self, index: int) -> int:
        try:
            return self.item_lines[index]
        except (AttributeError, IndexError):
            return self.line


def line_of(container: Any, key: Any = None) -> int | None:
    """Best-known line for ``container[key]`` (or the container itself)."""
    if isinstance(container, (LineDict, LineList)):
        return container.line_of(key) if key is not None else container.line
    return None


class _LineLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # libyaml: 5-10x faster
    """A safe loader that builds LineDict/LineList and rejects duplicate keys."""


def _construct_mapping(loader: _LineLoader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    result = LineDict()
    result.line = node.start_mark.line + 1
    result.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise GraphError(
                "a mapping key must be a plain value, not a list or mapping",
                file=loader.name, line=key_node.start_mark.line + 1,
            ) from None
        if key in result:
            raise GraphError(
                f"duplicate key '{key}' (first given on line {result.key_lines[key]})",
                file=loader.name, line=key_node.start_mark.line + 1,
                hint="Keep one of the two entries.",
            )
        result[key] = loader.construct_object(value_node, deep=True)
        result.key_lines[key] = key_node.start_mark.line + 1
    return result


def _construct_sequence(loader: _LineLoader, node: yaml.SequenceNode) -> LineList:
    result = LineList(loader.construct_object(child, deep=True) for child in node.value)
    result.line = node.start_mark.line + 1
    result.item_lines = [child.start_mark.line + 1 for child in node.value]
    return result


_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_yaml_text(text: str, file: str | Path = "<string>") -> Any:
    """Parse YAML text into LineDict/LineList trees; syntax errors become GraphError."""
    try:
        loader = _LineLoader(text)
    except yaml.reader.ReaderError as exc:
        raise GraphError(
            f"the file holds a character YAML does not allow ({exc.character!r} at "
            f"character {exc.position})", file=file,
            hint="Remove control characters; save the file as plain UTF-8 text.") from None
    loader.name = str(file)
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark else None
        problem = exc.problem or exc.context or "invalid YAML"
        raise GraphError(
            f"YAML syntax error: {problem}",
            file=file, line=line,
            hint="Check the indentation and quoting around that line.",
        ) from None
    except yaml.reader.ReaderError as exc:
        raise GraphError(f"the file holds a character YAML does not allow ({exc.character!r})",
                         file=file, hint="Save the file as plain UTF-8 text.") from None
    except yaml.YAMLError as exc:
        raise GraphError(f"YAML error: {exc}", file=file) from None
    except (RecursionError, ValueError, OverflowError) as exc:
        raise GraphError(f"YAML could not be read: {exc}", file=file) from None
    finally:
        loader.dispose()


def load_yaml_file(path: str | Path) -> Any:
    """Read and parse a YAML file, turning I/O problems into GraphError."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise GraphError("file not found", file=path,
                         hint="Check the path (relative paths start from the current "
                              "folder, includes from the including file's folder).") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GraphError(f"cannot read the file: {exc}", file=path) from None
    return load_yaml_text(text, path)


def load_versioned_mapping(path: str | Path, error: type[SemmapError], *, what: str,
                           fields: tuple[str, ...], missing_hint: str) -> Any:
    """Read a data file that is a YAML mapping of known top-level fields plus ``version: 1``.

    The vocabulary, the object catalogue and timetables share this shape; each
    reports problems with its own error class, so the message says which kind
    of file is wrong, where, and how to fix it.

    Parameters
    ----------
    path
        The YAML file.
    error
        The :class:`SemmapError` subclass to raise.
    what
        The file's kind with its article, for messages ("a timetable").
    fields
        The known top-level fields besides ``version``.
    missing_hint
        How to fix a missing file.

    Returns
    -------
    LineDict
        The parsed mapping (lines available through :func:`line_of`).
    """
    path = Path(path)
    try:
        doc = load_yaml_file(path)
    except SemmapError as exc:
        hint = missing_hint if exc.message == "file not found" else exc.hint
        raise error(exc.message, file=exc.file or path, line=exc.line, hint=hint) from None
    listed = " and ".join(f"'{f}'" for f in fields)
    if not isinstance(doc, dict):
        raise error(f"{what} must be a YAML mapping with {listed}", file=path,
                    line=line_of(doc))
    for key in doc:
        if key != "version" and key not in fields:
            raise error(f"unknown top-level field {key!r}", file=path, line=line_of(doc, key),
                        field=str(key), hint=f"Known fields: version, {', '.join(fields)}.")
    if doc.get("version", 1) != 1:
        raise error(f"unsupported {what.split(' ', 1)[-1]} version {doc.get('version')!r}",
                    file=path, line=line_of(doc, "version"), field="version",
                    hint="This reader understands version 1.")
    return doc
