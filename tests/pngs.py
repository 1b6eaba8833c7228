"""A small PNG reader for the picture tests: zlib and numpy, no imaging library.

It reads what Blender writes for a preview -- 8-bit greyscale, RGB or RGBA,
not interlaced -- and refuses anything else, rather than guess.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"
_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}  # colour type -> samples per pixel


def _chunks(data: bytes):
    pos = len(SIGNATURE)
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"bad CRC in chunk {kind!r}"
        yield kind, body
        pos += 12 + length


def _paeth(a: int, b: int, c: int) -> int:
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    return b if pb <= pc else c


def _unfilter(raw: bytes, height: int, stride: int, bpp: int) -> np.ndarray:
    rows = np.zeros((height, stride), np.uint8)
    previous = np.zeros(stride, np.int64)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int64)
        if kind == 0:
            out = line
        elif kind == 2:  # up
            out = (line + previous) % 256
        else:  # sub, average and paeth depend on the pixel just decoded: byte by byte
            out = np.zeros(stride, np.int64)
            cur, up = line.tolist(), previous.tolist()
            res = out.tolist()
            for x in range(stride):
                left = res[x - bpp] if x >= bpp else 0
                if kind == 1:
                    res[x] = (cur[x] + left) % 256
                elif kind == 3:
                    res[x] = (cur[x] + (left + up[x]) // 2) % 256
                elif kind == 4:
                    upleft = up[x - bpp] if x >= bpp else 0
                    res[x] = (cur[x] + _paeth(left, up[x], upleft)) % 256
                else:
                    raise ValueError(f"unknown PNG filter {kind} in row {y}")
            out = np.array(res, np.int64)
        rows[y] = out
        previous = out
    return rows


def read_png(path: str | Path) -> np.ndarray:
    """The pixels of an 8-bit PNG as ``(height, width, channels) uint8``."""
    data = Path(path).read_bytes()
    assert data.startswith(SIGNATURE), f"{path}: not a PNG file"
    header, idat = None, []
    for kind, body in _chunks(data):
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    assert header is not None, f"{path}: no IHDR chunk"
    width, height, depth, color, _, _, interlace = header
    if depth != 8 or color not in _CHANNELS or interlace:
        raise ValueError(f"{path}: only 8-bit non-interlaced grey/RGB(A) PNGs are read (depth {depth}, type {color})")
    channels = _CHANNELS[color]
    raw = zlib.decompress(b"".join(idat))
    assert len(raw) == height * (width * channels + 1), f"{path}: image data has the wrong length"
    return _unfilter(raw, height, width * channels, channels).reshape(height, width, channels)
