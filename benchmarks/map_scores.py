"""The map score table: every shipped world, specular loss on and off, every map.

Runs ``semmap run graphs/mapping.yaml --world W --set specular=S`` for each
world and prints the scores the map blocks wrote to run.json as a Markdown
table (the one in README.md and docs/maps.md).

    python benchmarks/map_scores.py [--worlds office,corridor] [--out runs/map_scores]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORLDS = ("corridor", "complex", "office", "hospital")
MAPS = (("online_map", "paper online"), ("processed_map", "processed online"),
        ("probabilistic_map", "log-odds"), ("offline_map", "offline"))
COLUMNS = ("precision", "recall", "f1", "f1_visible", "free_coverage_visible", "false_free")


def run(world: str, specular: str, out: Path) -> dict:
    semmap = Path(sys.executable).with_name("semmap")
    folder = out / f"{world}_{specular}"
    subprocess.run([str(semmap), "run", str(ROOT / "graphs/mapping.yaml"), "--world", world,
                    "--set", f"specular={specular}", "--out", str(folder), "--quiet"],
                   check=True, stdout=subprocess.DEVNULL)
    return json.loads((folder / "run.json").read_text())["metrics"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", default=",".join(WORLDS))
    parser.add_argument("--out", type=Path, default=ROOT / "runs/map_scores")
    args = parser.parse_args(argv)
    print("| world | specular | map | precision | recall | F1 | F1 seen | coverage seen "
          "| false free |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for world in args.worlds.split(","):
        for specular in ("on", "off"):
            metrics = run(world, specular, args.out)
            for key, label in MAPS:
                values = " | ".join(f"{metrics[key][c]:.2f}" for c in COLUMNS)
                print(f"| {world} | {specular} | {label} | {values} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
