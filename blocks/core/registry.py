"""The block registry: built-in and third-party toolboxes, plus subgraph files.

Toolboxes register through the entry-point group ``semmap.blocks``. An entry
point may name a module (importing it runs its ``@block`` decorators), a Block
class, or a callable that returns Block classes. A toolbox module may also set
``SUBGRAPHS = "<folder>"`` to publish its YAML subgraphs as block types named
after their files.
"""
from __future__ import annotations

import difflib
import importlib.metadata
import inspect
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Callable, Iterable

from .block import Block, finalize_block_class

ENTRY_POINT_GROUP = "semmap.blocks"


@dataclass(frozen=True)
class SubgraphType:
    """A YAML subgraph published under a type name."""

    type_name: str
    path: Path
    toolbox: str


class Registry:
    """Maps type names to Block classes and subgraph files."""

    def __init__(self) -> None:
        self.blocks: dict[str, type[Block]] = {}
        self.subgraphs: dict[str, SubgraphType] = {}
        self.toolbox_of: dict[str, str] = {}
        self.load_warnings: list[str] = []
        self.published: set[str] = {"core"}  # toolboxes from entry points, plus the core
        self._loaded = False

    def add_block(self, cls: type[Block], type_name: str, toolbox: str = "") -> None:
        existing = self.blocks.get(type_name)
        if existing is not None and (existing.__module__, existing.__qualname__) != (
                cls.__module__, cls.__qualname__):
            raise TypeError(f"block type {type_name!r} is already registered by "
                            f"{existing.__module__}.{existing.__qualname__}")
        finalize_block_class(cls, type_name)
        self.blocks[type_name] = cls
        self.toolbox_of[type_name] = toolbox or cls.__module__.split(".")[0]

    def add_subgraph_folder(self, folder: Path, toolbox: str) -> None:
        for path in sorted(Path(folder).glob("*.yaml")):
            self.subgraphs.setdefault(path.stem, SubgraphType(path.stem, path, toolbox))
            self.toolbox_of.setdefault(path.stem, toolbox)

    def ensure_loaded(self) -> None:
        """Import every toolbox named by the ``semmap.blocks`` entry points."""
        if self._loaded:
            return
        self._loaded = True
        for ep in sorted(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP),
                         key=lambda e: e.name):
            try:
                self.load_toolbox(ep.load(), ep.name)
            except Exception as exc:  # a broken plug-in must not break the others
                self.load_warnings.append(
                    f"toolbox '{ep.name}' ({ep.value}) failed to load: "
                    f"{type(exc).__name__}: {exc}")

    def load_toolbox(self, obj: object, toolbox: str) -> None:
        """Register what an entry point gives: a module, a class or a callable."""
        self.published.add(toolbox)
        if isinstance(obj, ModuleType):
            prefix = obj.__name__
            for type_name, cls in self.blocks.items():
                if cls.__module__ == prefix or cls.__module__.startswith(prefix + "."):
                    self.toolbox_of[type_name] = toolbox
            folder = getattr(obj, "SUBGRAPHS", None)
            if folder and getattr(obj, "__file__", None):
                self.add_subgraph_folder(Path(obj.__file__).parent / folder, toolbox)
        elif inspect.isclass(obj) and issubclass(obj, Block):
            self.add_block(obj, obj.type_name or obj.__name__.lower(), toolbox)
        elif callable(obj):
            for cls in _as_iterable(obj()):
                self.add_block(cls, cls.type_name or cls.__name__.lower(), toolbox)
        else:
            raise TypeError(f"entry point gives {type(obj).__name__}; expected a module, "
                            "a Block class or a callable returning Block classes")

    def names(self) -> list[str]:
        self.ensure_loaded()
        return sorted(set(self.blocks) | set(self.subgraphs))

    def get(self, type_name: str) -> type[Block] | SubgraphType | None:
        self.ensure_loaded()
        return self.blocks.get(type_name) or self.subgraphs.get(type_name)

    def closest(self, type_name: str, n: int = 3) -> list[str]:
        """Registered names that look like ``type_name`` (for 'did you mean')."""
        return difflib.get_close_matches(type_name, self.names(), n=n, cutoff=0.5)


def _as_iterable(result: object) -> Iterable[type[Block]]:
    if result is None:
        return []
    if isinstance(result, dict):
        return result.values()
    if isinstance(result, (list, tuple, set)):
        return result
    return [result]  # type: ignore[list-item]


REGISTRY = Registry()


def block(type_name: str, *, category: str | None = None) -> Callable[[type[Block]], type[Block]]:
    """Class decorator that registers a block under ``type_name``.

    The class is validated at once (ports, params, step signature), so a
    block author sees a mistake on import rather than when a graph uses it.
    """

    def decorate(cls: type[Block]) -> type[Block]:
        if category is not None:
            cls.category = category
        REGISTRY.add_block(cls, type_name)
        return cls

    return decorate
