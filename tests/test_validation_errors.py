"""Every validation error names file, line, node and field, and says how to fix it."""
from __future__ import annotations

import pytest

from blocks import GraphError, check_graph, load_graph


def load_error(path, overrides=None) -> GraphError:
    with pytest.raises(GraphError) as info:
        check_graph(load_graph(path, overrides))
    return info.value


def assert_cli_error(cli, path, *fragments, args=()):
    result = cli("check", path, *args)
    assert result.code == 2, result
    assert "Traceback" not in result.err + result.out
    assert result.err.startswith("error: ")
    assert len(result.err.strip().splitlines()) == 1, "one paragraph"
    for fragment in fragments:
        assert fragment in result.err, (fragment, result.err)


def test_yaml_syntax_error_names_line(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter
        edges: []
    """)
    err = load_error(path)
    assert err.file == str(path) and err.line == 3
    assert_cli_error(cli, path, "YAML syntax error", f"{path}:3", "indentation")


def test_unknown_block_type_suggests_closest(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: countr}
    """)
    err = load_error(path)
    assert err.line == 2 and err.node == "a"
    assert_cli_error(cli, path, "unknown block type 'countr'", "Did you mean 'counter'", ":2:")


def test_unknown_output_port(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter}
          - {id: b, type: scale}
        edges:
          - a.cnt -> b.x
    """)
    err = load_error(path)
    assert err.line == 5 and err.node == "a" and "port 'cnt'" in err.field
    assert_cli_error(cli, path, "no output 'cnt'", "Did you mean 'count'")


def test_unknown_input_port(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter}
          - {id: b, type: scale}
        edges:
          - a.count -> b.input
    """)
    assert_cli_error(cli, path, "node 'b'", "no input 'input'", "Its inputs are: x", ":5:")


def test_unknown_parameter(write, cli):
    path = write("g.yaml", """
        nodes:
          - id: a
            type: scale
            params:
              gian: 2.0
    """)
    err = load_error(path)
    assert err.line == 5 and err.node == "a" and "gian" in err.field
    assert_cli_error(cli, path, "has no parameter 'gian'", "Did you mean 'gain'")


def test_wrong_parameter_type(write, cli):
    path = write("g.yaml", """
        nodes:
          - id: a
            type: scale
            params: {gain: fast}
    """)
    err = load_error(path)
    assert err.line == 4
    assert_cli_error(cli, path, "param 'gain'", "expected a number, got 'fast'", "multiplier")


def test_out_of_range_parameter(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: n, type: noise, params: {std: -1.0}}
    """)
    assert_cli_error(cli, path, "node 'n'", "param 'std'", "below the minimum 0.0", ":2:")


def test_out_of_choices_parameter(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: n, type: arith, params: {op: pow}}
    """)
    assert_cli_error(cli, path, "'pow' is not one of 'add'")


def test_bad_override_value_names_set(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: n, type: noise}
    """)
    assert_cli_error(cli, path, "node 'n'", "param 'std' (from --set)", "below the minimum",
                     args=("--set", "n.std=-2"))


def test_override_of_missing_parameter(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: n, type: noise}
    """)
    assert_cli_error(cli, path, "--set 'n.sdt=2'", "Did you mean 'n.std'",
                     args=("--set", "n.sdt=2"))


@pytest.mark.parametrize("field,src,dst,why", [
    ("dtype", "{value: 1}", "{value: 1.0}", "dtype int64 vs float64"),
    ("shape", "{value: [1.0, 2.0, 3.0]}", "{value: [1.0, 2.0]}", "dimension 0 is 3 vs 2"),
    ("unit", "{value: 1.0, unit: m}", "{value: 1.0, unit: rad}", "unit m vs rad"),
    ("frame", "{value: [1.0, 2.0], frame: robot}", "{value: [1.0, 2.0], frame: map}",
     "frame robot vs map"),
])
def test_schema_mismatch(write, cli, field, src, dst, why):
    path = write("g.yaml", f"""
        nodes:
          - {{id: a, type: constant, params: {src}}}
          - {{id: b, type: constant, params: {dst}}}
          - {{id: add, type: arith}}
        edges:
          - b.value -> add.a
          - a.value -> add.b
    """)
    err = load_error(path)
    assert err.line == 7 and err.node == "add" and "port 'b'" in err.field
    assert_cli_error(cli, path, "does not type-check", why)


def test_kind_mismatch_on_trigger(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter}
          - {id: b, type: scale, trigger: a.count}
          - {id: c, type: counter}
        edges:
          - c.count -> b.x
    """)
    assert_cli_error(cli, path, "trigger a.count", "must be an event", "threshold")


def test_required_input_unconnected(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter}
          - {id: b, type: arith}
        edges:
          - a.count -> b.a
    """)
    err = load_error(path)
    assert err.node == "b" and err.line == 3 and "port 'b'" in err.field
    assert_cli_error(cli, path, "required input 'b'", "is not connected", "-> b.b")


def test_input_fed_twice(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter}
          - {id: b, type: scale}
        edges:
          - a.count -> b.x
          - a.count -> b.x
    """)
    assert_cli_error(cli, path, "fed twice", ":6:")


def test_cycle_without_delay_names_nodes(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: src, type: counter}
          - {id: first, type: arith}
          - {id: second, type: scale}
          - {id: third, type: scale}
        edges:
          - src.count -> first.a
          - first.y -> second.x
          - second.y -> third.x
          - third.y -> first.b
    """)
    err = load_error(path)
    for name in ("first", "second", "third"):
        assert name in err.message
    assert "src" not in err.message
    assert_cli_error(cli, path, "cycle without a delay", "delay: 1")


def test_cycle_with_delay_is_fine(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: src, type: counter}
          - {id: first, type: arith}
        edges:
          - src.count -> first.a
          - {from: first.y, to: first.b, delay: 2, initial: 0}
    """)
    assert cli("check", path).code == 0


def test_delay_needs_initial(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: src, type: counter}
          - {id: first, type: arith}
        edges:
          - src.count -> first.a
          - {from: first.y, to: first.b, delay: 1}
    """)
    assert_cli_error(cli, path, "needs an 'initial' value", ":6:")


def test_duplicate_node_ids(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: counter}
          - {id: a, type: clock}
    """)
    err = load_error(path)
    assert err.line == 3
    assert_cli_error(cli, path, "duplicate node id 'a'", "line 2", "Rename")


def test_include_loop(write, cli):
    write("one.yaml", """
        nodes:
          - {id: inner, include: two.yaml}
    """)
    write("two.yaml", """
        nodes:
          - {id: back, include: one.yaml}
    """)
    top = write("top.yaml", """
        nodes:
          - {id: sub, include: one.yaml}
    """)
    assert_cli_error(cli, top, "include loop: top.yaml -> one.yaml -> two.yaml -> one.yaml",
                     "two.yaml:2", "sub.inner.back")


def test_missing_include_file(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: a, include: nowhere.yaml}
    """)
    assert_cli_error(cli, path, "included file 'nowhere.yaml' not found", "relative")


def test_unknown_top_level_field(write, cli):
    path = write("g.yaml", """
        node:
          - {id: a, type: counter}
    """)
    assert_cli_error(cli, path, "unknown top-level field 'node'", "Did you mean 'nodes'")


def test_unknown_graph_param_reference(write, cli):
    path = write("g.yaml", """
        params: {gain: 2.0}
        nodes:
          - {id: a, type: scale, params: {gain: "${gian}"}}
    """)
    assert_cli_error(cli, path, "${gian} names no graph parameter", "Did you mean 'gain'", ":3:")


def test_rate_not_whole_ticks(write, cli):
    path = write("g.yaml", """
        dt: 0.1
        nodes:
          - {id: a, type: counter, rate: 3}
    """)
    assert_cli_error(cli, path, "rate 3 Hz is not a whole number of ticks")


def test_subgraph_unknown_param_points_at_caller(write, cli):
    write("sub.yaml", """
        params: {alpha: 0.5}
        inputs: {x: s.x}
        outputs: {y: s.y}
        nodes:
          - {id: s, type: scale, params: {gain: "${alpha}"}}
    """)
    top = write("top.yaml", """
        nodes:
          - {id: c, type: counter}
          - {id: f, include: sub.yaml, params: {alpah: 1.0}}
        edges:
          - c.count -> f.x
    """)
    assert_cli_error(cli, top, "top.yaml:3", "node 'f'", "has no parameter 'alpah'",
                     "Did you mean 'alpha'")


def test_missing_file(cli, tmp_path):
    assert_cli_error(cli, tmp_path / "absent.yaml", "file not found")


def test_not_a_mapping(write, cli):
    path = write("g.yaml", "- just\n- a list\n")
    assert_cli_error(cli, path, "must be a mapping")


def test_check_valid_graph_exits_zero(cli):
    from conftest import ROOT
    result = cli("check", ROOT / "graphs/examples/counter.yaml")
    assert result.code == 0 and result.out.startswith("ok:")


def test_real_console_script_prints_no_traceback(write, tmp_path):
    import subprocess
    import sys
    from pathlib import Path
    path = write("g.yaml", "nodes:\n  - {id: a, type: countr}\n")
    exe = Path(sys.executable).with_name("semmap")
    proc = subprocess.run([str(exe), "check", str(path)], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "unknown block type" in proc.stderr


def test_yaml_boolean_id_gets_a_hint(write, cli):
    path = write("g.yaml", """
        nodes:
          - {id: yes, type: counter}
    """)
    assert_cli_error(cli, path, "node id True", "quote the id")
