"""sim2d through the dataflow: world, drive, sonar, odometry; run outputs, --world, render."""
from __future__ import annotations

import csv
import json
import textwrap

import cv2
import numpy as np
import pytest

ROOM_YAML = """
image: room.png
resolution: 0.05
origin: [0.0, 0.0, 0.0]
negate: 0
occupied_thresh: 0.65
free_thresh: 0.196
starts: [[1.0, 2.5, 0.0], [1.0, 1.2, 0.0]]
signs:
  - {text: MAIL ROOM, x: 5.0, y: 4.85, facing: -90}
"""

GRAPH = """
name: drive
dt: 0.1
steps: 60
nodes:
  - {id: world, type: sim2d.world, params: {world: WORLD}}
  - {id: v, type: constant, params: {value: 0.6, unit: m/s}}
  - {id: w, type: constant, params: {value: 0.25, unit: rad/s}}
  - {id: drive, type: sim2d.drive}
  - {id: sonar, type: sim2d.sonar, params: {rate_hz: 5.0}}
  - {id: odom, type: sim2d.odometry}
  - {id: truth, type: sim2d.true_pose}
edges:
  - world.sim -> drive.sim
  - world.sim -> sonar.sim
  - world.sim -> odom.sim
  - world.sim -> truth.sim
  - v.value -> drive.v
  - w.value -> drive.w
"""


@pytest.fixture
def room(tmp_path):
    img = np.full((100, 240), 254, np.uint8)  # 12 x 5 m
    img[:3, :] = 0
    img[-3:, :] = 0
    img[:, :3] = 0
    img[:, -3:] = 0
    cv2.imwrite(str(tmp_path / "room.png"), img)
    (tmp_path / "room.yaml").write_text(ROOM_YAML)
    return tmp_path / "room.yaml"


@pytest.fixture
def graph(tmp_path, room):
    path = tmp_path / "drive.yaml"
    path.write_text(textwrap.dedent(GRAPH).replace("WORLD", str(room)))
    return path


def read_trajectory(folder):
    with open(folder / "trajectory.csv") as fh:
        return list(csv.DictReader(fh))


def test_run_writes_trajectory_and_collisions(cli, graph, tmp_path):
    out = tmp_path / "out"
    result = cli("run", graph, "--out", out, "-q", "--strict", "--record", "sonar.ranges",
                 "--record", "sonar.fresh")
    assert result.code == 0, result
    rows = read_trajectory(out)
    assert len(rows) == 60 and rows[0]["tick"] == "0"
    assert float(rows[0]["x"]) == 1.0 and float(rows[-1]["x"]) > 2.0
    assert set(rows[0]) >= {"tick", "time", "x", "y", "theta", "odom_x", "odom_y", "odom_theta"}
    run = json.loads((out / "run.json").read_text())
    assert run["metrics"]["world"]["collisions"] >= 0
    assert "collisions_by_robot" in run["metrics"]["world"]
    from blocks import load_probes
    probes = load_probes(out)
    ticks, ranges = probes["sonar.ranges"]
    assert ranges.shape[1] == 16
    assert ticks.tolist() == list(range(0, 60, 2))  # 5 Hz at dt 0.1: every other tick
    assert probes["sonar.fresh"][1].tolist() == [t % 2 == 0 for t in range(60)]


def test_same_seed_same_trajectory(cli, graph, tmp_path):
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        assert cli("run", graph, "--out", tmp_path / name, "-q", "--seed", seed).code == 0
    a, b, c = (tmp_path / n / "trajectory.csv" for n in "abc")
    assert a.read_bytes() == b.read_bytes()
    assert (tmp_path / "a" / "sonar.npz").read_bytes() == (tmp_path / "b" / "sonar.npz").read_bytes()
    assert a.read_bytes() != c.read_bytes()  # odometry noise follows the seed


def test_world_option_sets_every_world_node(cli, graph, tmp_path, room):
    other = room.parent / "moved.yaml"
    other.write_text(ROOM_YAML.replace("[1.0, 2.5, 0.0], [1.0, 1.2, 0.0]",
                                       "[3.0, 2.5, 1.0], [1.0, 1.2, 0.0]"))
    out = tmp_path / "moved"
    assert cli("run", graph, "--world", other, "--out", out, "-q").code == 0
    rows = read_trajectory(out)
    assert float(rows[0]["x"]) == 3.0 and float(rows[0]["theta"]) == 1.0
    run = json.loads((out / "run.json").read_text())
    node = next(n for n in run["graph"]["nodes"] if n["id"] == "world")
    assert node["params"]["world"] == {"value": str(other), "from": "--world"}


def test_world_option_without_world_node_is_an_error(cli, tmp_path):
    from conftest import ROOT
    result = cli("run", ROOT / "graphs/examples/counter.yaml", "--world", "x.yaml",
                 "--out", tmp_path / "x")
    assert result.code == 2 and "no node in the graph takes a world" in result.err


def test_malformed_world_is_a_clear_error_at_run(cli, graph, tmp_path, room):
    bad = room.parent / "bad.yaml"
    bad.write_text(ROOM_YAML.replace("negate: 0", "negate: maybe"))
    result = cli("run", graph, "--world", bad, "--out", tmp_path / "bad", "-q")
    assert result.code == 2 and "Traceback" not in result.err
    assert "bad.yaml" in result.err and "'negate' must be 0 or 1" in result.err


def test_missing_world_names_the_world_file_not_a_graph_line(cli, graph, tmp_path):
    absent = tmp_path / "absent.yaml"
    result = cli("run", graph, "--world", absent, "--out", tmp_path / "x", "-q")
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{absent}: node 'world': file not found" in result.err  # no graph line number


def test_world_option_also_sets_the_graphs_own_world_parameter(cli, tmp_path):
    from conftest import ROOT
    out = tmp_path / "corridor"
    result = cli("run", ROOT / "graphs/perimeter_following.yaml", "--world", "corridor",
                 "--out", out, "-q", "--steps", 3)
    assert result.code == 0, result
    run = json.loads((out / "run.json").read_text())
    assert run["graph"]["params"]["world"] == {"value": "corridor", "from": "--world"}


def test_two_robots_in_one_world(cli, tmp_path, room):
    path = tmp_path / "two.yaml"
    path.write_text(textwrap.dedent(f"""
        name: two
        dt: 0.1
        steps: 30
        nodes:
          - id: world
            type: sim2d.world
            params:
              world: {room}
              robots: [{{name: alpha}}, {{name: beta}}]
          - {{id: v, type: constant, params: {{value: 0.5, unit: m/s}}}}
          - {{id: w_a, type: constant, params: {{value: 0.3, unit: rad/s}}}}
          - {{id: w_b, type: constant, params: {{value: -0.3, unit: rad/s}}}}
          - {{id: drive_a, type: sim2d.drive, params: {{robot: alpha}}}}
          - {{id: drive_b, type: sim2d.drive, params: {{robot: beta}}}}
          - {{id: sonar_a, type: sim2d.sonar, params: {{robot: alpha}}}}
          - {{id: sonar_b, type: sim2d.sonar, params: {{robot: beta}}}}
        edges:
          - world.sim -> drive_a.sim
          - world.sim -> drive_b.sim
          - world.sim -> sonar_a.sim
          - world.sim -> sonar_b.sim
          - v.value -> drive_a.v
          - v.value -> drive_b.v
          - w_a.value -> drive_a.w
          - w_b.value -> drive_b.w
    """))
    out = tmp_path / "two_out"
    assert cli("run", path, "--out", out, "-q", "--record", "sonar_b.ranges").code == 0
    rows = read_trajectory(out)
    alpha = [r for r in rows if r["robot"] == "alpha"]
    beta = [r for r in rows if r["robot"] == "beta"]
    assert len(alpha) == len(beta) == 30
    assert float(alpha[-1]["theta"]) > 0.5 and float(beta[-1]["theta"]) < -0.5
    assert float(beta[0]["y"]) == 1.2  # the world's second start pose
    run = json.loads((out / "run.json").read_text())
    assert set(run["metrics"]["world"]["collisions_by_robot"]) == {"alpha", "beta"}
    # beta's left sonars see alpha 1.3 m away (centre to centre), not the far wall
    from blocks import load_probes
    from sim2d.robot import load_robot
    lt1 = load_robot("atrv_mini").sonar_index("Lt1")
    assert load_probes(out)["sonar_b.ranges"][1][0, lt1] == pytest.approx(1.3 - 0.25 - 0.25,
                                                                          abs=0.05)


def test_unknown_robot_name_is_a_user_error(cli, graph, tmp_path):
    text = graph.read_text().replace("{id: drive, type: sim2d.drive}",
                                     "{id: drive, type: sim2d.drive, params: {robot: nobody}}")
    graph.write_text(text)
    result = cli("run", graph, "--out", tmp_path / "o", "-q")
    assert result.code == 2 and "no robot named 'nobody'" in result.err
    assert "Robots: robot" in result.err


def test_render_png_and_gif(cli, graph, tmp_path):
    out = tmp_path / "out"
    assert cli("run", graph, "--out", out, "-q").code == 0
    result = cli("render", out, "--tick", 30, "--gif", "--frames", 5)
    assert result.code == 0, result
    png = (out / "render.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "run.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    image = cv2.imread(str(out / "render.png"))
    # the robot's path (blue, #1f77b4) is drawn
    blue = np.all(np.abs(image.astype(int) - [180, 119, 31]) < 40, axis=2)
    assert blue.sum() > 200


def test_render_errors(cli, tmp_path):
    assert "no run.json" in cli("render", tmp_path).err
    (tmp_path / "run.json").write_text(json.dumps({"metrics": {}}))
    result = cli("render", tmp_path)
    assert result.code == 2 and "no simulated world" in result.err


CAMERA_GRAPH = """
name: cam
dt: 0.1
steps: 30
nodes:
  - {id: world, type: sim2d.world, params: {world: office}}
  - {id: pan, type: constant, params: {value: -0.9, unit: rad}}
  - {id: tilt, type: constant, params: {value: 0.5, unit: rad}}
  - {id: camera, type: sim2d.camera}
  - {id: frames, type: recorder, trigger: camera.fresh}
edges:
  - world.sim -> camera.sim
  - pan.value -> camera.pan
  - tilt.value -> camera.tilt
  - camera.image -> frames.x
"""


def test_camera_pans_at_head_rate_and_sees_the_sign(cli, tmp_path):
    from blocks import load_probes
    path = tmp_path / "cam.yaml"
    path.write_text(CAMERA_GRAPH)
    out = tmp_path / "cam"
    result = cli("run", path, "--out", out, "-q", "--strict", "--record", "camera.pan",
                 "--record", "camera.visible", "--record", "camera.fresh")
    assert result.code == 0, result
    probes = load_probes(out)
    pan = probes["camera.pan"][1]
    step = np.radians(90.0) * 0.1  # the ATRV-Mini head pans at 90 deg/s
    assert pan[0] == pytest.approx(-step) and pan[3] == pytest.approx(-4 * step)
    assert pan[-1] == pytest.approx(-0.9)
    fresh = probes["camera.fresh"][1]
    assert fresh.sum() == 15  # 5 frames/s at dt 0.1 for 3 s
    visible = probes["camera.visible"][1][-1]
    assert [v["text"] for v in visible] == ["MAIL ROOM"]
    frames = np.load(out / "frames.npz")["values"]
    assert frames.shape == (15, 240, 320, 3) and frames.dtype == np.uint8
    x0, y0, x1, y1 = visible[0]["bbox"]
    plate = frames[-1][y0:y1 + 1, x0:x1 + 1].mean(axis=2)
    assert plate.max() > 200 and plate.min() < 80  # white plate, black letters
