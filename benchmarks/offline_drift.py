"""How much of the offline map's error is odometry drift: the same recorded run drawn from
odometry, from the true poses, and from the true poses without drift correction.

    semmap run graphs/mapping.yaml --world office --out runs/mapping
    python benchmarks/offline_drift.py runs/mapping
"""
import csv, sys, numpy as np
from blocks.maps.offline import build_offline_map
from blocks.maps.score import score_map
from sim2d.world import load_world
from sim2d.worlds import world_path
run = sys.argv[1] if len(sys.argv) > 1 else "runs/mapping"
d = np.load(f"{run}/sonar.npz"); rows = list(csv.DictReader(open(f"{run}/trajectory.csv")))
pose = lambda p: np.array([[float(r[p + k]) for k in ("x", "y", "theta")] for r in rows])[d["robot@tick"]]
truth, odom = pose(""), pose("odom_")
from blocks.maps.offline import OfflineMapParams
for name, poses, fix in (("odometry", odom, True), ("true poses", truth, True), ("true poses, no drift correction", truth, False)):
    om = build_offline_map(poses, d["robot@ranges"], d["robot@mounts"], echo=d["robot@echo"], params=OfflineMapParams(correct_drift=fix))
    s = score_map(om.map, load_world(world_path("office")))
    err = np.hypot(*(om.poses[:, :2] - truth[:, :2]).T)
    print(name, "precision %.3f false_free %.3f" % (s["precision"], s["false_free"]),
          "pose error mean %.2f max %.2f m" % (err.mean(), err.max()))
e0 = np.hypot(*(odom[:, :2] - truth[:, :2]).T); print("raw odometry error mean %.2f max %.2f m" % (e0.mean(), e0.max()))
