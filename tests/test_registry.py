"""Toolboxes: entry points, published subgraphs, broken plug-ins, block declarations."""
from __future__ import annotations

import importlib.metadata
import sys
import types

import pytest

from blocks import Block, Port, load_graph
from blocks.core.registry import Registry


class FakeEntryPoint:
    def __init__(self, name, value, obj):
        self.name, self.value, self._obj = name, value, obj

    def load(self):
        if isinstance(self._obj, Exception):
            raise self._obj
        return self._obj


def test_entry_point_toolbox_with_blocks_and_subgraphs(tmp_path, monkeypatch, write):
    pkg = tmp_path / "mytools"
    (pkg / "subgraphs").mkdir(parents=True)
    (pkg / "__init__.py").write_text(
        "from blocks import Block, Port, Param, block\n"
        "SUBGRAPHS = 'subgraphs'\n"
        "@block('mytools.twice', category='mytools')\n"
        "class Twice(Block):\n"
        "    '''Doubles its input.'''\n"
        "    inputs = {'x': Port.scalar(None)}\n"
        "    outputs = {'y': Port.scalar(None)}\n"
        "    def step(self, x):\n"
        "        return {'y': 2 * x}\n")
    (pkg / "subgraphs" / "quadruple.yaml").write_text(
        "doc: Four times the input.\n"
        "inputs: {x: a.x}\noutputs: {y: b.y}\n"
        "nodes:\n  - {id: a, type: mytools.twice}\n  - {id: b, type: mytools.twice}\n"
        "edges:\n  - a.y -> b.x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    module = __import__("mytools")
    registry = Registry()
    broken = FakeEntryPoint("broken", "nowhere:thing", ImportError("no module named nowhere"))
    good = FakeEntryPoint("mytools", "mytools", module)
    monkeypatch.setattr(importlib.metadata, "entry_points",
                        lambda group: [broken, good] if group == "semmap.blocks" else [])
    import blocks.generic  # noqa: F401  (registers 'constant', even when this file runs alone)
    from blocks.core import registry as registry_module
    registry.blocks.update(registry_module.REGISTRY.blocks)  # what the decorator registered
    registry.ensure_loaded()
    assert registry.get("quadruple") is not None
    assert registry.toolbox_of["mytools.twice"] == "mytools"
    assert registry.toolbox_of["quadruple"] == "mytools"
    assert "toolbox 'broken'" in registry.load_warnings[0]
    path = write("g.yaml", """
        nodes:
          - {id: one, type: constant, params: {value: 3}}
          - {id: q, type: quadruple}
        edges:
          - one.value -> q.x
    """)
    from blocks import Runner
    runner = Runner(load_graph(path, registry=registry))
    runner.run(1)
    assert runner.value("q.b.y") == 12
    sys.modules.pop("mytools", None)


def test_callable_entry_point_registers_classes():
    class Thing(Block):
        """A thing."""
        outputs = {"y": Port.scalar()}

        def step(self):
            return {"y": 1.0}

    Thing.type_name = "thing"
    registry = Registry()
    registry.load_toolbox(lambda: [Thing], "things")
    assert registry.get("thing") is Thing and registry.toolbox_of["thing"] == "things"


def test_step_signature_must_match_inputs():
    from blocks import block

    with pytest.raises(TypeError, match="declared inputs"):
        @block("test.bad_signature")
        class Bad(Block):
            inputs = {"a": Port(), "b": Port()}

            def step(self, a, c):
                return {}


def test_port_names_may_not_have_dots():
    from blocks import block

    with pytest.raises(TypeError, match="may not contain"):
        @block("test.bad_port")
        class Bad(Block):
            outputs = {"a.b": Port()}

            def step(self):
                return {}


def test_duplicate_type_name_from_another_class_is_refused():
    from blocks import block

    with pytest.raises(TypeError, match="already registered"):
        @block("scale")
        class MyScale(Block):
            def step(self):
                return {}


def test_module_toolbox_relabels_its_blocks():
    registry = Registry()
    mod = types.ModuleType("blocks.generic")
    from blocks.core.registry import REGISTRY
    registry.blocks.update(REGISTRY.blocks)
    registry.load_toolbox(mod, "generic")
    assert registry.toolbox_of["arith"] == "generic"
