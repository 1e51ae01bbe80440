"""Parameter specs and ${...} expressions."""
from __future__ import annotations

import math

import pytest

from blocks import Param
from blocks.core.expr import ExprError, evaluate
from blocks.core.schema import Port, mismatch, schema_of_value, value_mismatch


@pytest.mark.parametrize("text,expected", [
    ("1 - alpha", 0.75), ("2 * pi * r", 2 * math.pi * 2), ("max(alpha, 0.5)", 0.5),
    ("r ** 2", 4), ("-r", -2), ("r if alpha < 1 else 0", 2), ("round(alpha * 10)", 2),
    ("r // 3", 0), ("alpha > 0 and r > 0", True),
])
def test_expressions(text, expected):
    assert evaluate(text, {"alpha": 0.25, "r": 2}) == pytest.approx(expected)


@pytest.mark.parametrize("text", [
    "__import__('os')", "r.real", "open('x')", "[1, 2]", "lambda: 1", "2 ** 1000",
    "unknown + 1", "1 / 0", "(",
])
def test_unsafe_or_bad_expressions_raise(text):
    with pytest.raises(ExprError):
        evaluate(text, {"r": 2})


def test_param_coercion():
    assert Param(float, 1.0).coerce(2) == 2.0
    assert Param(int, 1).coerce(3.0) == 3
    with pytest.raises(ValueError, match="whole number"):
        Param(int, 1).coerce(2.5)
    with pytest.raises(ValueError, match="true or false"):
        Param(bool, True).coerce("yes")
    with pytest.raises(ValueError, match="above the maximum"):
        Param(float, 0.0, max=1.0).coerce(1.5)
    with pytest.raises(ValueError, match="not one of"):
        Param(str, "a", choices=("a", "b")).coerce("c")
    assert Param(object).required and not Param(int, 0).required


def test_graph_param_specs():
    assert Param.from_spec(3).type is int
    spec = Param.from_spec({"default": 0.5, "min": 0, "max": 1, "doc": "x"})
    assert spec.type is float and spec.max == 1
    with pytest.raises(ValueError, match="unknown parameter field"):
        Param.from_spec({"defualt": 1})
    with pytest.raises(ValueError, match="below the minimum"):
        Param.from_spec({"default": -1, "min": 0})


def test_schema_matching():
    metres = Port.array("float64", (16,), "m", frame="robot")
    assert mismatch(metres, Port.array("float64", ("N",), "m")) is None
    assert mismatch(metres, Port.array("float64", (8,), "m")) == "shape dimension 0 is 16 vs 8"
    assert mismatch(metres, Port(kind="any")) is None
    assert "kind" in mismatch(metres, Port.scalar())
    assert mismatch(Port.event(), Port.scalar("bool")) is None
    assert schema_of_value([[1, 2], [3, 4]]).shape == (2, 2)
    assert schema_of_value(True).dtype == "bool"


def test_value_checks():
    import numpy as np
    port = Port.array("float64", (3,))
    assert value_mismatch(port, np.zeros(3)) is None
    assert "dtype" in value_mismatch(port, np.zeros(3, dtype=np.int32))
    assert "shape" in value_mismatch(port, np.zeros(4))
    assert "bool" in value_mismatch(Port.event(), 1.0)
    assert value_mismatch(Port.scalar(), np.float64(2.0)) is None
