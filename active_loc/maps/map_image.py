"""The image of a ROS map file, read and classified as nav2's map_server reads it.

PGM images (P5 binary and P2 ASCII, 8 or 16 bit) are parsed here, exactly; every other format
map_server reads (PNG, BMP, JPEG, and the rest Pillow knows) goes through Pillow. An image
becomes integer ``pixels`` with a ``maxval``, so that occupancy probabilities are exact ratios
of integers and threshold ties are reproducible:

- gray: the pixel value, ``maxval`` 255 or 65535 (or the PGM's own maxval);
- color: map_server's channel rule, the mean of red, green and blue, kept as their sum with
  ``maxval = 3 * 255``;
- alpha: a pixel below full opacity is UNKNOWN (in every mode).

:meth:`~active_loc.maps.occupancy.OccupancyGrid.load` turns them into the grid's three cell
classes.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

#: the largest image file read (bytes) and the most pixels an image may hold: about 10 000 x
#: 10 000 cells, far above any building map, and refused before the pixels are decoded
MAX_IMAGE_BYTES = 2**30
MAX_IMAGE_PIXELS = 10**8

_WHITESPACE = b" \t\r\n\v\f"


class MapFileError(ValueError):
    """A map file (YAML or image) that cannot be read; the message names the file."""


class MapFileNotFoundError(MapFileError, FileNotFoundError):
    """A map file that does not exist; both a :class:`ValueError` and a FileNotFoundError."""


@dataclass(frozen=True)
class MapImage:
    """An image as integers.

    Attributes:
        pixels: ``(height, width)`` int64 brightness in ``[0, maxval]``, row 0 the top.
        maxval: the brightness of white.
        opaque: ``(height, width)`` bool, False where alpha is below full opacity; None when
            the image has no alpha.
    """

    pixels: NDArray[np.int64]
    maxval: int
    opaque: NDArray[np.bool_] | None = None


def read_file_bytes(path: Path, limit: int) -> bytes:
    """The bytes of the regular file ``path``, refused when it is larger than ``limit``
    (a device such as ``/dev/zero`` or a FIFO is refused before reading)."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise MapFileNotFoundError(f"{path}: no such file") from None
    except OSError as err:
        raise MapFileError(f"{path}: cannot read: {err.strerror or err}") from None
    if not stat.S_ISREG(info.st_mode):
        raise MapFileError(f"{path}: not a regular file")
    if info.st_size > limit:
        raise MapFileError(f"{path}: {info.st_size} bytes, larger than the limit of {limit}")
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
    except OSError as err:
        raise MapFileError(f"{path}: cannot read: {err.strerror or err}") from None
    if len(data) > limit:
        raise MapFileError(f"{path}: larger than the limit of {limit} bytes")
    return data


def read_map_image(path: Path, yaml_path: Path) -> MapImage:
    """The image ``path`` named by the map YAML ``yaml_path``: a PGM parsed exactly, any
    other format through Pillow."""
    try:
        data = read_file_bytes(path, MAX_IMAGE_BYTES)
    except MapFileNotFoundError:
        raise MapFileNotFoundError(
            f"{path}: no such file (the image named by {yaml_path})"
        ) from None
    if data[:2] in (b"P5", b"P2"):
        pixels, maxval = _read_pgm(data, path)
        return MapImage(pixels, maxval)
    return _read_with_pillow(data, path)


def _check_size(width: int, height: int, path: Path) -> None:
    if width == 0 or height == 0:
        raise MapFileError(f"{path}: image size {width} x {height} is empty")
    if width * height > MAX_IMAGE_PIXELS:
        raise MapFileError(
            f"{path}: image size {width} x {height} exceeds the limit of {MAX_IMAGE_PIXELS} "
            "pixels"
        )


def _read_with_pillow(data: bytes, path: Path) -> MapImage:
    import io

    from PIL import Image, UnidentifiedImageError

    try:
        img = Image.open(io.BytesIO(data))  # lazy: reads the header only
    except UnidentifiedImageError:
        raise MapFileError(
            f"{path}: not an image map_server reads (PGM, PNG, BMP, JPEG, ...): starts with "
            f"{data[:8]!r}"
        ) from None
    _check_size(img.width, img.height, path)
    try:
        if img.mode == "P":  # palette: its colors, and its transparency when it has one
            img = img.convert("RGBA" if "transparency" in img.info else "RGB")
        elif img.mode in ("1", "CMYK", "YCbCr", "LAB", "HSV"):
            img = img.convert("RGB" if img.mode != "1" else "L")
        elif img.mode == "PA":
            img = img.convert("RGBA")
        array = np.asarray(img)
    except (OSError, ValueError) as err:
        raise MapFileError(f"{path}: cannot decode the image: {err}") from None
    mode = img.mode
    if mode in ("L", "LA"):
        gray = array if mode == "L" else array[..., 0]
        opaque = None if mode == "L" else array[..., 1] == 255
        return MapImage(gray.astype(np.int64), 255, opaque)
    if mode in ("RGB", "RGBA"):
        rgb = array[..., :3].astype(np.int64).sum(axis=-1)
        opaque = None if mode == "RGB" else array[..., 3] == 255
        return MapImage(rgb, 3 * 255, opaque)
    if mode.startswith("I;16") or mode == "I":  # 16-bit gray (PNG opens as "I" or "I;16")
        gray = array.astype(np.int64)
        if gray.min() < 0 or gray.max() > 65535:
            raise MapFileError(f"{path}: 32-bit integer images are not map images")
        return MapImage(gray, 65535)
    raise MapFileError(f"{path}: image mode {mode!r} is not a gray or color map image")


def _read_pgm(data: bytes, path: Path) -> tuple[NDArray[np.int64], int]:
    """Pixels ``(height, width)`` and maxval of a P5 or P2 PGM with maxval <= 65535 (two
    big-endian bytes per binary sample above 255, as netpbm writes them)."""
    magic = data[:2]
    if len(data) < 3 or data[2:3] not in (*(bytes([b]) for b in _WHITESPACE), b"#"):
        raise MapFileError(f"{path}: bad PGM header: no whitespace after {magic!r}")
    pos = 2
    numbers: list[int] = []
    names = ("width", "height", "maxval")
    while len(numbers) < 3:
        pos = _skip_space_and_comments(data, pos)
        if pos >= len(data):
            raise MapFileError(f"{path}: truncated PGM header: {names[len(numbers)]} is missing")
        start = pos
        while pos < len(data) and data[pos] not in _WHITESPACE and data[pos] != ord("#"):
            pos += 1
        token = data[start:pos]
        if not token.isdigit() or len(token) > 9:
            raise MapFileError(
                f"{path}: bad PGM header: {names[len(numbers)]} is {token[:20]!r}, not a "
                f"positive integer"
            )
        numbers.append(int(token))
    width, height, maxval = numbers
    _check_size(width, height, path)
    if not 1 <= maxval <= 65535:
        raise MapFileError(f"{path}: PGM maxval {maxval} is not in 1..65535")
    count = width * height
    if magic == b"P5":
        # exactly one whitespace character separates maxval from the raster (a comment may
        # sit there too, which the netpbm spec allows)
        if pos >= len(data):
            raise MapFileError(f"{path}: truncated PGM: no pixel data after the header")
        if data[pos] == ord("#"):
            newline = data.find(b"\n", pos)
            pos = len(data) if newline < 0 else newline + 1
        else:
            pos += 1
        sample = 1 if maxval <= 255 else 2
        available = (len(data) - pos) // sample
        if available < count:
            raise MapFileError(
                f"{path}: truncated PGM: {width} x {height} needs {count * sample} bytes of "
                f"pixel data, found {len(data) - pos}"
            )
        dtype = np.uint8 if sample == 1 else np.dtype(">u2")
        pixels = np.frombuffer(data, dtype=dtype, count=count, offset=pos).astype(np.int64)
    else:
        text = re.sub(rb"#[^\n]*", b" ", data[pos:])
        tokens = text.split()
        if len(tokens) < count:
            raise MapFileError(
                f"{path}: truncated PGM: {width} x {height} needs {count} pixel values, "
                f"found {len(tokens)}"
            )
        if not all(t.isdigit() and len(t) <= 9 for t in tokens[:count]):
            raise MapFileError(f"{path}: bad PGM pixel data: values must be integers")
        pixels = np.array([int(t) for t in tokens[:count]], dtype=np.int64)
    if pixels.max() > maxval:
        raise MapFileError(f"{path}: bad PGM: pixel value {pixels.max()} exceeds maxval {maxval}")
    return pixels.reshape(height, width), maxval


def _skip_space_and_comments(data: bytes, pos: int) -> int:
    while pos < len(data):
        if data[pos] in _WHITESPACE:
            pos += 1
        elif data[pos] == ord("#"):
            newline = data.find(b"\n", pos)
            pos = len(data) if newline < 0 else newline + 1
        else:
            break
    return pos
