"""Map files: occupancy maps in the ROS map_server format (YAML + PGM/PNG).

A map built by semmap should open in any ROS tool (``map_server``, ``rviz``,
``nav2``), and a map made elsewhere should be scoreable here, so the file
format is map_server's: a YAML file naming an image plus ``resolution``,
``origin``, ``negate``, ``occupied_thresh``, ``free_thresh`` and ``mode``.

Conventions
-----------
In memory an :class:`OccupancyMap` holds the probability of occupancy per cell,
``NaN`` meaning unknown, indexed ``[iy, ix]`` with row 0 at the *lowest* y
(y up, REP-103), like :mod:`blocks.maps.tiles`.  Images store row 0 at the
*top*, so reading and writing flip the rows.  ``origin`` is the world pose
``(x, y, yaw)`` of the lower-left corner of cell ``[0, 0]``; only ``yaw = 0``
is supported, because scoring and drawing sample by axis-aligned world
coordinates.

Pixels follow map_server's ``trinary`` mode: with ``negate: 0`` a pixel of
value ``v`` has ``p = (255 - v) / 255``; ``p > occupied_thresh`` is occupied,
``p < free_thresh`` free and anything in between unknown.  :func:`write_map`
writes unknown cells as 205 (``p = 0.196``), the value ``map_saver`` uses.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from blocks.core.atomic import atomic_write_bytes, atomic_write_text
from blocks.core.errors import GraphError, SemmapError
from blocks.core.yamlsrc import line_of, load_yaml_file

__all__ = ["MapError", "OccupancyMap", "UNKNOWN_RGB", "display_sized", "map_rgba",
           "occupancy_map_from_world", "read_map", "write_map"]

#: Pixel value of an unknown cell (``map_saver``'s choice: p = 50/255 = 0.196).
UNKNOWN_PIXEL = 205

#: Colour (RGB) of unknown cells in the map pictures drawn with matplotlib (hybrid map,
#: semantic map): a warm grey, so unknown is not mistaken for p = 0.5.
UNKNOWN_RGB = (175, 160, 150)

#: Longest side (pixels) below which the preview PNG is enlarged so it can be seen.
_PREVIEW_MIN_SIDE = 400


class MapError(SemmapError):
    """A map file is missing or malformed (a user error: reported without a traceback)."""


@dataclass
class OccupancyMap:
    """An occupancy grid in the world frame.

    Attributes
    ----------
    occupancy
        (H, W) float array: probability of occupancy in [0, 1], ``NaN`` = unknown.
        Indexed ``[iy, ix]``; row 0 is the lowest y.
    resolution
        Cell size in metres.
    origin
        World pose ``(x, y, yaw)`` of cell ``[0, 0]``'s lower-left corner; yaw must be 0.
    occupied_thresh, free_thresh
        map_server's thresholds: ``p > occupied_thresh`` is occupied,
        ``p < free_thresh`` is free, anything else unknown.
    """

    occupancy: np.ndarray
    resolution: float
    origin: tuple[float, float, float]
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W): rows (y) and columns (x)."""
        return self.occupancy.shape  # type: ignore[return-value]

    def classes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The map_server trinary reading of the map.

        Returns
        -------
        occupied, free, unknown
            Boolean (H, W) masks that partition the grid.  ``NaN`` compares
            false with both thresholds, so unknown cells land in ``unknown``.
        """
        p = np.asarray(self.occupancy, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            occupied = p > self.occupied_thresh
            free = p < self.free_thresh
        return occupied, free, ~(occupied | free)

    def first_occupied(self, x: float, y: float, dx: float, dy: float,
                       max_range: float) -> tuple[float, float] | None:
        """Where the ray from ``(x, y)`` along the unit direction ``(dx, dy)`` first
        crosses occupied cells: the distances (m) to the first occupied cell and to
        the first free or unknown one after it, or None if there is none within
        ``max_range``.

        The ray is sampled every half cell, so both are within half a cell. A
        sonar map draws a wall as a band some cells thick; the wall's face is
        within it.
        """
        step = self.resolution / 2
        s = np.arange(0.0, max_range + step, step)
        col = np.floor((x + s * dx - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((y + s * dy - self.origin[1]) / self.resolution).astype(int)
        h, w = self.shape
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
        hit = np.zeros(len(s), dtype=bool)
        with np.errstate(invalid="ignore"):
            hit[inside] = self.occupancy[row[inside], col[inside]] > self.occupied_thresh
        first = np.flatnonzero(hit)
        if not len(first):
            return None
        after = np.flatnonzero(~hit[first[0]:])
        end = s[first[0] + after[0]] if len(after) else s[-1] + step
        return float(s[first[0]]), float(end)

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """World coordinates of the cell centres.

        Returns
        -------
        x, y
            ``x`` has shape (W,) (one per column), ``y`` has shape (H,) (one per
            row, increasing, since row 0 is the lowest y).
        """
        h, w = self.shape
        ox, oy = float(self.origin[0]), float(self.origin[1])
        return (ox + (np.arange(w) + 0.5) * self.resolution,
                oy + (np.arange(h) + 0.5) * self.resolution)


# ---- writing -----------------------------------------------------------------------------
def _check_for_writing(m: OccupancyMap) -> np.ndarray:
    """Validate a map before writing it (a bad map here is a programming error: ValueError)."""
    p = np.asarray(m.occupancy, dtype=np.float64)
    if p.ndim != 2 or p.size == 0:
        raise ValueError(f"occupancy must be a non-empty 2-D array, got shape {p.shape}")
    finite = p[np.isfinite(p)]
    if np.isinf(p).any() or finite.size and (finite.min() < 0 or finite.max() > 1):
        raise ValueError("occupancy values must lie in [0, 1] (NaN for unknown)")
    if not (math.isfinite(m.resolution) and m.resolution > 0):
        raise ValueError(f"resolution must be > 0, got {m.resolution!r}")
    if len(m.origin) != 3 or not all(math.isfinite(v) for v in m.origin):
        raise ValueError(f"origin must be three finite numbers, got {m.origin!r}")
    if m.origin[2] != 0:
        raise ValueError("only origin yaw 0 is supported (read_map and score_map reject others)")
    if not 0 <= m.free_thresh <= m.occupied_thresh <= 1:
        raise ValueError(f"need 0 <= free_thresh ({m.free_thresh}) <= occupied_thresh "
                         f"({m.occupied_thresh}) <= 1")
    return p


def _pixels(m: OccupancyMap, p: np.ndarray) -> np.ndarray:
    """Grey pixels (negate 0, row 0 at the top) that read back in the same class.

    ``round(255 * (1 - p))`` alone could push a probability just above a
    threshold across it, so each class's pixels are clamped into the range
    that map_server reads as that class.
    """
    occupied, free, unknown = m.classes()
    # Classify every possible pixel exactly as read_map will (p = (255 - v) / 255), rather
    # than inverting the thresholds in floating point and risking an off-by-one.
    values = np.arange(256)
    p_read = (255.0 - values) / 255.0
    occ_ok, free_ok = p_read > m.occupied_thresh, p_read < m.free_thresh
    occ_max = int(values[occ_ok].max()) if occ_ok.any() else -1
    free_min = int(values[free_ok].min()) if free_ok.any() else 256
    mid_lo, mid_hi = occ_max + 1, free_min - 1
    with np.errstate(invalid="ignore"):
        v = np.rint(255 * (1 - np.nan_to_num(p, nan=0.5)))
    if mid_lo <= UNKNOWN_PIXEL <= mid_hi:
        unknown_value = UNKNOWN_PIXEL
    else:  # unusual thresholds: pick a grey between them
        unknown_value = (mid_lo + mid_hi) // 2
    v = np.where(occupied, np.minimum(v, max(occ_max, 0)), v)
    v = np.where(free, np.maximum(v, min(free_min, 255)), v)
    v = np.where(unknown & np.isfinite(p), np.clip(v, mid_lo, max(mid_lo, mid_hi)), v)
    v = np.where(np.isnan(p), unknown_value, v)
    return np.flipud(np.clip(v, 0, 255).astype(np.uint8))


def _pgm_bytes(image: np.ndarray) -> bytes:
    """A binary (P5) 8-bit PGM."""
    h, w = image.shape
    return f"P5\n{w} {h}\n255\n".encode("ascii") + np.ascontiguousarray(image).tobytes()


def _preview_png(m: OccupancyMap, p: np.ndarray) -> bytes:
    """A picture for people: free white, occupied black, known-uncertain grey shades,
    unknown a blue-grey (so it is not confused with p = 0.5), enlarged if tiny."""
    import cv2

    occupied, free, _ = m.classes()
    shade = np.rint(255 * (1 - np.nan_to_num(p, nan=0.5))).astype(np.uint8)
    rgb = np.repeat(shade[:, :, None], 3, axis=2)
    rgb[free] = 255
    rgb[occupied] = 0
    rgb[np.isnan(p)] = (150, 160, 175)  # B, G, R: a cool grey
    rgb = np.flipud(rgb)
    side = max(rgb.shape[:2])
    if side < _PREVIEW_MIN_SIDE:
        k = min(16, -(-_PREVIEW_MIN_SIDE // side))
        rgb = np.repeat(np.repeat(rgb, k, axis=0), k, axis=1)
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb))
    if not ok:  # pragma: no cover - cv2 always encodes a uint8 BGR array
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def map_rgba(m: OccupancyMap) -> np.ndarray:
    """A picture of a map to draw under plots with ``imshow(..., origin="lower")``.

    Free cells white, occupied black, uncertain cells grey (``1 - p``), unknown
    :data:`UNKNOWN_RGB`. The picture is 8-bit RGBA, 4 bytes a cell, which
    matplotlib draws from without converting it (a float RGB picture costs
    24 bytes a cell, and matplotlib copies it twice more, as float64 RGBA,
    to draw it). Shades are truncated as matplotlib truncates float colours
    (``int(255 * v)``), so it draws the same pixels as from the float picture.

    Parameters
    ----------
    m
        The map (row 0 the lowest y).

    Returns
    -------
    (H, W, 4) uint8 array
        Row 0 the lowest y, alpha 255.

    Examples
    --------
    >>> m = OccupancyMap(np.array([[0.0, 0.5, 1.0, np.nan]]), 0.05, (0.0, 0.0, 0.0))
    >>> map_rgba(m)[0, :, 0]
    array([255, 127,   0, 175], dtype=uint8)
    """
    p = np.asarray(m.occupancy, dtype=np.float64)
    occupied, free, _ = m.classes()
    shade = np.nan_to_num(p, nan=0.5)
    np.clip(shade, 0, 1, out=shade)
    np.subtract(1, shade, out=shade)
    shade *= 255
    rgba = np.empty(p.shape + (4,), dtype=np.uint8)
    rgba[..., :3] = shade.astype(np.uint8)[..., None]
    del shade
    rgba[..., 3] = 255
    rgba[free, :3] = 255
    rgba[occupied, :3] = 0
    rgba[np.isnan(p), :3] = UNKNOWN_RGB
    return rgba


def display_sized(picture: np.ndarray, width_px: float, height_px: float) -> np.ndarray:
    """``picture`` (H, W, C) sampled down (nearest cell) to fit ``width_px`` x ``height_px``,
    or as it is when it fits already.

    matplotlib converts an image to floats to draw it, some 60 bytes a pixel
    (about 100 MB for a 1,100 x 1,500-cell office map): a picture no larger
    than the figure it is drawn in looks the same and costs a figure's worth.
    """
    import cv2
    h, w = picture.shape[:2]
    factor = max(w / max(width_px, 1.0), h / max(height_px, 1.0))
    if factor <= 1.0:
        return picture
    size = (max(1, math.ceil(w / factor)), max(1, math.ceil(h / factor)))
    return cv2.resize(np.ascontiguousarray(picture), size, interpolation=cv2.INTER_NEAREST)


def write_map(yaml_path: str | Path, m: OccupancyMap, *, preview: bool = True,
              comment: str | None = None) -> list[Path]:
    """Write a map in map_server format: ``NAME.yaml`` + ``NAME.pgm`` (+ ``NAME.png``).

    Every file is written atomically, so a viewer polling the folder (or a
    crash) never sees half a map.

    Parameters
    ----------
    yaml_path
        ``NAME.yaml`` (or ``.yml``); the image goes next to it as ``NAME.pgm``.
    m
        The map.  Unknown (``NaN``) cells are written as 205; known cells as
        ``round(255 * (1 - p))`` (``negate: 0``), clamped so each cell reads
        back in the same trinary class.
    preview
        Also write ``NAME.png``, a picture for people (free white, occupied
        black, unknown blue-grey, enlarged if the map is tiny).  It is not
        referenced by the YAML.
    comment
        Text put at the top of the YAML as ``#`` comments (e.g. the run that made it).

    Returns
    -------
    list of Path
        The files written: YAML, PGM and, with ``preview``, PNG.

    Raises
    ------
    ValueError
        If the map itself is invalid (a programming error, not a user one).
    """
    import yaml

    yaml_path = Path(yaml_path)
    if yaml_path.suffix not in (".yaml", ".yml"):
        raise ValueError(f"the map file must end in .yaml or .yml, got {yaml_path.name!r}")
    p = _check_for_writing(m)
    pgm_path = yaml_path.with_suffix(".pgm")
    doc = {
        "image": pgm_path.name,
        "resolution": float(m.resolution),
        "origin": [float(v) for v in m.origin],
        "negate": 0,
        "occupied_thresh": float(m.occupied_thresh),
        "free_thresh": float(m.free_thresh),
        "mode": "trinary",
    }
    header = "".join(f"# {line}\n" for line in comment.splitlines()) if comment else ""
    text = header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
    atomic_write_bytes(pgm_path, _pgm_bytes(_pixels(m, p)))
    written = [yaml_path, pgm_path]
    if preview:
        png_path = yaml_path.with_suffix(".png")
        atomic_write_bytes(png_path, _preview_png(m, p))
        written.append(png_path)
    # The YAML last: once it exists, the image it names is complete.
    atomic_write_text(yaml_path, text)
    return written


# ---- reading -----------------------------------------------------------------------------
_MAP_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")


def _missing(doc: dict, key: str, file: Path) -> MapError:
    """A 'missing key' error that spots a misspelt key."""
    close = difflib.get_close_matches(key, [str(k) for k in doc if k not in _MAP_KEYS], n=1,
                                      cutoff=0.75)
    if close:
        return MapError(f"the map has no '{key}'", file=file, line=line_of(doc, close[0]),
                        field=key, hint=f"Is '{close[0]}' meant to be '{key}'?")
    return MapError(f"the map has no '{key}'", file=file, line=line_of(doc), field=key,
                    hint=f"Add '{key}:' (ROS map_server format: image, resolution, origin, "
                         "negate, occupied_thresh, free_thresh).")


def _number(doc: dict, key: str, file: Path, default: float | None = None, *,
            positive: bool = False, unit: bool = False) -> float:
    """A finite number from the YAML, with map_server's range rules."""
    if key not in doc and default is None:
        raise _missing(doc, key, file)
    value = doc.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MapError(f"'{key}' must be a number, got {value!r}", file=file,
                       line=line_of(doc, key), field=key)
    if positive and value <= 0:
        raise MapError(f"'{key}' must be > 0, got {value!r}", file=file,
                       line=line_of(doc, key), field=key, hint="It is metres per pixel, "
                       "e.g. 0.05.")
    if unit and not 0 <= value <= 1:
        raise MapError(f"'{key}' must be in [0, 1], got {value!r}", file=file,
                       line=line_of(doc, key), field=key,
                       hint="Thresholds are probabilities of occupancy.")
    return float(value)


def read_map(yaml_path: str | Path) -> OccupancyMap:
    """Read any map_server map (PGM or PNG image, ``negate`` 0 or 1).

    Extra keys (a world's ``start``, ``signs``, ...) are ignored, so a world
    file reads as its own map.

    Parameters
    ----------
    yaml_path
        The map's YAML file; a relative ``image`` is resolved from its folder.

    Returns
    -------
    OccupancyMap
        Occupied and free pixels keep their probability; pixels between the
        thresholds become ``NaN`` (unknown) in ``trinary`` mode (the default),
        and keep their probability in ``scale`` mode, as map_server does.

    Raises
    ------
    MapError
        For a missing or unreadable file, a missing key, a bad value or an
        origin with a yaw; the error names the file, line and field.
    """
    from sim2d.world import WorldError, occupancy_from_image, read_grey_image

    path = Path(yaml_path)
    try:
        doc = load_yaml_file(path)
    except GraphError as exc:  # missing file, YAML syntax: a map error here
        hint = exc.hint
        if "not found" in exc.message:
            hint = "Check the path to the map's YAML file (map_server format)."
        raise MapError(exc.message, file=exc.file, line=exc.line, hint=hint) from None
    if not isinstance(doc, dict):
        raise MapError("a map file must be a YAML mapping (ROS map_server format)", file=path,
                       hint="Give image, resolution, origin, negate, occupied_thresh, "
                            "free_thresh.")
    if "image" not in doc:
        raise _missing(doc, "image", path)
    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise MapError(f"'image' must be a file name, got {image!r}", file=path,
                       line=line_of(doc, "image"), field="image")
    resolution = _number(doc, "resolution", path, positive=True)
    if "origin" not in doc:
        raise _missing(doc, "origin", path)
    origin_raw: Any = doc["origin"]
    ok = isinstance(origin_raw, list) and len(origin_raw) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        for v in origin_raw)
    if not ok:
        raise MapError(f"'origin' must be [x, y, yaw] in metres and radians, got {origin_raw!r}",
                       file=path, line=line_of(doc, "origin"), field="origin")
    origin = (float(origin_raw[0]), float(origin_raw[1]), float(origin_raw[2]))
    if origin[2] != 0:
        raise MapError(f"origin yaw {origin[2]} is not supported", file=path,
                       line=line_of(doc, "origin"), field="origin",
                       hint="Only axis-aligned maps (yaw 0) can be read; rotate the image "
                            "and set the yaw to 0.")
    negate = doc.get("negate", 0)
    if negate not in (0, 1) or isinstance(negate, float):
        raise MapError(f"'negate' must be 0 or 1, got {negate!r}", file=path,
                       line=line_of(doc, "negate"), field="negate")
    occ_t = _number(doc, "occupied_thresh", path, 0.65, unit=True)
    free_t = _number(doc, "free_thresh", path, 0.196, unit=True)
    if free_t > occ_t:
        raise MapError(f"free_thresh {free_t} is above occupied_thresh {occ_t}", file=path,
                       line=line_of(doc, "free_thresh"), field="free_thresh")
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale"):
        raise MapError(f"map mode {mode!r} is not supported", file=path,
                       line=line_of(doc, "mode"), field="mode",
                       hint="Use 'trinary' (the default) or 'scale'.")
    image_path = path.parent / image
    if not image_path.is_file():
        raise MapError(f"image '{image}' not found (looked for {image_path})", file=path,
                       line=line_of(doc, "image"), field="image",
                       hint="The image path is relative to the YAML file's folder.")
    try:
        pixels = read_grey_image(image_path, path, line_of(doc, "image"))
    except WorldError as exc:
        raise MapError(exc.message, file=path, line=line_of(doc, "image"), field="image",
                       hint="The image must be an 8- or 16-bit PGM or PNG.") from None
    pixels = np.flipud(pixels)  # image row 0 is the top; ours is the lowest y
    value = pixels.astype(np.float64)
    p = value / 255.0 if negate else (255.0 - value) / 255.0
    occupied, free = occupancy_from_image(pixels, bool(negate), occ_t, free_t)
    if mode == "trinary":
        p = np.where(occupied | free, p, np.nan)
    return OccupancyMap(occupancy=p, resolution=resolution, origin=origin,
                        occupied_thresh=occ_t, free_thresh=free_t)


def occupancy_map_from_world(world: Any) -> OccupancyMap:
    """The world's own floor plan as a map: walls 1.0, everything else 0.0.

    The perfect map a mapper could produce; scoring it gives the best possible
    numbers, which checks the scorer and calibrates the others.

    Parameters
    ----------
    world
        A :class:`sim2d.world.World` loaded from an image (``world.occupied``
        has row 0 at the top, image order; it is flipped here).

    Raises
    ------
    MapError
        If the world has no floor-plan image (vector walls only) or a rotated origin.
    """
    if world.occupied is None:
        raise MapError(f"world '{world.name}' has no floor-plan image (vector walls only)",
                       file=world.source or None, field="image",
                       hint="Map files and scores need a world with an 'image'.")
    if world.origin[2] != 0:
        raise MapError(f"world '{world.name}' has origin yaw {world.origin[2]}; only 0 is "
                       "supported", file=world.source or None, field="origin")
    grid = np.flipud(np.asarray(world.occupied, dtype=bool)).astype(np.float64)
    return OccupancyMap(occupancy=grid, resolution=float(world.resolution),
                        origin=(float(world.origin[0]), float(world.origin[1]), 0.0))
