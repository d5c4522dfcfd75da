"""Reading map files, turning every OS or decoding failure into a one-line PlannerError.

This module and the format loaders next to it are the planner's one sanctioned place for file
I/O: everything after the read is a pure function of the bytes.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from planner.errors import MapFormatError, MapReadError

if TYPE_CHECKING:
    from PIL import Image


def describe(path: str | os.PathLike[str]) -> str:
    return os.fspath(path)


def read_bytes(path: str | os.PathLike[str]) -> bytes:
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise MapReadError(describe(path), "no such map file") from None
    except IsADirectoryError:
        raise MapReadError(describe(path), "is a directory, not a map file") from None
    except OSError as exc:
        raise MapReadError(describe(path), f"cannot read map file ({exc.strerror})") from None


def read_text(path: str | os.PathLike[str]) -> str:
    """The file as UTF-8 text; a bad byte is reported with its line."""
    data = read_bytes(path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise MapFormatError(describe(path), f"not UTF-8 text (byte 0x{data[exc.start]:02x})",
                             line=line) from None


def read_image(path: str | os.PathLike[str]) -> Image.Image:
    """The decoded image (fully loaded, so later errors cannot surface lazily)."""
    # Pillow is imported here, not at the top: every robot, simhw and launcher process
    # imports planner.maps, and only image maps need it (~20 ms of each start-up).
    from PIL import Image, UnidentifiedImageError

    read_bytes(path)  # the same not-found / unreadable messages as for text maps
    try:
        with Image.open(path) as image:
            image.load()
            return image
    except UnidentifiedImageError:
        raise MapFormatError(describe(path), "not an image Pillow can read") from None
    except Image.DecompressionBombError as exc:
        raise MapFormatError(describe(path), f"image too large: {exc}") from None
    except (OSError, SyntaxError, ValueError) as exc:
        # Pillow reports truncated or corrupt image data as one of these.
        raise MapFormatError(describe(path), f"corrupt image: {exc}") from None
