"""The perimeter follower through the dataflow: blocks, subgraph, stop input, loop closure."""
from __future__ import annotations

import json


from blocks import Runner, load_graph
from blocks.explore.loop import LoopClosure
from conftest import ROOT

GRAPH = ROOT / "graphs/perimeter_following.yaml"


def test_office_loop_closes_without_collisions(cli, tmp_path):
    out = tmp_path / "office"
    result = cli("run", GRAPH, "--world", "office", "--out", out, "-q", "--steps", 3000)
    assert result.code == 0, result
    run = json.loads((out / "run.json").read_text())
    assert run["status"] == "stopped" and run["stop_reason"] == "finished: back at the start"
    assert run["metrics"]["world"]["collisions"] == 0
    loop = run["metrics"]["follower.loop"]
    assert loop["loop_closed"] and loop["distance_travelled_m"] > 60  # round the corridor loop
    assert (out / "velocity_plot.png").read_bytes()[:4] == b"\x89PNG"


def test_stop_input_halts_the_robot(write, tmp_path):
    path = write("stop.yaml", """
        dt: 0.1
        nodes:
          - {id: world, type: sim2d.world, params: {world: corridor}}
          - {id: sonar, type: sim2d.sonar}
          - {id: truth, type: sim2d.true_pose}
          - {id: follower, type: perimeter_follower}
          - {id: drive, type: sim2d.drive}
          - {id: clock, type: clock}
          - {id: halt, type: threshold, params: {level: 2.0, direction: above}}
        edges:
          - world.sim -> sonar.sim
          - world.sim -> truth.sim
          - world.sim -> drive.sim
          - sonar.ranges -> follower.ranges
          - truth.pose -> follower.pose
          - clock.time -> halt.x
          - halt.on -> follower.stop
          - follower.v -> drive.v
          - follower.w -> drive.w
    """)
    runner = Runner(load_graph(path), seed=0)
    runner.run(20)
    assert runner.value("follower.v") > 0.2  # moving during the first 2 s
    runner.run(15)
    assert runner.value("follower.v") == 0.0 and runner.value("follower.w") == 0.0
    x_then = runner.value("truth.pose")[0]
    runner.run(10)  # still halted; the robot has come to rest
    assert abs(runner.value("truth.pose")[0] - x_then) < 1e-3


def test_loop_closure_rule():
    loop = LoopClosure(radius=1.0, min_travel=10.0, min_away=3.0)
    assert not loop.update(0.0, 0.0, 0.0)
    for k, (x, y) in enumerate([(0.5, 0), (2, 0), (4, 0), (4, 3), (0, 3), (0, 0.5)]):
        closed = loop.update(x, y, float(k + 1))
    assert closed and loop.closed_at == 6.0 and loop.travelled > 10
    short = LoopClosure(min_travel=10.0)
    for x in (0.0, 0.5, 0.2):
        assert not short.update(x, 0.0, 0.0)  # leaving the start is not a loop
