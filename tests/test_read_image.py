"""kinid.files.read_image: the one image reader; sizes checked from the header before decoding."""
import struct
import zlib

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import ImageError, KinidError
from kinid.files import image_size, read_image


def _png_header_only(width, height):
    """A PNG whose IHDR claims ``width`` × ``height`` and whose data is one compressed empty row."""
    def chunk(kind, payload):
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


@pytest.mark.parametrize("ext", [".png", ".tif", ".bmp", ".jpg"])
def test_header_sizes_match_opencv(tmp_path, ext):
    img = (np.arange(37 * 53) % 251).astype(np.uint8).reshape(37, 53)
    f = tmp_path / f"a{ext}"
    cv2.imwrite(str(f), img)
    assert image_size(f.read_bytes()) == (53, 37)
    assert read_image(f).shape == (37, 53)


def test_sixteen_bit_is_kept(tmp_path):
    img = (np.arange(20 * 30) * 97 % 65535).astype(np.uint16).reshape(20, 30)
    f = tmp_path / "deep.png"
    cv2.imwrite(str(f), img)
    out = read_image(f)
    assert out.dtype == np.uint16 and np.array_equal(out, img)


def test_colour_becomes_grey(tmp_path):
    f = tmp_path / "c.png"
    cv2.imwrite(str(f), np.full((5, 6, 3), 100, np.uint8))
    out = read_image(f)
    assert out.shape == (5, 6) and out.dtype == np.uint8


@pytest.mark.parametrize("size", [(20000, 20000), (100000, 100000)])
def test_huge_header_is_refused_before_decoding(tmp_path, size):
    f = tmp_path / "bomb.png"
    f.write_bytes(_png_header_only(*size))
    with pytest.raises(ImageError, match=rf"bomb.png: image of {size[0]} × {size[1]} pixels is larger than the limit"):
        read_image(f)


@pytest.mark.parametrize("content, match", [
    (None, "image file does not exist"),
    (b"", "the image file is empty"),
    (b"not an image at all", "cannot decode the file as an image"),
    ("folder", "is a folder"),
])
def test_bad_files_name_the_file(tmp_path, content, match):
    f = tmp_path / "x.png"
    if content == "folder":
        f.mkdir()
    elif content is not None:
        f.write_bytes(content)
    with pytest.raises(ImageError, match=match) as info:
        read_image(f)
    assert str(f) in str(info.value)


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=300))
def test_any_bytes_give_an_image_or_an_image_error(tmp_path_factory, data):
    f = tmp_path_factory.mktemp("fuzz") / "f.png"
    f.write_bytes(b"\x89PNG\r\n\x1a\n" + data)
    try:
        img = read_image(f)
    except KinidError:
        return
    assert img.ndim == 2


def test_a_truncated_png_gives_kinid_s_line_only(tmp_path):
    """The decoder's own complaint (libpng's ``PNG input buffer is incomplete``, OpenCV's ``[ WARN ...]``) does not
    reach the terminal: stderr is kinid's one line naming the file."""
    import subprocess
    import sys

    import cv2
    import numpy as np

    cv2.imwrite(str(tmp_path / "full.png"), (np.random.default_rng(0).random((120, 120)) * 255).astype(np.uint8))
    data = (tmp_path / "full.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    r = subprocess.run([sys.executable, "-m", "kinid", "markers", "cut.png"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.splitlines() == ["kinid markers: cut.png: cannot decode the file as an image (expected PNG, TIFF, "
                                     "BMP, JPEG, ...)"], r.stderr
