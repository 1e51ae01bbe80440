"""User-facing errors.

Every mistake a user can make (a bad graph, parameter, world or command) is
raised as a :class:`SemmapError`. The CLI prints it as one paragraph and exits
nonzero; anything else is a bug and is reported differently.
"""
from __future__ import annotations

from pathlib import Path


class SemmapError(Exception):
    """An error caused by user input, reported without a traceback.

    Parameters
    ----------
    message
        What is wrong, as a sentence.
    file, line
        Where the offending text is, when it comes from a file.
    node
        The node path (``sub.inner``) the error concerns.
    field
        The port, parameter or field name concerned.
    hint
        How to fix it, as a sentence.
    """

    exit_code = 2

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        line: int | None = None,
        node: str | None = None,
        field: str | None = None,
        hint: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = str(file) if file is not None else None
        self.line = line
        self.node = node
        self.field = field
        self.hint = hint

    def where(self) -> str:
        """The location prefix, e.g. ``graphs/a.yaml:12: node 'x', param 'gain'``."""
        parts = []
        if self.file:
            parts.append(f"{self.file}:{self.line}" if self.line else self.file)
        subject = []
        if self.node:
            subject.append(f"node '{self.node}'")
        if self.field:
            subject.append(self.field)
        if subject:
            parts.append(", ".join(subject))
        return ": ".join(parts)

    def __str__(self) -> str:
        where = self.where()
        text = f"{where}: {self.message}" if where else self.message
        if self.hint:
            text = f"{text.rstrip('.')}. {self.hint}"
        # User text quoted in a message may hold line breaks; keep one paragraph.
        return text.replace("\r", "\\r").replace("\n", "\\n")


class GraphError(SemmapError):
    """The graph description is invalid; found when the graph loads."""


class ParamError(SemmapError):
    """A parameter value is of the wrong type or out of range."""


class BlockError(SemmapError):
    """A block met a user-caused problem at run time (bad input file, unknown robot, ...)."""


class SchemaViolation(SemmapError):
    """A block's output broke its declared schema (found by --strict): a bug in the block."""

    exit_code = 1
