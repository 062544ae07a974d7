"""The image reader: size from the header before decoding, through the untrusted-file opener."""
from __future__ import annotations

import contextlib
import os

from .untrusted import read_untrusted_bytes, shown_path

#: Largest image kinid decodes, pixels (width × height). A 2048² frame is 4.2 Mpx; a decompression
#: bomb (a small PNG that decodes to 20000²) is refused from its header before any memory is spent.
MAX_IMAGE_PIXELS = 64_000_000
#: Largest image file kinid reads, bytes (checked from ``os.stat`` before reading): 64 Mpx of 16-bit RGBA,
#: uncompressed, is 512 MB.
MAX_IMAGE_BYTES = 1024 * 1024 * 1024


def image_size(data: bytes):
    """(width, height) from the header of a PNG, JPEG, BMP or TIFF file's bytes, else None."""
    import struct

    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24 and data[12:16] == b"IHDR":
        return struct.unpack(">II", data[16:24])
    if data[:2] == b"BM" and len(data) >= 26:
        w, h = struct.unpack("<ii", data[18:26])
        return abs(w), abs(h)
    if data[:4] in (b"II*\x00", b"MM\x00*") and len(data) >= 8:
        return _tiff_size(data)
    if data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    return None


def _tiff_size(data: bytes):
    import struct

    order = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(order + "I", data[4:8])
    if ifd + 2 > len(data):
        return None
    (n,) = struct.unpack(order + "H", data[ifd:ifd + 2])
    size = {}
    for k in range(min(n, 4096)):
        at = ifd + 2 + 12 * k
        if at + 12 > len(data):
            break
        tag, typ = struct.unpack(order + "HH", data[at:at + 4])
        if tag in (256, 257):  # ImageWidth, ImageLength: SHORT or LONG
            fmt = "H" if typ == 3 else "I"
            (size[tag],) = struct.unpack(order + fmt, data[at + 8:at + 8 + struct.calcsize(fmt)])
    return (size[256], size[257]) if 256 in size and 257 in size else None


def _jpeg_size(data: bytes):
    import struct

    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        (length,) = struct.unpack(">H", data[i + 2:i + 4])
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return w, h
        i += 2 + length
    return None


@contextlib.contextmanager
def _native_stderr_quiet():
    """The decoders' own messages (``libpng error: …``, OpenCV's ``[ WARN …]``) kept off the terminal while an
    image is decoded: kinid says what is wrong with the file in one line of its own. They write to file
    descriptor 2 from C, so it is pointed at the null device for the call (and restored whatever happens)."""
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to keep quiet
        yield
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 2)
        finally:
            os.close(null)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def read_image(path, *, max_pixels: int = MAX_IMAGE_PIXELS):
    """Read an image file as a 2-D grey array, 8 or 16 bit as stored.

    The size is read from the file's header and refused above ``max_pixels``
    before anything is decoded. Colour images are converted to grey.

    Raises
    ------
    ImageError
        Naming the file: missing, a folder, empty, too large, or not an image
        OpenCV can decode (PNG, TIFF, BMP, JPEG, ...).
    """
    import numpy as np

    from .errors import ImageError

    data = read_untrusted_bytes(path, what="image file", max_bytes=MAX_IMAGE_BYTES, error=ImageError,
                                missing="image file does not exist")
    if not data:
        raise ImageError("the image file is empty", path=shown_path(path))
    size = image_size(data)
    if size is not None and size[0] * size[1] > max_pixels:
        raise ImageError(f"image of {size[0]} × {size[1]} pixels is larger than the limit of {max_pixels:,} pixels",
                         path=shown_path(path))
    os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(max_pixels))  # OpenCV's own guard, for other formats
    import cv2

    try:
        with _native_stderr_quiet():
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
    except cv2.error as exc:
        reason = str(exc).strip().splitlines()[-1][:200]
        raise ImageError(f"cannot decode the image ({reason})", path=shown_path(path)) from None
    if img is None or img.ndim != 2 or img.size == 0:
        raise ImageError("cannot decode the file as an image (expected PNG, TIFF, BMP, JPEG, ...)",
                         path=shown_path(path))
    return img
