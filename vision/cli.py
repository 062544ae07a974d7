"""``kinid markers``: detect and decode ring-coded marks in an image (docs/hardware.md)."""
from __future__ import annotations

from pathlib import Path

from kinid.errors import DataError, ImageError

__all__ = ["register"]


def draw_markers(image, markers):
    """A BGR copy of ``image`` with each marker's centre circle, ring outline and code drawn."""
    import cv2
    import numpy as np

    img = np.asarray(image)
    out = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img.copy()
    S = 16
    thick = max(1, int(round(max(img.shape[:2]) / 800)))
    for m in markers:
        c = (int(round(m.x_px * S)), int(round(m.y_px * S)))
        cv2.circle(out, c, int(round(m.radius_px * S)), (0, 200, 0), thick, cv2.LINE_AA, 4)
        cv2.circle(out, c, int(round(2.6 * m.radius_px * S)), (0, 140, 255), thick, cv2.LINE_AA, 4)
        cv2.drawMarker(out, (int(round(m.x_px)), int(round(m.y_px))), (0, 0, 255), cv2.MARKER_CROSS,
                       max(5, int(m.radius_px)), thick)
        scale = max(0.4, m.radius_px / 25.0)
        org = (int(round(m.x_px + 1.9 * m.radius_px)), int(round(m.y_px - 2.0 * m.radius_px)))
        cv2.putText(out, str(m.code), org, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 0, 255), thick, cv2.LINE_AA)
    return out


def _run(args) -> int:
    import cv2

    from kinid.files import atomic_write

    from .ringcode import detect_markers

    if not 3 <= args.bits <= 30:
        raise DataError(f"--bits must be in 3..30, got {args.bits}", column="--bits")
    from kinid.files import read_image

    img = read_image(args.image)
    markers = detect_markers(img, bits=args.bits, polarity=args.polarity)
    if args.draw:
        ext = Path(args.draw).suffix.lower() or ".png"
        ok, buf = cv2.imencode(ext if ext in (".png", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg") else ".png",
                               draw_markers(img, markers))
        if not ok:  # pragma: no cover - encoder failure
            raise ImageError("cannot encode the drawing", path=args.draw)
        with atomic_write(args.draw, "wb") as f:
            f.write(buf.tobytes())
    if args.json:
        from kinid.files import strict_json

        print(strict_json([{"code": m.code, "x_px": m.x_px, "y_px": m.y_px} for m in markers]))
    else:
        print(f"{len(markers)} mark(s) decoded in {args.image}")
        if markers:
            print(f"{'code':>6} {'x_px':>11} {'y_px':>11} {'radius_px':>10}  bits")
            for m in markers:
                print(f"{m.code:>6d} {m.x_px:>11.4f} {m.y_px:>11.4f} {m.radius_px:>10.3f}  {m.bits}")
    return 0


def register(subparsers) -> None:
    """Add the ``markers`` verb."""
    p = subparsers.add_parser("markers", help="detect and decode ring-coded marks in an image",
                              description="Detect ring-coded marks (the monocular contour method) and print each decoded mark's code "
                                          "and the sub-pixel centre of its centre circle (pixels, x right, y down, "
                                          "top-left pixel centre at (0, 0)).")
    p.add_argument("image", metavar="IMAGE", help="image file (PNG, TIFF, BMP, JPEG)")
    p.add_argument("--bits", type=int, default=12, help="ring elements per mark (default 12)")
    p.add_argument("--polarity", choices=("auto", "dark", "light"), default="auto",
                   help="dark marks on light, light on dark, or auto (default)")
    p.add_argument("--json", action="store_true", help='print [{"code": int, "x_px": float, "y_px": float}, ...]')
    p.add_argument("--draw", metavar="OUT.png", help="write the image with the detections drawn")
    p.set_defaults(run=_run)
