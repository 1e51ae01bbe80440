"""Port schemas: what flows on a link, checked when the graph loads.

A schema describes a value by its *kind* (scalar, array, image, message,
event, any), and where they apply its dtype, shape, unit and frame. A field
left as ``None`` means "not specified" and matches anything; this is how
generic blocks stay generic while domain blocks stay strict.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

KINDS = ("any", "scalar", "array", "image", "message", "event", "handle")

Dim = int | str | None


def _norm_dtype(dtype: Any) -> str | None:
    if dtype is None:
        return None
    if dtype in ("bool", bool):
        return "bool"
    try:
        return np.dtype(dtype).name
    except TypeError:
        raise ValueError(f"unknown dtype {dtype!r}") from None


@dataclass(frozen=True)
class Port:
    """One named input or output of a block.

    Parameters
    ----------
    kind
        One of ``any, scalar, array, image, message, event, handle``. ``event``
        is a boolean that fires a trigger on the ticks it is true; ``handle`` is
        a shared object (a simulator, a model) whose users must run after its owner.
    dtype
        numpy dtype name (``float64``, ``uint8``, ``bool``) or ``None``.
    shape
        Tuple of dimensions; an ``int`` is fixed, a ``str`` or ``None`` is free
        (a named dimension such as ``"N"`` documents intent).
    unit
        SI unit string such as ``m``, ``rad``, ``m/s``, or ``None``.
    frame
        Coordinate frame (``robot``, ``map``, ``world``, ``camera``) or ``None``.
    doc
        One line shown in the palette and the docs.
    required
        For inputs: must the input be connected?
    default
        For optional inputs: the value seen when unconnected.
    like
        For outputs: take the resolved schema of this input (type inference
        for generic blocks such as delay or arithmetic).
    """

    kind: str = "any"
    dtype: str | None = None
    shape: tuple[Dim, ...] | None = None
    unit: str | None = None
    frame: str | None = None
    doc: str = ""
    required: bool = True
    default: Any = None
    like: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown port kind {self.kind!r}; use one of {', '.join(KINDS)}")
        object.__setattr__(self, "dtype", _norm_dtype(self.dtype))
        if self.kind == "event" and self.dtype is None:
            object.__setattr__(self, "dtype", "bool")
        if self.shape is not None:
            object.__setattr__(self, "shape", tuple(self.shape))

    # ---- convenience constructors -------------------------------------
    @classmethod
    def scalar(cls, dtype: Any = "float64", unit: str | None = None, **kw: Any) -> "Port":
        return cls(kind="scalar", dtype=dtype, unit=unit, **kw)

    @classmethod
    def array(cls, dtype: Any = "float64", shape: tuple | None = None,
              unit: str | None = None, **kw: Any) -> "Port":
        return cls(kind="array", dtype=dtype, shape=shape, unit=unit, **kw)

    @classmethod
    def event(cls, **kw: Any) -> "Port":
        return cls(kind="event", dtype="bool", **kw)

    @classmethod
    def message(cls, **kw: Any) -> "Port":
        return cls(kind="message", **kw)

    # ---- presentation ---------------------------------------------------
    def describe(self) -> str:
        """Compact text such as ``array[float64, (16,), m, robot]``."""
        bits = []
        if self.dtype:
            bits.append(self.dtype)
        if self.shape is not None:
            dims = ",".join("?" if d is None else str(d) for d in self.shape)
            bits.append(f"({dims}{',' if len(self.shape) == 1 else ''})")
        if self.unit:
            bits.append(self.unit)
        if self.frame:
            bits.append(f"frame={self.frame}")
        if self.like:
            bits.append(f"like {self.like}")
        inner = ", ".join(bits)
        return f"{self.kind}[{inner}]" if inner else self.kind

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind}
        for name in ("dtype", "unit", "frame", "like"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        if self.shape is not None:
            out["shape"] = list(self.shape)
        if not self.required:
            out["required"] = False
        if self.doc:
            out["doc"] = self.doc
        return out

    def with_fields(self, **kw: Any) -> "Port":
        return replace(self, **kw)


def _shape_mismatch(src: tuple | None, dst: tuple | None) -> str | None:
    if src is None or dst is None:
        return None
    if len(src) != len(dst):
        return f"rank {len(src)} vs {len(dst)}"
    for i, (a, b) in enumerate(zip(src, dst)):
        if isinstance(a, int) and isinstance(b, int) and a != b:
            return f"dimension {i} is {a} vs {b}"
    return None


def mismatch(src: Port, dst: Port) -> str | None:
    """Why a value described by ``src`` may not flow into ``dst`` (None if it may)."""
    if src.kind != "any" and dst.kind != "any" and src.kind != dst.kind:
        # An event is a boolean scalar: let it feed scalar bool inputs and vice versa.
        bools = {src.kind, dst.kind} == {"event", "scalar"} and "bool" in (src.dtype, dst.dtype)
        if not bools:
            return f"kind {src.kind} cannot feed kind {dst.kind}"
    if src.dtype and dst.dtype and src.dtype != dst.dtype:
        return f"dtype {src.dtype} vs {dst.dtype}"
    why = _shape_mismatch(src.shape, dst.shape)
    if why:
        return f"shape {why}"
    if src.unit and dst.unit and src.unit != dst.unit:
        return f"unit {src.unit} vs {dst.unit}"
    if src.frame and dst.frame and src.frame != dst.frame:
        return f"frame {src.frame} vs {dst.frame}"
    return None


def schema_of_value(value: Any) -> Port:
    """Infer a schema from a constant (used for constants and delay initials)."""
    if isinstance(value, (bool, np.bool_)):
        return Port(kind="scalar", dtype="bool")
    if isinstance(value, (int, np.integer)):
        return Port(kind="scalar", dtype="int64")
    if isinstance(value, (float, np.floating)):
        return Port(kind="scalar", dtype="float64")
    if isinstance(value, (list, tuple, np.ndarray)):
        try:
            arr = np.asarray(value)
        except ValueError:
            return Port(kind="any")
        if arr.dtype == object:
            return Port(kind="any")
        return Port(kind="array", dtype=arr.dtype.name, shape=arr.shape)
    if isinstance(value, dict):
        return Port(kind="message")
    return Port(kind="any")


def value_mismatch(port: Port, value: Any) -> str | None:
    """Why a run-time value breaks its declared schema (strict mode)."""
    if value is None or port.kind in ("any", "message"):
        return None
    if port.kind in ("array", "image"):
        if not isinstance(value, np.ndarray):
            return f"expected a numpy array, got {type(value).__name__}"
        if port.dtype and value.dtype.name != port.dtype:
            return f"expected dtype {port.dtype}, got {value.dtype.name}"
        why = _shape_mismatch(tuple(value.shape), port.shape)
        return f"shape {why}" if why else None
    if port.kind in ("scalar", "event"):
        if isinstance(value, np.ndarray) and value.ndim == 0:
            value = value.item()
        if port.dtype == "bool" and not isinstance(value, (bool, np.bool_)):
            return f"expected a bool, got {type(value).__name__}"
        if port.dtype and port.dtype != "bool" and not isinstance(
                value, (int, float, np.integer, np.floating)):
            return f"expected a number, got {type(value).__name__}"
    return None
