"""The Block base class: declared ports and params, a step function, state.

A block is a thin adapter: it declares typed ports and parameters, and its
``step`` maps this tick's inputs to outputs by calling plain functions that
can be tested without the framework.

Two protocols exist:

* **direct feedthrough** (the default): ``step(**inputs) -> {output: value}``.
* **no direct feedthrough** (``direct_feedthrough = False``): ``output()``
  gives this tick's outputs from state only, and ``update(**inputs)`` absorbs
  the inputs afterwards. Such blocks (delays, integrators) break cycles, the
  way Simulink's unit delay and FlowDesigner's Feedback node do.
"""
from __future__ import annotations

import inspect
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np

from .params import Param
from .schema import Port


class RunContext:
    """What a running block may know about its run: clock, output dir, metrics."""

    def __init__(self, *, dt: float, seed: int, out_dir: Any = None) -> None:
        self.dt = dt
        self.seed = seed
        self.out_dir = out_dir
        self.tick = 0
        self.metrics: dict[str, dict[str, Any]] = {}
        self.stop_reason: str | None = None
        self.outputs: list[str] = []
        #: What blocks of this run compute once and share (the map blocks' sonar
        #: visibility, say), so it lives and dies with the run; cleared on reset.
        self.shared: dict[Any, Any] = {}

    @property
    def time(self) -> float:
        """Simulated time in seconds at the current tick."""
        return self.tick * self.dt


class Block:
    """Base class of every block. Subclass it and register it with ``@block``.

    Class attributes
    ----------------
    inputs, outputs : dict[str, Port]
        Declared ports. Override :meth:`resolve_ports` when they depend on params.
    params : dict[str, Param]
        Declared parameters; their values are on ``self.p`` at run time.
    direct_feedthrough : bool
        False for blocks whose outputs depend only on past inputs.
    category : str
        Palette group.
    """

    type_name: ClassVar[str] = ""
    category: ClassVar[str] = "misc"
    inputs: ClassVar[dict[str, Port]] = {}
    outputs: ClassVar[dict[str, Port]] = {}
    params: ClassVar[dict[str, Param]] = {}
    direct_feedthrough: ClassVar[bool] = True
    _input_order: ClassVar[tuple[str, ...]] = ()

    def __init__(self, params: dict[str, Any], *, name: str = "",
                 ctx: RunContext | None = None, rng: np.random.Generator | None = None) -> None:
        self.name = name
        self.p = SimpleNamespace(**params)
        self.ctx = ctx if ctx is not None else RunContext(dt=1.0, seed=0)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.setup()

    # ---- lifecycle hooks for subclasses -------------------------------------
    def setup(self) -> None:
        """Allocate resources after params are set (called once)."""

    def reset(self) -> None:
        """Return state to its initial value (called before the first tick)."""

    def step(self, **inputs: Any) -> dict[str, Any] | None:
        """Map this tick's inputs to outputs. Missing outputs hold their value."""
        raise NotImplementedError

    def output(self) -> dict[str, Any] | None:
        """Outputs from state alone (blocks without direct feedthrough)."""
        raise NotImplementedError

    def update(self, **inputs: Any) -> None:
        """Absorb this tick's inputs (blocks without direct feedthrough)."""
        raise NotImplementedError

    def finish(self) -> None:
        """Write files and release resources; runs even after Ctrl-C."""

    # ---- services -------------------------------------------------------------
    def report(self, name: str, value: Any) -> None:
        """Record a metric that ends up in run.json."""
        self.ctx.metrics.setdefault(self.name, {})[name] = value

    def request_stop(self, reason: str = "done") -> None:
        """Ask the runner to stop after this tick."""
        if self.ctx.stop_reason is None:
            self.ctx.stop_reason = f"{self.name}: {reason}"

    def output_path(self, filename: str):
        """Path inside the run's output folder for a file this block writes."""
        from pathlib import Path
        if self.ctx.out_dir is None:
            raise RuntimeError("this run has no output folder")
        path = Path(self.ctx.out_dir) / filename
        path.parent.mkdir(parents=True, exist_ok=True)
        self.ctx.outputs.append(str(path))
        return path

    # ---- metadata -------------------------------------------------------------
    @classmethod
    def resolve_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Port], dict[str, Port]]:
        """Port schemas for these params; override for parameterised types."""
        return cls.inputs, cls.outputs

    @classmethod
    def summary(cls) -> str:
        doc = inspect.getdoc(cls) or ""
        return doc.splitlines()[0] if doc else ""

    @classmethod
    def description(cls) -> str:
        return inspect.getdoc(cls) or ""


def _input_order(cls: type[Block]) -> tuple[str, ...]:
    """Check that step/update accept exactly the declared inputs; return their order."""
    method = cls.step if cls.direct_feedthrough else cls.update
    sig = inspect.signature(method)
    names = [n for n, p in sig.parameters.items()
             if n != "self" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    has_var_kw = any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values())
    declared = list(cls.inputs)
    if has_var_kw and not names:
        return tuple(declared)
    if set(names) != set(declared):
        raise TypeError(
            f"block {cls.__name__}: {method.__name__}() takes {names} "
            f"but the declared inputs are {declared}")
    return tuple(names)


def finalize_block_class(cls: type[Block], type_name: str) -> None:
    """Validate a block class's declarations once, when it registers."""
    if not (isinstance(cls, type) and issubclass(cls, Block)):
        raise TypeError(f"{cls!r} is not a Block subclass")
    for table in ("inputs", "outputs", "params"):
        value = getattr(cls, table)
        if not isinstance(value, dict):
            raise TypeError(f"block {cls.__name__}: {table} must be a dict")
    for name, port in {**cls.inputs, **cls.outputs}.items():
        if not isinstance(port, Port):
            raise TypeError(f"block {cls.__name__}: port {name} is not a Port")
        if "." in name:
            raise TypeError(f"block {cls.__name__}: port name {name!r} may not contain '.'")
    for name, param in cls.params.items():
        if not isinstance(param, Param):
            raise TypeError(f"block {cls.__name__}: param {name} is not a Param")
    cls.type_name = type_name
    cls._input_order = _input_order(cls)
