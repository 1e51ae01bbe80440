"""Simulator speed: robot steps per second with 16 sonars, for 1, 10 and 100 robots.

One *robot step* is what a control tick costs per robot: applying its drive
command, its share of the physics step (0.1 s of simulated time, in 5 ms
substeps) and one reading of its 16 sonars (the exact 30-degree cone model
against the walls near it and the other robots).

Reported per scenario: simulation steps per wall second, robot steps per
second (steps x robots) and simulated seconds per wall second (x real time).
Because these machines are noisy, each figure is also given as a ratio to a
reference measured in the same run on the same world: pymunk's own
``segment_query_first`` ray casts (the issue quotes about 115k rays/s here),
so "one robot step costs as much as K pymunk rays". A 1-robot run through the
dataflow engine (world + drive + sonar + odometry blocks) shows the engine's share.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim2d.robot import load_robot  # noqa: E402
from sim2d.simulation import Simulation  # noqa: E402
from sim2d.world import World, distance_to_segments, load_world  # noqa: E402
from sim2d.worlds import world_path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "sim.json"
DT = 0.1
TARGET_SINGLE = 1000.0  # robot steps/s for one robot


def free_starts(world: World, count: int, seed: int = 0) -> list[tuple[float, float, float]]:
    """``count`` poses in free space, 0.5 m from walls and 0.9 m from each other."""
    rng = np.random.default_rng(seed)
    xmin, ymin, xmax, ymax = world.bounds()
    poses = [world.start]
    tries = 0
    while len(poses) < count:
        tries += 1
        if tries > 200_000:
            raise RuntimeError(f"could not place {count} robots in {world.name}")
        x, y = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
        if distance_to_segments(np.array([x, y]), world.segments).min() < 0.5:
            continue
        if any(math.hypot(x - px, y - py) < 0.9 for px, py, _ in poses):
            continue
        poses.append((x, y, rng.uniform(-math.pi, math.pi)))
    return poses


def pymunk_rays_per_second(sim: Simulation, seconds: float) -> float:
    """The reference: pymunk ray casts of sonar length (4 m) from the robots' positions."""
    import pymunk
    rng = np.random.default_rng(1)
    origins = [r.pose for r in sim.robots.values()]
    rays = []
    for i in range(2000):
        x, y, _ = origins[i % len(origins)]
        a = rng.uniform(-math.pi, math.pi)
        rays.append(((x, y), (x + 4 * math.cos(a), y + 4 * math.sin(a))))
    query = sim.space.segment_query_first
    everything = pymunk.ShapeFilter()
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for a, b in rays:
            query(a, b, 0.0, everything)
        count += len(rays)
    return count / (time.perf_counter() - start)


def robot_steps(sim: Simulation, seconds: float) -> tuple[float, int]:
    """Simulation steps per wall second (all robots driving and sensing)."""
    names = list(sim.robots)
    steps, start = 0, time.perf_counter()
    while True:
        for i, name in enumerate(names):
            sim.command(name, 0.5, 0.6 * math.sin(0.05 * steps + i))
        sim.step(DT)
        for name in names:
            sim.sonar(name)
        steps += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds and steps >= 3:
            return steps / elapsed, steps


def camera_frames_per_second(world: World, spec: Any, seconds: float,
                             noise_ahead: bool = True) -> float:
    """320 x 240 PTZ frames (image and ground truth) per wall second, panning along the
    office corridor: with the noise drawn a frame ahead on a thread, as the camera block
    draws them, or (``noise_ahead`` False) in turn on this thread."""
    from sim2d.blocks import camera_spec_of
    from sim2d.camera import CameraRenderer, camera_pose
    from sim2d.noise import NoiseAhead

    cam_spec, _ = camera_spec_of(spec)
    renderer = CameraRenderer(world, cam_spec)
    rng = np.random.default_rng(0)
    rng = NoiseAhead(rng) if noise_ahead else rng
    frames, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds or frames < 3:
        x, y, th = world.start
        pose = camera_pose((x + 0.05 * frames % 20, y, th), cam_spec, math.sin(frames / 5))
        renderer.frame(pose, 0.3, 1.0 + frames % 3, rng)
        frames += 1
    return frames / (time.perf_counter() - start)


def engine_steps(seconds: float) -> float:
    """Ticks per second of a 1-robot graph (world, drive, sonar, odometry) in the engine."""
    import tempfile

    from blocks.core.loader import load_graph
    from blocks.core.runner import Runner

    text = """
name: bench
dt: 0.1
nodes:
  - {id: world, type: sim2d.world, params: {world: office, trajectory: false}}
  - {id: v, type: constant, params: {value: 0.5, unit: m/s}}
  - {id: w, type: constant, params: {value: 0.3, unit: rad/s}}
  - {id: drive, type: sim2d.drive}
  - {id: sonar, type: sim2d.sonar}
  - {id: odom, type: sim2d.odometry}
edges:
  - world.sim -> drive.sim
  - world.sim -> sonar.sim
  - world.sim -> odom.sim
  - v.value -> drive.v
  - w.value -> drive.w
"""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.yaml"
        path.write_text(text)
        runner = Runner(load_graph(path), seed=0)
        runner.run(20)
        ticks, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            runner.run(50)
            ticks += 50
        return ticks / (time.perf_counter() - start)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="short runs, for a smoke test")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    seconds = 0.3 if args.quick else 3.0
    world = load_world(world_path("office"))
    spec = load_robot("atrv_mini")
    print("semmap sim2d speed: office world, ATRV-Mini with 16 sonars, dt = 0.1 s")
    print(f"world: {len(world.segments)} wall segments, {len(world.signs)} signs")
    results: dict[str, Any] = {"world": "office", "dt": DT, "scenarios": []}
    base = Simulation(world, [("r0", spec, world.start)])
    rays = pymunk_rays_per_second(base, seconds)
    results["reference_pymunk_rays_per_s"] = round(rays)
    print(f"reference: pymunk segment_query_first, 4 m rays: {rays:,.0f} rays/s")
    print(f"\n{'robots':>7}{'steps/s':>10}{'robot steps/s':>15}{'x real time':>13}"
          f"{'rays per robot step':>21}")
    for count in (1, 10, 100):
        starts = free_starts(world, count)
        sim = Simulation(world, [(f"r{i}", spec, p) for i, p in enumerate(starts)], seed=0)
        rate, steps = robot_steps(sim, seconds * (2 if count == 100 else 1))
        robot_rate = rate * count
        equivalent = rays / robot_rate
        row = {"robots": count, "steps_per_s": round(rate, 1),
               "robot_steps_per_s": round(robot_rate, 1),
               "sim_s_per_wall_s": round(rate * DT, 2),
               "pymunk_rays_per_robot_step": round(equivalent, 1), "steps_measured": steps,
               "collisions": sum(r.collisions for r in sim.robots.values())}
        results["scenarios"].append(row)
        print(f"{count:>7}{rate:>10.1f}{robot_rate:>15.1f}{rate * DT:>13.1f}{equivalent:>21.1f}")
    single = results["scenarios"][0]["robot_steps_per_s"]
    status = "PASS" if single >= TARGET_SINGLE else "FAIL"
    print(f"\n{status} one robot: {single:.0f} robot steps/s (target >= {TARGET_SINGLE:.0f})")
    fps = camera_frames_per_second(world, spec, seconds)
    in_turn = camera_frames_per_second(world, spec, seconds, noise_ahead=False)
    results["camera_frames_per_s"] = round(fps, 1)
    results["camera_frames_per_s_noise_in_turn"] = round(in_turn, 1)
    print(f"PTZ camera, 320 x 240 frame and ground truth: {fps:.0f} frames/s "
          f"({fps / 5.0:.0f} x the robot's 5 frames/s); {in_turn:.0f} frames/s with the noise "
          f"drawn in turn, not a frame ahead: {fps / in_turn:.2f} x")
    ticks = engine_steps(seconds)
    results["engine_one_robot_ticks_per_s"] = round(ticks, 1)
    print(f"through the dataflow engine (world, drive, sonar, odometry blocks): "
          f"{ticks:.0f} ticks/s = {ticks / single:.2f} x the bare simulation")
    write_results(args.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
