"""Byte-reproducible ``.npz`` files.

``numpy.savez`` stamps each zip entry with the current time, so two identical
runs give different bytes. This writer fixes the timestamp, which keeps the
determinism guarantee (same graph and seed, same bytes) for array outputs.
"""
from __future__ import annotations

import io
import zipfile
from pathlib import Path
from typing import Mapping

import numpy as np

from .atomic import atomic_write_bytes

_EPOCH = (1980, 1, 1, 0, 0, 0)


def npz_bytes(arrays: Mapping[str, np.ndarray], compress: bool = True) -> bytes:
    """Serialise arrays exactly as ``np.savez[_compressed]`` would, minus the clock."""
    buffer = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(buffer, "w", compression=method) as archive:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_EPOCH)
            info.compress_type = method
            info.external_attr = 0o644 << 16
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
            archive.writestr(info, member.getvalue())
    return buffer.getvalue()


def save_npz(path: str | Path, arrays: Mapping[str, np.ndarray], compress: bool = True) -> None:
    """Write an ``.npz`` atomically and reproducibly; read it back with ``np.load``."""
    atomic_write_bytes(path, npz_bytes(arrays, compress))
