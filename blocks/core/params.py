"""Typed block and graph parameters: defaults, ranges, choices, docs."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

_TYPE_NAMES = {int: "int", float: "float", bool: "bool", str: "str",
               list: "list", dict: "dict", object: "any"}
_NAME_TYPES = {v: k for k, v in _TYPE_NAMES.items()}

_MISSING = object()


_YAML11_WORDS = {True: ("on", "yes", "true", "y"), False: ("off", "no", "false", "n")}


def _yaml11_word(value: bool, choices: tuple) -> Any:
    """The choice a YAML 1.1 boolean was typed as (``on``/``off``, ``yes``/``no``...).

    YAML 1.1 reads ``specular: off`` as ``False``; when the parameter is text
    and one of its choices is such a word, that word was meant.
    """
    for word in _YAML11_WORDS[value]:
        if word in choices:
            return word
    return value


@dataclass(frozen=True)
class Param:
    """A typed parameter with a one-line doc.

    Parameters
    ----------
    type
        ``int, float, bool, str, list, dict`` or ``object`` for any value.
    default
        The value used when the graph gives none; leave it out to make the
        parameter required.
    doc
        One line for the palette and the docs.
    min, max
        Inclusive bounds for numbers (and list lengths are not bounded).
    choices
        The allowed values.
    unit
        SI unit of the value, for the docs.
    """

    type: type = object
    default: Any = _MISSING
    doc: str = ""
    min: float | None = None
    max: float | None = None
    choices: tuple | None = None
    unit: str | None = None
    role: str | None = None  # e.g. "world": set on every node at once by `semmap run --world`

    @property
    def required(self) -> bool:
        return self.default is _MISSING

    @property
    def type_name(self) -> str:
        return _TYPE_NAMES.get(self.type, getattr(self.type, "__name__", str(self.type)))

    def coerce(self, value: Any) -> Any:
        """Check ``value`` and return it in canonical form; raise ValueError why not."""
        t = self.type
        if t is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"expected a number, got {_show(value)}")
            value = to_float(value)
        elif t is int:
            if isinstance(value, bool) or not isinstance(value, int):
                if isinstance(value, float) and value.is_integer():
                    value = int(value)
                else:
                    raise ValueError(f"expected a whole number, got {_show(value)}")
        elif t is bool:
            if not isinstance(value, bool):
                raise ValueError(f"expected true or false, got {_show(value)}")
        elif t is str:
            if isinstance(value, bool) and self.choices is not None:
                value = _yaml11_word(value, self.choices)
            if not isinstance(value, str):
                raise ValueError(f"expected text, got {_show(value)}")
        elif t is list:
            if not isinstance(value, (list, tuple)):
                raise ValueError(f"expected a list, got {_show(value)}")
            value = list(value)
        elif t is dict:
            if not isinstance(value, dict):
                raise ValueError(f"expected a mapping, got {_show(value)}")
        if self.choices is not None and value not in self.choices:
            options = ", ".join(repr(c) for c in self.choices)
            raise ValueError(f"{_show(value)} is not one of {options}")
        if self.min is not None and isinstance(value, (int, float)) and value < self.min:
            raise ValueError(f"{value} is below the minimum {self.min}")
        if self.max is not None and isinstance(value, (int, float)) and value > self.max:
            raise ValueError(f"{value} is above the maximum {self.max}")
        return value

    def describe_range(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        if self.min is not None and self.max is not None:
            return f"[{self.min}, {self.max}]"
        if self.min is not None:
            return f">= {self.min}"
        if self.max is not None:
            return f"<= {self.max}"
        return ""

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": self.type_name, "doc": self.doc}
        if not self.required:
            out["default"] = self.default
        else:
            out["required"] = True
        for name in ("min", "max", "unit", "role"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        if self.choices is not None:
            out["choices"] = list(self.choices)
        return out

    @classmethod
    def from_spec(cls, spec: Any) -> "Param":
        """Build a graph-level parameter from YAML: a bare default or a mapping."""
        if not isinstance(spec, dict):
            return cls(type=_infer_type(spec), default=spec)
        unknown = set(spec) - {"default", "type", "doc", "min", "max", "choices", "unit"}
        if unknown:
            raise ValueError(f"unknown parameter field(s) {', '.join(sorted(map(str, unknown)))}; "
                             "use default, type, doc, min, max, choices, unit")
        type_name = spec.get("type")
        if type_name is None:
            ptype = _infer_type(spec["default"]) if "default" in spec else object
        elif type_name in _NAME_TYPES:
            ptype = _NAME_TYPES[type_name]
        else:
            raise ValueError(f"unknown type {type_name!r}; use one of {', '.join(_NAME_TYPES)}")
        choices = spec.get("choices")
        if choices is not None and not isinstance(choices, list):
            raise ValueError("choices must be a list")
        for bound in ("min", "max"):
            if bound in spec and (isinstance(spec[bound], bool)
                                  or not isinstance(spec[bound], (int, float))):
                raise ValueError(f"{bound} must be a number")
            if bound in spec:
                to_float(spec[bound])
        doc = spec.get("doc", "")
        param = cls(type=ptype, default=spec.get("default", _MISSING), doc=str(doc),
                    min=spec.get("min"), max=spec.get("max"),
                    choices=tuple(choices) if choices is not None else None,
                    unit=spec.get("unit"))
        if not param.required:
            param.coerce(param.default)
        return param


def to_float(value: int | float) -> float:
    """A number as a float; ValueError for nan or an integer too large for a float."""
    try:
        result = float(value)
    except OverflowError:
        raise ValueError(f"{_show(value)} is too large for a number") from None
    if result != result:
        raise ValueError("nan is not a usable value")
    return result


def _infer_type(value: Any) -> type:
    for t in (bool, int, float, str, list, dict):
        if isinstance(value, t):
            return t
    return object


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
