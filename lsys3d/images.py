"""Texture images: PNG and JPEG files checked as data, and a small PNG encoder.

glTF 2.0 and USDZ both carry PNG and JPEG, so those are the two formats a
material's ``texture`` may name.  :func:`read_image` reads one
(:func:`lsys3d.external.read_file`: bounded, regular files only) and checks it
without decoding it into memory:

* PNG: the signature, every chunk's length and CRC, the header (size, bit
  depth and colour type of the specification), a palette where one is needed,
  and the compressed pixels, inflated in bounded pieces to exactly the size the
  header promises, every row starting with a valid filter byte;
* JPEG: the markers from start to end of image, a baseline, extended or
  progressive Huffman frame (what every viewer decodes) with 1 or 3 components
  and a size.

So a truncated, corrupt or mislabelled file is an error naming it, not a
black texture in a viewer; and a decompression bomb costs at most the time to
inflate :data:`MAX_IMAGE_SIDE` squared pixels, in 1 MiB of memory.  The bytes
are embedded or copied into the exported files as they are.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import AssetError, clip
from .external import read_file

__all__ = [
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_SIDE",
    "Image",
    "check_image",
    "png_bytes",
    "png_image",
    "png_pixels",
    "read_image",
]

MAX_IMAGE_BYTES = 64 << 20
"""Largest texture file read, in bytes."""
MAX_IMAGE_SIDE = 16384
"""Largest width or height of a texture, in pixels (what desktop GPUs hold)."""

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class Image:
    """A texture image as bytes, checked, with what the writers need to know of it.

    Attributes
    ----------
    name : str
        The file's name (``bark.png``): exported copies are named after it.
    data : bytes
        The file's bytes, embedded or copied as they are.
    mime : str
        ``image/png`` or ``image/jpeg``.
    width, height : int
        Size in pixels.
    alpha : bool
        Whether the image has an alpha channel (a PNG with alpha or transparency).
    source : str
        Where it was read from (messages only; not part of equality).
    """

    name: str
    data: bytes = field(repr=False)
    mime: str
    width: int
    height: int
    alpha: bool
    source: str = field(default="", compare=False)

    @property
    def suffix(self) -> str:
        """``.png`` or ``.jpg``."""
        return ".png" if self.mime == "image/png" else ".jpg"


def read_image(path) -> Image:
    """Read and check a PNG or JPEG file (see the module docstring).

    Raises
    ------
    AssetError
        ``path: what``: missing, unreadable, too large, not a PNG or JPEG, corrupt.
    """
    path = Path(path)
    data = read_file(path, MAX_IMAGE_BYTES, "texture", "lsys3d.images.MAX_IMAGE_BYTES")
    try:
        mime, width, height, alpha = check_image(data)
    except AssetError as exc:
        raise AssetError(f"{clip(str(path), 100)}: {exc}") from None
    return Image(path.name, data, mime, width, height, alpha, str(path))


def check_image(data: bytes) -> tuple[str, int, int, bool]:
    """``(mime, width, height, alpha)`` of PNG or JPEG bytes, or :class:`AssetError` saying what is wrong.

    >>> check_image(png_bytes(np.zeros((2, 3, 4), np.uint8)))
    ('image/png', 3, 2, True)
    >>> check_image(b"GIF89a...")
    Traceback (most recent call last):
      ...
    lsys3d.errors.AssetError: not a PNG or JPEG image (a texture must be one of the two)
    """
    if data.startswith(PNG_SIGNATURE):
        return ("image/png", *_check_png(data))
    if data.startswith(b"\xff\xd8\xff"):
        return ("image/jpeg", *_check_jpeg(data))
    raise AssetError("not a PNG or JPEG image (a texture must be one of the two)")


def _size(width: int, height: int, kind: str) -> None:
    if width < 1 or height < 1:
        raise AssetError(f"{kind} of {width}x{height} pixels: an image needs at least one pixel")
    if width > MAX_IMAGE_SIDE or height > MAX_IMAGE_SIDE:
        raise AssetError(
            f"{kind} of {width}x{height} pixels, larger than {MAX_IMAGE_SIDE} on a side (lsys3d.images.MAX_IMAGE_SIDE)"
        )


# ---------------------------------------------------------------- PNG
# colour type -> (channels, allowed bit depths)
_PNG_TYPES = {0: (1, (1, 2, 4, 8, 16)), 2: (3, (8, 16)), 3: (1, (1, 2, 4, 8)), 4: (2, (8, 16)), 6: (4, (8, 16))}
# Adam7 passes: (x start, y start, x step, y step)
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def _check_png(data: bytes) -> tuple[int, int, bool]:
    pos = len(PNG_SIGNATURE)
    header = None
    palette = transparency = ended = False
    idat: list[memoryview] = []
    view = memoryview(data)
    while pos < len(data):
        if ended:
            raise AssetError("PNG: data after the end chunk (IEND)")
        if pos + 12 > len(data):
            raise AssetError("PNG: cut short (a chunk is incomplete)")
        length, kind = struct.unpack_from(">I4s", data, pos)
        if length > len(data) - pos - 12:
            raise AssetError(f"PNG: cut short (chunk {kind!r} needs {length:,} bytes)")
        body = view[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack_from(">I", data, pos + 8 + length)
        if zlib.crc32(view[pos + 4 : pos + 8 + length]) != crc:
            raise AssetError(f"PNG: chunk {kind.decode('latin-1')!r} is corrupt (its checksum does not match)")
        pos += 12 + length
        if header is None and kind != b"IHDR":
            raise AssetError("PNG: the first chunk is not the header (IHDR)")
        if kind == b"IHDR":
            if header is not None or length != 13:
                raise AssetError("PNG: a malformed header (IHDR)")
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"PLTE":
            palette = True
        elif kind == b"tRNS":
            transparency = True
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            ended = True
    if header is None:
        raise AssetError("PNG: no header (IHDR)")
    if not ended:
        raise AssetError("PNG: cut short (no end chunk, IEND)")
    width, height, depth, color, compression, filtering, interlace = header
    _size(width, height, "PNG")
    if color not in _PNG_TYPES or depth not in _PNG_TYPES[color][1]:
        raise AssetError(f"PNG: colour type {color} with bit depth {depth} is not in the PNG specification")
    if compression != 0 or filtering != 0 or interlace not in (0, 1):
        raise AssetError("PNG: unknown compression, filter or interlace method")
    if color == 3 and not palette:
        raise AssetError("PNG: a palette image without a palette (PLTE)")
    if not idat:
        raise AssetError("PNG: no image data (IDAT)")
    bits = _PNG_TYPES[color][0] * depth
    if interlace:
        rows = []
        for x0, y0, dx, dy in _ADAM7:
            w, h = (width - x0 + dx - 1) // dx, (height - y0 + dy - 1) // dy
            if w and h:
                rows += [(w * bits + 7) // 8] * h
    else:
        rows = None
    _inflate_rows(idat, (width * bits + 7) // 8, height, rows)
    return width, height, color in (4, 6) or transparency


def _inflate_rows(idat: list[memoryview], row_bytes: int, height: int, rows: list[int] | None) -> None:
    """Inflate the pixels in bounded pieces and check they are exactly the promised rows, each with a filter byte."""
    if rows is None:
        starts = None
        total = (row_bytes + 1) * height
    else:
        starts = np.cumsum([0] + [r + 1 for r in rows[:-1]], dtype=np.int64)
        total = sum(r + 1 for r in rows)
    inflater = zlib.decompressobj()
    seen = 0
    step = 1 << 20

    def check(piece: bytes, at: int) -> None:
        if not piece:
            return
        a = np.frombuffer(piece, np.uint8)
        if starts is None:
            first = (-at) % (row_bytes + 1)
            filters = a[first :: row_bytes + 1]
        else:
            inside = starts[(starts >= at) & (starts < at + len(piece))] - at
            filters = a[inside]
        if (filters > 4).any():
            raise AssetError("PNG: corrupt image data (a row with an unknown filter)")

    try:
        for chunk in idat:
            data = chunk
            while data:
                piece = inflater.decompress(data, step)
                check(piece, seen)
                seen += len(piece)
                if seen > total:
                    raise AssetError("PNG: more image data than its size says")
                data = inflater.unconsumed_tail
        while not inflater.eof:
            piece = inflater.decompress(b"", step)
            if not piece:
                break
            check(piece, seen)
            seen += len(piece)
            if seen > total:
                raise AssetError("PNG: more image data than its size says")
    except zlib.error:
        raise AssetError("PNG: corrupt image data (it does not inflate)") from None
    if not inflater.eof or seen != total:
        raise AssetError(f"PNG: the image data are cut short ({seen:,} of {total:,} bytes)")


def png_bytes(pixels: np.ndarray, level: int = 9) -> bytes:
    """Encode ``(h, w)``, ``(h, w, 3)`` or ``(h, w, 4)`` uint8 pixels (top row first) as a PNG file.

    Deterministic: the same pixels give the same bytes (zlib ``level``, no
    timestamp chunk).  For the procedural textures, the docs' example
    textures and the tests.

    >>> png_bytes(np.full((1, 1, 3), 255, np.uint8))[:8] == PNG_SIGNATURE
    True
    """
    pixels = np.ascontiguousarray(pixels, np.uint8)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.ndim != 3 or pixels.shape[2] not in (1, 2, 3, 4) or 0 in pixels.shape:
        raise ValueError(f"png_bytes: expected (h, w[, 1..4]) pixels, got shape {pixels.shape}")
    h, w, c = pixels.shape
    color = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    raw = np.zeros((h, 1 + w * c), np.uint8)  # filter 0 (none) on every row
    raw[:, 1:] = pixels.reshape(h, w * c)

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", w, h, 8, color, 0, 0, 0)
    return (
        PNG_SIGNATURE
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw.tobytes(), level))
        + chunk(b"IEND", b"")
    )


def png_image(name: str, pixels: np.ndarray, level: int = 9, source: str = "") -> Image:
    """``pixels`` encoded by :func:`png_bytes` as an :class:`Image`: its size and alpha read from the pixels'
    shape, which is what :func:`check_image` would read back from the bytes (without inflating them).

    >>> image = png_image("a.png", np.zeros((2, 3, 4), np.uint8))
    >>> (image.mime, image.width, image.height, image.alpha) == check_image(image.data)
    True
    """
    data = png_bytes(pixels, level)
    alpha = pixels.ndim == 3 and pixels.shape[2] in (2, 4)  # png_bytes' grey + alpha and RGBA colour types
    return Image(name, data, "image/png", pixels.shape[1], pixels.shape[0], alpha, source)


def png_pixels(data: bytes) -> np.ndarray:
    """The ``(h, w, c)`` uint8 pixels of a PNG that :func:`png_bytes` wrote: its inverse.

    Only that encoder's form (8 bits, filter 0 on every row); other PNGs raise ``ValueError``.

    >>> p = np.arange(12, dtype=np.uint8).reshape(2, 2, 3)
    >>> bool((png_pixels(png_bytes(p)) == p).all())
    True
    """
    w, h, depth, color = struct.unpack(">IIBB", data[16:26])
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(color)
    if depth != 8 or channels is None:
        raise ValueError(f"png_pixels: not an 8-bit PNG of png_bytes (depth {depth}, colour type {color})")
    pos, idat = len(PNG_SIGNATURE), []
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos : pos + 8])
        if kind == b"IDAT":
            idat.append(data[pos + 8 : pos + 8 + n])
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8).reshape(h, 1 + w * channels)
    if (raw[:, 0] != 0).any():
        raise ValueError("png_pixels: a row with a filter other than 0 (not written by png_bytes)")
    return raw[:, 1:].reshape(h, w, channels)


# ---------------------------------------------------------------- JPEG
_SOF_SUPPORTED = {0xC0: "baseline", 0xC1: "extended", 0xC2: "progressive"}
_SOF_OTHER = {0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def _check_jpeg(data: bytes) -> tuple[int, int, bool]:
    pos = 2
    n = len(data)
    frame = None
    scans = 0
    while True:
        if pos >= n:
            raise AssetError("JPEG: cut short (no end-of-image marker)")
        if data[pos] != 0xFF:
            raise AssetError(f"JPEG: corrupt (no marker at byte {pos:,})")
        while pos < n and data[pos] == 0xFF:  # fill bytes
            pos += 1
        if pos >= n:
            raise AssetError("JPEG: cut short (no end-of-image marker)")
        marker = data[pos]
        pos += 1
        if marker == 0xD9:  # end of image
            break
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            if marker == 0xD8:
                raise AssetError("JPEG: corrupt (a second start-of-image marker)")
            continue
        if pos + 2 > n:
            raise AssetError("JPEG: cut short (a segment is incomplete)")
        (length,) = struct.unpack_from(">H", data, pos)
        if length < 2 or pos + length > n:
            raise AssetError(f"JPEG: cut short or corrupt (a segment of {length} bytes at byte {pos:,})")
        body = data[pos + 2 : pos + length]
        pos += length
        if marker in _SOF_SUPPORTED:
            if frame is not None or len(body) < 6:
                raise AssetError("JPEG: a malformed frame header")
            precision, height, width, components = struct.unpack_from(">BHHB", body)
            if height == 0:
                raise AssetError("JPEG: the height is not in the frame header (a DNL marker), which viewers refuse")
            if components not in (1, 3) or precision != 8:
                raise AssetError(f"JPEG: {components} components of {precision} bits (expected 1 or 3 of 8 bits)")
            if len(body) < 6 + 3 * components:
                raise AssetError("JPEG: a malformed frame header")
            frame = (width, height)
        elif marker in _SOF_OTHER:
            raise AssetError("JPEG: lossless, hierarchical or arithmetic-coded, which glTF and USD viewers refuse")
        elif marker == 0xDA:  # start of scan: entropy-coded data follow until the next marker
            if frame is None:
                raise AssetError("JPEG: a scan before the frame header")
            scans += 1
            while True:
                nxt = data.find(b"\xff", pos)
                if nxt < 0 or nxt + 1 >= n:
                    raise AssetError("JPEG: cut short (a scan without an end)")
                following = data[nxt + 1]
                if following == 0x00 or 0xD0 <= following <= 0xD7 or following == 0xFF:
                    pos = nxt + 1 if following == 0xFF else nxt + 2
                    continue
                pos = nxt
                break
    if frame is None or not scans:
        raise AssetError("JPEG: no frame header or no scan (not an image)")
    _size(*frame, "JPEG")
    return frame[0], frame[1], False
