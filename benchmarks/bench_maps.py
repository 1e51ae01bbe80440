"""Global map update rate: the paper's 2-bit map and the log-odds map, on a recorded exploration.

One *update* is one step's sonar scan accumulated into the global map (for the
paper's map: the local map built, rotated, shifted and added). The scans and
odometry come from the perimeter follower exploring the office world, run
first without the framework. The reference, measured in the same run, is one
simulation step of that robot (physics plus the 16-sonar scan): the ratio says
how many map updates fit in the time of one simulated step.
Target: >= 2000 updates per second on one core, for both models.

Monte Carlo localisation (``maps.amcl``, its defaults: 300 particles at the
start, KLD sampling down to 100): one *update* is the filter's motion, sensor
model and resampling for one scan, forced at every step of the same
exploration. The filter updates every 0.2 m of travel, five or more simulated
steps at the follower's speed, so the target is that an update costs at most
five simulated steps: >= 0.2 updates per step. The same filter with a fixed
300 particles is measured beside it.

Visibility (``blocks.maps.score.visible_from_path``, what a sensor on a path
could see, for the visible-only map scores): about 800 poses along the
office's corridor loop, against the same reference.
Target: the whole loop in under 2 s.

Peak memory: ``semmap run graphs/mapping.yaml --world office`` runs as a child
of a small wrapper process, which reads its peak resident set size (RSS) from
the kernel when it reaps it (``os.wait4``: that child's own ``ru_maxrss``, so
other children cannot inflate it, which ``RUSAGE_CHILDREN`` would, and this
benchmark's own memory is not inherited through fork).  The reference, measured
the same way in the same run, is a process that only imports the framework
and the block libraries: the ratio is what mapping adds on top.
Target: <= 400 MB peak RSS for the whole mapping run.  ``--quick`` runs the
graph for 300 ticks only.
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.explore.controller import (GROUP_INPUTS, KnowledgeBases,  # noqa: E402
                                       PerimeterController, sonar_group_index, sonar_groups)
from blocks.maps.logodds import LogOddsMap  # noqa: E402
from blocks.maps.paper import LocalMapper, PaperGlobalMap, SensorMount  # noqa: E402
from blocks.maps.score import visible_from_path  # noqa: E402
from sim2d.robot import load_robot  # noqa: E402
from sim2d.simulation import Simulation  # noqa: E402
from sim2d.world import load_world  # noqa: E402
from sim2d.worlds import world_path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "maps.json"
TARGET = 2000.0
AMCL_TARGET = 0.2  # filter updates per simulated step's time: one per 0.2 m is one per >= 5 steps
RSS_TARGET_MB = 400.0
#: What the reference process imports: the framework and the block libraries.
REFERENCE_IMPORTS = "import blocks, sim2d, blocks.maps.blocks, blocks.explore.blocks"


def record_exploration(steps: int
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
    """Scans (T, 16), odometry poses (T, 3), sonar mounts, seconds per simulated step, and
    which readings were echoes (T, 16)."""
    spec = load_robot("atrv_mini")
    world = load_world(world_path("office"))
    sim = Simulation(world, [("r", spec, world.start)])
    controller = PerimeterController(KnowledgeBases.load(), spec.limits.max_speed,
                                     spec.limits.max_turn_rate)
    index = sonar_group_index(spec)
    scans, poses, echoes, sim_seconds = [], [], [], 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        ranges, echo = sim.sonar("r")
        sim_seconds += time.perf_counter() - t0
        groups = sonar_groups(ranges, index)
        v, w = controller.decide(np.array([[groups[n][0] for n in GROUP_INPUTS]]))[0]
        t0 = time.perf_counter()
        sim.command("r", v, w)
        sim.step(0.1)
        sim_seconds += time.perf_counter() - t0
        scans.append(ranges.copy())
        echoes.append(echo.copy())
        poses.append(sim.robots["r"].odom.copy())
    return (np.array(scans), np.array(poses), np.asarray(spec.sonar_mounts), sim_seconds / steps,
            np.array(echoes))


def paper_updates_per_second(scans, poses, mounts) -> float:
    mapper = LocalMapper([SensorMount(*m) for m in mounts])
    gm = PaperGlobalMap()
    start = time.perf_counter()
    for ranges, pose in zip(scans, poses):
        gm.add(mapper.local_map(ranges), pose)
    return len(scans) / (time.perf_counter() - start)


def logodds_updates_per_second(scans, poses, mounts) -> float:
    lo = LogOddsMap()
    start = time.perf_counter()
    for ranges, (x, y, theta) in zip(scans, poses):
        c, s = math.cos(theta), math.sin(theta)
        sensors = np.column_stack([x + c * mounts[:, 0] - s * mounts[:, 1],
                                   y + s * mounts[:, 0] + c * mounts[:, 1], theta + mounts[:, 2]])
        lo.add_scan(sensors, ranges)
    return len(scans) / (time.perf_counter() - start)


def amcl_updates_per_second(scans, poses, echoes, mounts,
                            min_particles: int = 100) -> tuple[float, float]:
    """Filter updates per second, one forced at every step (the office map), and the mean
    number of particles; ``min_particles=300`` fixes the number."""
    from blocks.maps.amcl import AMCLParams, MonteCarloLocaliser, map_walls
    from blocks.maps.mapio import occupancy_map_from_world
    sonar = load_robot("atrv_mini").sonar
    walls = map_walls(occupancy_map_from_world(load_world(world_path("office"))))
    params = AMCLParams(update_min_d=0.0, update_min_a=0.0, min_particles=min_particles)
    loc = MonteCarloLocaliser(walls, mounts, cone_deg=sonar.cone_deg, max_range=sonar.max_range,
                              specular_deg=sonar.specular_deg, start=poses[0], params=params,
                              rng=0)
    loc.step(poses[0], scans[0], echoes[0])
    start = time.perf_counter()
    for ranges, echo, pose in zip(scans[1:], echoes[1:], poses[1:]):
        loc.step(pose + [1e-3, 0.0, 0.0], ranges, echo)  # past the zero thresholds
    rate = (len(scans) - 1) / (time.perf_counter() - start)
    return rate, float(np.mean(loc.particle_counts))


VISIBILITY_TARGET_S = 2.0


def visibility_seconds() -> tuple[float, int]:
    """Seconds for visible_from_path on ~800 poses round the office's corridor loop, and the
    number of cells seen."""
    world = load_world(world_path("office"))
    loop = np.array([[1.0, 5.8], [29.0, 5.8], [29.0, 14.0], [1.0, 14.0], [1.0, 5.8]])
    start = time.perf_counter()
    seen = visible_from_path(world, loop, spacing=72.0 / 800)
    return time.perf_counter() - start, int(seen.sum())


def _semmap_command() -> list[str]:
    """The venv's ``semmap`` next to this interpreter, else ``python -m blocks.cli``."""
    script = Path(sys.executable).with_name("semmap")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "blocks.cli"]


#: Runs argv[1:] and prints its peak RSS (ru_maxrss) to stdout; the child's output goes to
#: stderr.  A fresh, small process, because a child's ru_maxrss also counts the RSS of the
#: process it was forked from (Linux keeps the pre-exec high-water mark across exec).
_RSS_WRAPPER = """
import os, sys
pid = os.fork()
if pid == 0:
    os.dup2(2, 1)
    try:
        os.execvp(sys.argv[1], sys.argv[1:])
    except OSError as exc:
        os.write(2, f"cannot run {sys.argv[1]}: {exc}\\n".encode())
    os._exit(127)
_, status, usage = os.wait4(pid, 0)
print(usage.ru_maxrss)
sys.exit(os.waitstatus_to_exitcode(status))
"""


def peak_rss_mb(command: list[str]) -> float:
    """Run ``command`` and return its peak resident set size in MiB.

    The command runs under a fresh ``python -S`` wrapper that forks it and
    reaps it with ``os.wait4``, which gives that one child's usage (with
    any children it waited for).  Measuring from this process instead would
    be wrong twice: ``RUSAGE_CHILDREN`` is the maximum over every child ever
    reaped, and a child's ``ru_maxrss`` starts at the RSS of the process it
    was forked from (here, a benchmark holding numpy and a recorded run);
    the wrapper's own few MiB are far below anything measured.  The child's
    output goes to a temporary file (shown on failure), so a chatty child
    cannot block on a full pipe.
    """
    with tempfile.TemporaryFile() as log:
        proc = subprocess.run([sys.executable, "-S", "-c", _RSS_WRAPPER, *command],
                              stdout=subprocess.PIPE, stderr=log, cwd=ROOT, text=True,
                              check=False)
        if proc.returncode != 0:
            log.seek(0)
            tail = log.read().decode(errors="replace")[-2000:]
            raise RuntimeError(f"{' '.join(command)} exited with {proc.returncode}:\n{tail}")
    kib_or_bytes = int(proc.stdout.split()[-1])
    # ru_maxrss is in KiB on Linux, in bytes on macOS
    return kib_or_bytes / (2**20 if sys.platform == "darwin" else 2**10)


def mapping_memory(steps: int | None) -> dict[str, float | int | bool | None]:
    """Peak RSS of the office mapping run and of the import-only reference (MiB)."""
    reference = peak_rss_mb([sys.executable, "-c", REFERENCE_IMPORTS])
    with tempfile.TemporaryDirectory(prefix="bench_maps_") as out:
        command = _semmap_command() + ["run", str(ROOT / "graphs" / "mapping.yaml"),
                                       "--world", "office", "--quiet", "--out", out]
        if steps is not None:
            command += ["--steps", str(steps)]
        mapping = peak_rss_mb(command)
    return {"mapping_steps": steps, "mapping_peak_rss_mb": round(mapping, 1),
            "reference_rss_mb": round(reference, 1),
            "mapping_rss_x_reference": round(mapping / reference, 3),
            "rss_target_mb": RSS_TARGET_MB, "rss_pass": mapping <= RSS_TARGET_MB}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    scans, poses, mounts, sim_step, echoes = record_exploration(300 if args.quick else 1500)
    repeats = 1 if args.quick else 3
    rates = {"paper": max(paper_updates_per_second(scans, poses, mounts) for _ in range(repeats)),
             "logodds": max(logodds_updates_per_second(scans, poses, mounts)
                            for _ in range(repeats))}
    reference = 1.0 / sim_step
    print(f"semmap global map updates: {len(scans)} office exploration steps")
    print(f"reference: one simulated robot step (physics + 16 sonars): {reference:,.0f} per s\n")
    print(f"{'model':>8}  {'updates/s':>10}  {'x sim steps':>11}")
    status = 0
    results = {"steps": len(scans), "reference_sim_steps_per_s": round(reference, 1),
               "target_updates_per_s": TARGET}
    for name, rate in rates.items():
        print(f"{name:>8}  {rate:10,.0f}  {rate / reference:11.2f}")
        results[f"{name}_updates_per_s"] = round(rate, 1)
        results[f"{name}_x_sim_step"] = round(rate / reference, 3)
    print()
    for name, rate in rates.items():
        ok = rate >= TARGET
        status |= 0 if ok else 1
        print(f"{'PASS' if ok else 'MISS'} {name}: {rate:,.0f} updates per second "
              f"(target >= {TARGET:,.0f})")
    fixed, _ = amcl_updates_per_second(scans[:200], poses[:200], echoes[:200], mounts,
                                       min_particles=300)
    amcl, particles = amcl_updates_per_second(scans[:200], poses[:200], echoes[:200], mounts)
    results["amcl_updates_per_s"] = round(amcl, 1)
    results["amcl_x_sim_step"] = round(amcl / reference, 4)
    results["amcl_particles_mean"] = round(particles, 1)
    results["amcl_300_updates_per_s"] = round(fixed, 1)
    results["amcl_300_x_sim_step"] = round(fixed / reference, 4)
    ok = amcl / reference >= AMCL_TARGET
    status |= 0 if ok else 1
    print(f"{'PASS' if ok else 'MISS'} amcl (KLD sampling, {particles:.0f} particles on "
          f"average): {amcl:,.0f} updates per second, {amcl / reference:.2f} per simulated step "
          f"(target >= {AMCL_TARGET}; a fixed 300: {fixed / reference:.2f})")
    seconds, cells = min(visibility_seconds() for _ in range(repeats))
    results["visibility_s"] = round(seconds, 3)
    results["visibility_poses_per_sim_step"] = round(800 / seconds / reference, 3)
    ok = seconds <= VISIBILITY_TARGET_S and cells > 50_000
    status |= 0 if ok else 1
    print(f"{'PASS' if ok else 'MISS'} visibility: 800 poses round the office loop in "
          f"{seconds:.2f} s, {800 / seconds / reference:.2f} poses per simulated step "
          f"(target <= {VISIBILITY_TARGET_S:g} s)")
    memory = mapping_memory(300 if args.quick else None)
    results.update(memory)
    ticks = "the whole run" if memory["mapping_steps"] is None else \
        f"{memory['mapping_steps']} ticks"
    print(f"\npeak RSS, semmap run graphs/mapping.yaml --world office ({ticks}):")
    print(f"{'process':>9}  {'MiB':>7}  {'x ref':>6}")
    print(f"{'reference':>9}  {memory['reference_rss_mb']:7.1f}  {1.0:6.2f}   (imports only)")
    print(f"{'mapping':>9}  {memory['mapping_peak_rss_mb']:7.1f}  "
          f"{memory['mapping_rss_x_reference']:6.2f}")
    status |= 0 if memory["rss_pass"] else 1
    print(f"{'PASS' if memory['rss_pass'] else 'MISS'} mapping: "
          f"{memory['mapping_peak_rss_mb']:,.0f} MiB peak RSS (target <= {RSS_TARGET_MB:,.0f})")
    write_results(args.json, results)
    return 0 if args.quick else status  # a quick run is a smoke test on a busy machine


if __name__ == "__main__":
    sys.exit(main())
