"""``kinid board``: a printable ring-coded board (SVG, PDF, true scale) and its board file."""
from __future__ import annotations

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "board", help="a printable ring-coded board (SVG and PDF at true scale) and its board file",
        description="Write a board of ring-coded marks: its board file (JSON, what kinid contour and kinid "
                    "observe read) and a drawing to print at 100 %: SVG and/or PDF in millimetres on a standard paper "
                    "size, with scale bars in both directions and the board's identifier.")
    p.add_argument("--out", required=True, metavar="BOARD.json", help="board file to write")
    p.add_argument("--svg", metavar="BOARD.svg", help="the drawing as SVG (width and height in mm)")
    p.add_argument("--pdf", metavar="BOARD.pdf", help="the drawing as PDF")
    p.add_argument("--page", default="auto", help="paper: auto (the first of a4, letter, a3, tabloid, a2, a1, a0 the "
                                                  "board fits, either way round; default), one of them, or fit (the "
                                                  "board's own size)")
    p.add_argument("--rows", type=int, default=14, help="rows of marks (default 14)")
    p.add_argument("--cols", type=int, default=14, help="columns of marks (default 14)")
    p.add_argument("--pitch-mm", type=float, default=16.0, help="distance between neighbouring marks, mm (default 16)")
    p.add_argument("--bits", type=int, default=12, help="ring elements per mark (default 12)")
    p.add_argument("--center-d-mm", type=float, default=5.0, help="diameter of the centre circle, mm (default 5)")
    p.add_argument("--ring-inner-d-mm", type=float, default=9.0, help="inner diameter of the ring, mm (default 9)")
    p.add_argument("--ring-outer-d-mm", type=float, default=13.0, help="outer diameter of the ring, mm (default 13)")
    p.set_defaults(run=_run, outputs={"out": "file", "svg": "file", "pdf": "file"},
                   parameter_options={"rows": "--rows", "cols": "--cols", "pitch_mm": "--pitch-mm", "bits": "--bits",
                                      "center_d_mm": "--center-d-mm", "ring_inner_d_mm": "--ring-inner-d-mm",
                                      "ring_outer_d_mm": "--ring-outer-d-mm", "page": "--page"})


def _run(args) -> int:
    from kinid.errors import DataError
    from kinid.files import write_together
    from .board import board_text, make_board
    from .board_print import board_id, board_layout, board_pdf, board_svg

    if not 3 <= args.bits <= 30:
        raise DataError(f"--bits must be in 3..30, got {args.bits}")
    if args.rows * args.cols > 10000:
        raise DataError(f"a board of {args.rows} x {args.cols} marks is larger than kinid draws (10 000 marks)")
    if not args.ring_outer_d_mm < args.pitch_mm:
        raise DataError(f"--ring-outer-d-mm ({args.ring_outer_d_mm:g}) must be smaller than --pitch-mm "
                        f"({args.pitch_mm:g}): the marks would overlap")
    if not 0 < args.center_d_mm < args.ring_inner_d_mm < args.ring_outer_d_mm:
        raise DataError("the diameters must grow: 0 < --center-d-mm < --ring-inner-d-mm < --ring-outer-d-mm")
    board = make_board(args.rows, args.cols, args.pitch_mm, args.bits, args.center_d_mm, args.ring_inner_d_mm,
                       args.ring_outer_d_mm)
    lay = board_layout(board, args.page)  # a page kinid cannot draw is refused here, before any file is written
    contents = {args.out: board_text(board)}  # the board file and its drawings are one unit: all or none
    if args.svg:
        contents[args.svg] = board_svg(board, args.page)
    if args.pdf:
        contents[args.pdf] = board_pdf(board, args.page)
    write_together(contents)
    written = list(contents)
    paper = f"{lay.page} " if lay.page != "fit" else ""
    print(f"board {board_id(board)} of {board.rows} x {board.cols} marks, pitch {board.pitch_mm:g} mm, {paper}page "
          f"{lay.width_mm:.1f} x {lay.height_mm:.1f} mm; written: {', '.join(written)}")
    if args.svg or args.pdf:
        print(f"print at 100 % (no scaling) and check both scale bars ({lay.scale_bar_mm:g} mm across, "
              f"{lay.vertical_bar_mm:g} mm down) with a ruler")
    return 0
