"""Robot descriptions (YAML): body, drive limits, odometry noise, sonar layout, camera."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blocks.core.yamlsrc import line_of, load_yaml_file

from .sonar import SonarSpec
from .world import WorldError

ROBOTS_DIR = Path(__file__).parent / "robots"


@dataclass(frozen=True)
class Limits:
    """Velocity and acceleration limits the drive enforces (SI units)."""

    max_speed: float = 1.0
    max_turn_rate: float = 1.5
    max_accel: float = 1.0
    max_turn_accel: float = 3.0


@dataclass(frozen=True)
class OdometryNoise:
    """Std of odometry errors as fractions of the true motion per tick."""

    trans_per_trans: float = 0.02
    trans_per_rot: float = 0.005
    rot_per_rot: float = 0.02
    rot_per_trans: float = 0.01


@dataclass
class RobotSpec:
    """Everything about one robot model."""

    name: str
    length: float = 0.5
    width: float = 0.5
    mass: float = 25.0
    limits: Limits = field(default_factory=Limits)
    odometry: OdometryNoise = field(default_factory=OdometryNoise)
    sonar: SonarSpec = field(default_factory=SonarSpec)
    sonar_names: list[str] = field(default_factory=list)
    sonar_mounts: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # x, y, theta(rad)
    sonar_groups: dict[str, list[str]] = field(default_factory=dict)
    camera: dict[str, Any] = field(default_factory=dict)
    #: Contact switches round the body: (name, from, to), bearings (rad) in the robot
    #: frame, CCW from ``from`` to ``to``; a switch is pressed while something touches
    #: the body within its span.
    bumpers: list[tuple[str, float, float]] = field(default_factory=list)
    source: str = ""

    @property
    def radius(self) -> float:
        """Radius of the circle that encloses the body."""
        return math.hypot(self.length, self.width) / 2

    def sonar_index(self, name: str) -> int:
        return self.sonar_names.index(name)


def _section(doc: dict, key: str, path: Path) -> dict:
    value = doc.get(key) or {}
    if not isinstance(value, dict):
        raise WorldError(f"'{key}' must be a mapping", file=path, line=line_of(doc, key), field=key)
    return value


def _numbers(section: dict, cls: type, path: Path, where: str) -> Any:
    known = cls.__dataclass_fields__
    values = {}
    for key, value in section.items():
        if key not in known:
            raise WorldError(f"unknown field '{where}.{key}'", file=path,
                             line=line_of(section, key), field=f"{where}.{key}",
                             hint=f"Known fields: {', '.join(known)}.")
        default = known[key].default
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise WorldError(f"'{where}.{key}' must be true or false", file=path,
                                 line=line_of(section, key), field=f"{where}.{key}")
        elif isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0:
            raise WorldError(f"'{where}.{key}' must be a number >= 0, got {value!r}", file=path,
                             line=line_of(section, key), field=f"{where}.{key}")
        values[key] = value
    return cls(**values)


def load_robot(name_or_path: str | Path) -> RobotSpec:
    """Load a robot by model name (``atrv_mini``) or YAML path."""
    path = Path(name_or_path)
    if not path.suffix:
        path = ROBOTS_DIR / f"{name_or_path}.yaml"
        if not path.exists():
            known = ", ".join(p.stem for p in sorted(ROBOTS_DIR.glob("*.yaml")))
            raise WorldError(f"unknown robot model '{name_or_path}'",
                             hint=f"Known models: {known}; or give a path to a robot YAML.")
    doc = load_yaml_file(path)
    if not isinstance(doc, dict):
        raise WorldError("a robot file must be a YAML mapping", file=path)
    body = _section(doc, "body", path)
    sonar = dict(_section(doc, "sonar", path))
    sensors = sonar.pop("sensors", [])
    groups = sonar.pop("groups", {}) or {}
    if not isinstance(sensors, list):
        raise WorldError("'sonar.sensors' must be a list", file=path, field="sonar.sensors")
    names, mounts = [], []
    for i, item in enumerate(sensors):
        ok = isinstance(item, dict) and isinstance(item.get("name"), str) and all(
            isinstance(item.get(k), (int, float)) and not isinstance(item.get(k), bool)
            for k in ("x", "y", "theta"))
        if not ok:
            raise WorldError(f"sonar {i} must be {{name, x, y, theta}}", file=path,
                             line=line_of(sensors, i), field=f"sonar.sensors[{i}]")
        if item["name"] in names:
            raise WorldError(f"duplicate sonar name '{item['name']}'", file=path,
                             line=line_of(sensors, i), field=f"sonar.sensors[{i}]")
        names.append(item["name"])
        mounts.append((float(item["x"]), float(item["y"]), math.radians(item["theta"])))
    if not isinstance(groups, dict):
        raise WorldError("'sonar.groups' must map group names to sensor lists", file=path,
                         field="sonar.groups")
    for group, members in groups.items():
        if not isinstance(members, list) or not members or any(m not in names for m in members):
            raise WorldError(f"sonar group '{group}' must list known sensor names", file=path,
                             line=line_of(groups, group), field=f"sonar.groups.{group}",
                             hint=f"Sensors: {', '.join(names)}.")
    camera = _section(doc, "camera", path)
    bumpers = _bumpers(doc.get("bumpers") or [], path)
    for key in ("length", "width", "mass"):
        value = body.get(key, RobotSpec.__dataclass_fields__[key].default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
            raise WorldError(f"'body.{key}' must be a positive number", file=path,
                             line=line_of(body, key), field=f"body.{key}")
    return RobotSpec(
        name=str(doc.get("name") or path.stem),
        length=float(body.get("length", 0.5)), width=float(body.get("width", 0.5)),
        mass=float(body.get("mass", 25.0)),
        limits=_numbers(_section(doc, "limits", path), Limits, path, "limits"),
        odometry=_numbers(_section(doc, "odometry", path), OdometryNoise, path, "odometry"),
        sonar=_numbers(sonar, SonarSpec, path, "sonar"),
        sonar_names=names, sonar_mounts=np.asarray(mounts, dtype=np.float64).reshape(-1, 3),
        sonar_groups={str(k): list(v) for k, v in groups.items()},
        camera=dict(camera), bumpers=bumpers, source=str(path),
    )


def _bumpers(items: Any, path: Path) -> list[tuple[str, float, float]]:
    """The robot file's ``bumpers``: [{name, from, to}] in degrees, checked."""
    if not isinstance(items, list):
        raise WorldError("'bumpers' must be a list of {name, from, to}", file=path,
                         field="bumpers")
    out: list[tuple[str, float, float]] = []
    for i, item in enumerate(items):
        ok = isinstance(item, dict) and isinstance(item.get("name"), str) and all(
            isinstance(item.get(k), (int, float)) and not isinstance(item.get(k), bool)
            for k in ("from", "to"))
        if not ok:
            raise WorldError(f"bumper {i} must be {{name, from, to}} (bearings in degrees)",
                             file=path, line=line_of(items, i), field=f"bumpers[{i}]")
        if any(item["name"] == name for name, _, _ in out):
            raise WorldError(f"duplicate bumper name '{item['name']}'", file=path,
                             line=line_of(items, i), field=f"bumpers[{i}]")
        out.append((item["name"], math.radians(item["from"]), math.radians(item["to"])))
    return out
