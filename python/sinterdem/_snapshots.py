"""Reading a run's snapshots back (``RunResult.times``, ``.particles(i)``, ``.contacts(i)``).

Heat and compact runs write ``particles.pvd`` / ``contacts.pvd`` with one ``particles_NNNNNN.vtu``
/ ``contacts_NNNNNN.vtu`` per snapshot (docs/outputs.md "VTU and PVD"): VTK XML with binary
arrays, zlib-compressed (``vtkZLibDataCompressor``, ``header_type="UInt64"``), base64 inline.
This module reads exactly that format with the standard library and numpy (no VTK needed).
"""

from __future__ import annotations

import base64
import struct
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np

_DTYPES = {"Float64": "<f8", "Float32": "<f4", "Int32": "<i4", "Int64": "<i8", "UInt8": "u1", "UInt32": "<u4", "UInt64": "<u8", "Int8": "i1"}


def pvd_entries(path: Path) -> List[Tuple[float, Path]]:
    """(time [s], file) of each snapshot listed in a ``.pvd`` file, in order."""
    if not path.exists():
        return []
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), path.parent / d.get("file")) for d in root.iter("DataSet")]


def _decode(text: str, dtype: str, compressed: bool) -> np.ndarray:
    raw = text.strip().encode("ascii")
    if not compressed:
        data = base64.b64decode(raw)
        (n,) = struct.unpack("<Q", data[:8])
        return np.frombuffer(data[8:8 + n], dtype=dtype)
    # header: number of blocks, block size, last block size, compressed sizes (UInt64 each),
    # base64-encoded on its own, then the compressed blocks
    first = base64.b64decode(raw[:32])  # 24 bytes → 32 characters
    (nb,) = struct.unpack("<Q", first[:8])
    hlen = 8 * (3 + nb)
    henc = 4 * ((hlen + 2) // 3)
    header = base64.b64decode(raw[:henc])
    sizes = struct.unpack(f"<{3 + nb}Q", header)
    body = base64.b64decode(raw[henc:])
    if len(body) < sum(sizes[3:]):
        # the header and data encoded as one stream
        whole = base64.b64decode(raw)
        body = whole[hlen:]
    out, pos = [], 0
    for c in sizes[3:]:
        out.append(zlib.decompress(body[pos:pos + c]))
        pos += c
    return np.frombuffer(b"".join(out), dtype=dtype)


def read_vtu(path: Path) -> Dict[str, np.ndarray]:
    """Arrays of a sinterdem ``.vtu`` file: ``Points`` (N, 3), ``connectivity``, point and cell data by name."""
    root = ET.parse(path).getroot()
    compressed = root.get("compressor") is not None
    out: Dict[str, np.ndarray] = {}
    piece = root.find("UnstructuredGrid/Piece")
    if piece is None:
        raise ValueError(f"{path}: not a VTK unstructured grid")
    for section in ("Points", "Cells", "PointData", "CellData"):
        node = piece.find(section)
        if node is None:
            continue
        for arr in node.findall("DataArray"):
            name = arr.get("Name") or section
            dtype = _DTYPES[arr.get("type")]
            fmt = arr.get("format", "binary")
            if fmt == "ascii":
                a = np.array((arr.text or "").split(), dtype=dtype)
            else:
                a = _decode(arr.text or "", dtype, compressed)
            k = int(arr.get("NumberOfComponents", "1"))
            if k > 1:
                a = a.reshape(-1, k)
            out["Points" if section == "Points" else name] = a
    return out
