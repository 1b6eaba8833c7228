"""Reading back the .glb files lsys3d writes: the JSON document, the binary chunk, accessors."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

DTYPES = {5126: np.float32, 5123: np.uint16, 5125: np.uint32, 5121: np.uint8}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def read_glb(path: Path) -> tuple[dict, bytes]:
    """The JSON document and the binary chunk of a .glb, checking the container's framing."""
    data = Path(path).read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_len, json_type = struct.unpack_from("<I4s", data, 12)
    assert json_type == b"JSON" and json_len % 4 == 0
    doc = json.loads(data[20 : 20 + json_len])
    if 20 + json_len == len(data):
        return doc, b""
    bin_len, bin_type = struct.unpack_from("<I4s", data, 20 + json_len)
    assert bin_type == b"BIN\0" and bin_len % 4 == 0
    binary = data[28 + json_len : 28 + json_len + bin_len]
    assert 28 + json_len + bin_len == len(data)
    return doc, binary


def accessor(doc: dict, binary: bytes, index: int) -> np.ndarray:
    """The values of accessor ``index`` (tightly packed, as lsys3d writes them)."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = np.dtype(DTYPES[acc["componentType"]])
    width = WIDTH[acc["type"]]
    start = view["byteOffset"] + acc.get("byteOffset", 0)
    out = np.frombuffer(binary, dtype, acc["count"] * width, start)
    return out.reshape(-1, width) if width > 1 else out


def node(doc: dict, name: str) -> dict:
    (found,) = [n for n in doc["nodes"] if n.get("name") == name]
    return found
