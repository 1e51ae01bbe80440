"""Shared helpers: write graph files, run the CLI in-process, define test blocks."""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest

from blocks.cli import main

ROOT = Path(__file__).resolve().parents[1]


class CliResult:
    def __init__(self, code: int, out: str, err: str) -> None:
        self.code, self.out, self.err = code, out, err

    def __repr__(self) -> str:
        return f"CliResult(code={self.code}, out={self.out!r}, err={self.err!r})"


@pytest.fixture
def cli(capsys):
    """Run ``semmap ARGS`` in-process; return exit code and captured text."""

    def invoke(*args: Any) -> CliResult:
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return CliResult(code, captured.out, captured.err)

    return invoke


@pytest.fixture
def write(tmp_path):
    """Write a dedented YAML file under tmp_path and return its path."""

    def writer(name: str, text: str) -> Path:
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text).lstrip("\n"))
        return path

    return writer
