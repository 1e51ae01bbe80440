"""The documentation's examples run, and the block reference is up to date."""
from __future__ import annotations

import re

import pytest

from blocks import GraphError, Runner, check_graph, load_graph
from blocks.core.palette import palette, to_markdown
from conftest import ROOT

FENCE = re.compile(r"```yaml\n(.*?)```", re.S)


def doc_examples() -> list[tuple[str, str, str | None]]:
    text = (ROOT / "docs/graph-format.md").read_text()
    examples = []
    for body in FENCE.findall(text):
        name = re.search(r"^# file: (\S+)", body, re.M).group(1)
        expect = re.search(r"^# expect: (.+)$", body, re.M)
        examples.append((name, body, expect.group(1).strip() if expect else None))
    return examples


def test_docs_have_examples():
    assert len(doc_examples()) >= 6


# Files under lib/ are subgraphs; they run through the examples that include them.
@pytest.mark.parametrize("name", [e[0] for e in doc_examples() if not e[0].startswith("lib/")])
def test_doc_example(name, tmp_path):
    for other, body, _ in doc_examples():  # every example file, for includes
        (tmp_path / other).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / other).write_text(body)
    expect = dict((n, e) for n, _, e in doc_examples())[name]
    path = tmp_path / name
    if expect:
        with pytest.raises(GraphError) as info:
            check_graph(load_graph(path))
        assert expect in str(info.value)
        return
    graph = load_graph(path)
    runner = Runner(graph, out_dir=tmp_path / "out", strict=True)
    runner.run(graph.steps or 10)
    runner.finish()


def test_feedback_example_counts():
    body = dict((n, b) for n, b, _ in doc_examples())["feedback.yaml"]
    assert "delay: 1" in body


def test_block_reference_is_current():
    committed = (ROOT / "docs/blocks.md").read_text()
    assert committed == to_markdown(palette(published_only=True)), "run 'make docs' to regenerate docs/blocks.md"
