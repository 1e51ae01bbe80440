"""World specs: the library's names, world files, and families of generated buildings.

A world spec names one or more worlds wherever semmap takes a world:

``office``
    A world of the library (``sim2d/worlds/*.yaml``).
``path/to/floor.yaml``
    A world file.
``gen:KIND:SEEDS``
    Buildings drawn by the generator (:mod:`sim2d.worlds.building`): ``KIND``
    is one of :func:`sim2d.worlds.building.kinds` or ``any`` (seed ``s`` then
    takes the kind ``kinds()[s % len(kinds())]``, so a range is balanced over
    the kinds); ``SEEDS`` is a seed spec (:func:`parse_seeds`). Where a single
    world is expected (``semmap run --world``), the spec must name one seed:
    ``gen:ring:7``.

A generated world is written once into a cache folder
(``$SEMMAP_CACHE`` or ``~/.cache/semmap``, under the generator's version) and
read from there afterwards; it is deterministic, so the cache only saves time.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from blocks.core.errors import SemmapError

__all__ = ["WorldRef", "WorldSpecError", "cache_dir", "expand_worlds", "generated_world",
           "parse_seeds"]

GEN_PREFIX = "gen:"
_SEEDS_HELP = ("Seeds are a number (7), a range (100-129) or a comma-separated list of "
               "both (1,4,10-12).")


class WorldSpecError(SemmapError):
    """A world or seed spec that cannot be read."""


@dataclass(frozen=True)
class WorldRef:
    """One world of a spec.

    Attributes
    ----------
    name : str
        A short name for folders and tables: the library name, the file's stem,
        or ``KIND-SEED`` for a generated building.
    kind : str
        The layout kind of a generated building, else ``library`` or ``file``.
    spec : str
        What ``--world`` accepts for it: ``office``, a path, or ``gen:KIND:SEED``.
    seed : int or None
        The generator seed of a generated building.
    """

    name: str
    kind: str
    spec: str
    seed: int | None = None


def parse_seeds(text: str, *, what: str = "seeds") -> list[int]:
    """The seeds of a seed spec, in the order given, without repeats.

    Parameters
    ----------
    text : str
        ``"7"``, ``"100-129"`` or a comma-separated list of both.
    what : str
        How to name the spec in an error message.

    Returns
    -------
    list of int

    Raises
    ------
    WorldSpecError
        For anything else, or a range whose end is below its start.

    Examples
    --------
    >>> parse_seeds("1,4,10-12")
    [1, 4, 10, 11, 12]
    """
    seeds: list[int] = []
    parts = str(text).split(",")
    for part in parts:
        m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", part)
        if not m:
            raise WorldSpecError(f"{what} {text!r}: cannot read {part.strip()!r}",
                                 hint=_SEEDS_HELP)
        lo = int(m.group(1))
        hi = int(m.group(2)) if m.group(2) is not None else lo
        if hi < lo:
            raise WorldSpecError(f"{what} {text!r}: the range {lo}-{hi} runs backwards",
                                 hint=f"Write {hi}-{lo}.")
        seeds.extend(s for s in range(lo, hi + 1) if s not in seeds)
    return seeds


def _kinds() -> list[str]:
    from .building import kinds
    return kinds()


def _kind_of(kind: str, seed: int) -> str:
    names = _kinds()
    return names[seed % len(names)] if kind == "any" else kind


def _parse_gen(spec: str) -> tuple[str, list[int]]:
    """(kind, seeds) of a ``gen:KIND:SEEDS`` spec."""
    parts = spec[len(GEN_PREFIX):].split(":")
    usage = "Write gen:KIND:SEEDS, for example gen:ring:100-129 or gen:any:0-199."
    if len(parts) != 2 or not parts[0]:
        raise WorldSpecError(f"world spec {spec!r} is not gen:KIND:SEEDS", field="world",
                             hint=usage)
    kind, seeds = parts
    names = _kinds()
    if kind != "any" and kind not in names:
        import difflib
        close = difflib.get_close_matches(kind, names + ["any"], n=1)
        guess = f"Did you mean {close[0]!r}? " if close else ""
        raise WorldSpecError(f"world spec {spec!r}: no building kind {kind!r}", field="world",
                             hint=f"{guess}Kinds: {', '.join(names)}, or any.")
    return kind, parse_seeds(seeds, what=f"world spec {spec!r}: seeds")


def expand_worlds(spec: str) -> list[WorldRef]:
    """Every world a spec names (see the module docstring).

    Raises
    ------
    WorldSpecError
        For a malformed ``gen:`` spec.
    sim2d.world.WorldError
        For an unknown library name.
    """
    spec = str(spec).strip()
    if spec.startswith(GEN_PREFIX):
        kind, seeds = _parse_gen(spec)
        refs = []
        for seed in seeds:
            k = _kind_of(kind, seed)
            refs.append(WorldRef(name=f"{k}-{seed}", kind=k, spec=f"{GEN_PREFIX}{k}:{seed}",
                                 seed=seed))
        return refs
    if not spec:
        raise WorldSpecError("an empty world spec", field="world",
                             hint="Name a library world (office), a world file or "
                                  "gen:KIND:SEEDS.")
    path = Path(spec)
    if path.is_dir():
        raise WorldSpecError(f"world {spec!r} is a folder, not a world file", field="world",
                             hint="Give the world's YAML file.")
    if path.suffix in (".yaml", ".yml") or path.exists():
        return [WorldRef(name=path.stem, kind="file", spec=str(path))]
    from . import world_path
    world_path(spec)  # raises for an unknown name, listing the library
    return [WorldRef(name=spec, kind="library", spec=spec)]


def cache_dir() -> Path:
    """Where generated worlds are kept: ``$SEMMAP_CACHE/worlds`` (default ``~/.cache/semmap``)."""
    from .building import GENERATOR_VERSION
    root = Path(os.environ.get("SEMMAP_CACHE") or Path.home() / ".cache" / "semmap")
    return root / "worlds" / f"v{GENERATOR_VERSION}"


def generated_world(spec: str, folder: str | Path | None = None, *,
                    name: str | None = None) -> Path:
    """The world file of a one-seed ``gen:KIND:SEED`` spec, generated if not there yet.

    Parameters
    ----------
    spec : str
        ``gen:KIND:SEED`` (``any`` is allowed: the seed picks the kind).
    folder : path, optional
        Where to write it (default: :func:`cache_dir`).
    name : str, optional
        The file's stem (default ``KIND-SEED``); a file given by name is always
        written anew.

    Raises
    ------
    WorldSpecError
        If the spec is malformed or names more than one seed.
    """
    kind, seeds = _parse_gen(spec)
    if len(seeds) != 1:
        raise WorldSpecError(f"world spec {spec!r} names {len(seeds)} buildings where one "
                             "world is expected", field="world",
                             hint="Name one seed (gen:ring:7), or use `semmap sweep --worlds` "
                                  "for a family.")
    seed = seeds[0]
    kind = _kind_of(kind, seed)
    from .building import generate_building
    target = Path(folder) if folder is not None else cache_dir()
    path = target / f"{name or f'{kind}-{seed}'}.yaml"
    if name is not None:
        generate_building(kind, seed, path)
    elif not path.is_file():
        _generate_into_cache(kind, seed, path)
    return path


def _generate_into_cache(kind: str, seed: int, path: Path) -> None:
    """Generate beside the cache and move the files in, the world YAML last.

    Runs in parallel (a sweep's workers) may ask for the same building at
    once; each generates its own copy, and a reader who finds the YAML finds
    its side files whole (the generator rewrites the YAML once it has the
    commands, so it must not be read in the cache while being written).
    """
    import shutil
    import tempfile
    from .building import generate_building
    path.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{path.stem}.", dir=path.parent))
    try:
        generate_building(kind, seed, scratch / path.name)
        files = sorted(scratch.iterdir(), key=lambda f: f.name == path.name)  # YAML last
        for file in files:
            os.replace(file, path.parent / file.name)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
