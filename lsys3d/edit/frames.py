"""The frames between ``lsys3d edit``'s server and its workers: an 8-byte length, then a pickle.

Both ends are lsys3d (the server starts the worker itself), so a pickle carries the answers' bytes without
a copy through base64 or JSON.
"""

from __future__ import annotations

import pickle
import struct

__all__ = ["HEADER", "decode", "encode"]

HEADER = struct.Struct(">Q")
"""A frame's header: the length of the pickle that follows."""


def encode(message: dict) -> bytes:
    """``message`` as one frame."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    return HEADER.pack(len(data)) + data


def decode(data: bytes) -> dict:
    """The message of a frame's body (without its header)."""
    return pickle.loads(data)  # our own child process wrote it
