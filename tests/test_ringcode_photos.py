"""Ring-coded marks in photographs (kinid.vision.render_photo.board_photo): perspective, uneven light, blur, JPEG.

CI-sized version of benchmarks/bench_photo_markers.py: frames of 3000 x 2000 and 4800 x 3200 px (the
candidate search on its scale pyramid), centre circles of 15-45 px diameter.
"""
import numpy as np
import pytest

from kinid.errors import DataError
from kinid.vision.render import similarity_plane_to_image
from kinid.vision.render_photo import board_photo, imaged_circle
from kinid.vision.ringcode import canonical_code, detect_markers


def mirror_code(code, n=12):
    return canonical_code(int(format(int(code), f"0{n}b")[::-1], 2), n)


def score(found, truth, codes=None):
    """(decoded, wrong, counted): marks with the whole ring in the frame and a centre >= 15 px are counted."""
    codes = truth["code"] if codes is None else codes
    counted = truth["inside"] & (truth["d"] >= 15.0)
    ok = np.zeros(len(truth), bool)
    wrong = 0
    for m in found:
        d = np.hypot(truth["x"] - m.x_px, truth["y"] - m.y_px)
        i = int(np.argmin(d))
        if d[i] <= 0.25 * truth["d"][i] and codes[i] == m.code:
            ok[i] = True
        else:
            wrong += 1
    return int(np.count_nonzero(ok & counted)), wrong, int(np.count_nonzero(counted))


@pytest.mark.parametrize("seed,shape,d_range,pitch", [
    (1, (2000, 3000), (15, 24), 3.5),
    (2, (2000, 3000), (22, 45), 3.5),
    # 15 Mpx, small marks: the earlier search (one threshold on a copy shrunk 4 x) decoded 149 of 210
    (4, (3200, 4800), (15, 20), 5.0),
])
def test_photo_of_a_board_decodes_every_mark_and_no_wrong_code(seed, shape, d_range, pitch):
    img, truth = board_photo(shape, d_range, pitch=pitch, blur_px=1.0, rng=np.random.default_rng(seed))
    found = detect_markers(img)
    decoded, wrong, counted = score(found, truth)
    assert counted >= 40
    assert wrong == 0
    assert decoded >= 0.99 * counted
    # the centres are those of the centre circles' image ellipses
    err = [np.hypot(truth["x"] - m.x_px, truth["y"] - m.y_px).min() for m in found]
    assert float(np.sqrt(np.mean(np.square(err)))) < 0.05


def test_mirrored_board_reads_counter_clockwise():
    img, truth = board_photo((1600, 2400), (16, 30), pitch=3.5, blur_px=0.8, mirror=True,
                             rng=np.random.default_rng(3))
    ccw = detect_markers(img, clockwise=False)
    decoded, wrong, counted = score(ccw, truth)
    assert counted >= 40 and wrong == 0 and decoded >= 0.99 * counted
    # read clockwise, the same rings give the bit-mirror codes (different for most codes)
    cw = detect_markers(img)
    decoded_m, wrong_m, _ = score(cw, truth, codes=np.array([mirror_code(c) for c in truth["code"]]))
    assert wrong_m == 0 and decoded_m == decoded
    assert sum(a.code != b.code for a, b in zip(cw, ccw)) > 0.5 * len(cw)
    assert [(a.x_px, a.y_px) for a in cw] == [(b.x_px, b.y_px) for b in ccw]


def test_clockwise_must_be_a_bool():
    with pytest.raises(DataError, match="True or False"):
        detect_markers(np.zeros((50, 50), np.uint8), clockwise="ccw")


def test_imaged_circle_of_a_similarity_is_the_circle():
    H = similarity_plane_to_image(0.2, 30.0, (100.0, 50.0))
    x, y, d = imaged_circle(H, (10.0, 4.0), 2.5)
    p = H @ np.array([10.0, 4.0, 1.0])
    assert (x, y) == pytest.approx((p[0], p[1]), abs=1e-9) and d == pytest.approx(25.0)
