"""Every kinid report, written from the shipped examples into one folder, and a screenshot of each page when
headless Chromium is at hand: what a reviewer looks at before calling a report done.

    python benchmarks/report_gallery.py OUT_DIR [--chromium PATH]

Writes OUT_DIR/<report>/ (index.html, report.html, report.pdf and the figures) for demo, identify, identify
--auto, diagnose, verify, backlash, uvw, dual-axis (each measured and simulated) and contour, the ISO 230-2
plot, a board (SVG and PDF), and OUT_DIR/<report>.png (the whole page at 1200 px wide) for each report page.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
STAGES = EXAMPLES / "stages"
PIXEL_TO_MM = ["0.0049931", "0.0002617", "0.0002617", "-0.0049931"]


def commands(out: Path) -> dict:
    """report name -> kinid arguments (the simulated observations are written first)."""
    from kinid.urdf import path as urdf_path

    machine = str(urdf_path("five_axis_bc"))
    obs, fit = str(out / "obs.csv"), str(out / "fit.json")
    return {
        "obs": ["simulate", "--machine", machine, "--errors", str(EXAMPLES / "errors.json"), "--noise-um", "1",
                "--seed", "4", "--out", obs],
        "demo": ["demo", "--out", str(out / "demo")],
        "identify": ["identify", "--machine", machine, "--data", obs, "--add", "EXX:periodic:10", "EYY:poly3",
                     "--out", fit, "--report", str(out / "identify")],
        "auto": ["identify", "--machine", machine, "--data", obs, "--auto", "--out", str(out / "auto.json"),
                 "--report", str(out / "auto")],
        "diagnose": ["diagnose", "--fit", fit, "--data", obs, "--report", str(out / "diagnose")],
        "verify": ["verify", "--fit", fit, "--data", obs, "--before", obs, "--report", str(out / "verify")],
        "backlash": ["backlash", "--data", str(STAGES / "backlash" / "log.csv"), "--travel-mm", "0.4",
                     "--report", str(out / "backlash")],
        "uvw": ["uvw", "--data", str(STAGES / "uvw_moves.csv"), "--lead-um", "2000", "--report", str(out / "uvw")],
        "uvw-simulated": ["uvw", "--simulate", "--report", str(out / "uvw-simulated")],
        "dual-axis-simulated": ["dual-axis", "--simulate", "--random-errors", "--report",
                                str(out / "dual-axis-simulated")],
        "backlash-simulated": ["backlash", "--simulate", "--repeats", "3", "--report", str(out / "backlash-simulated")],
        "dual-axis": ["dual-axis", "--data", str(STAGES / "dual_axis.csv"), "--pixel-to-mm", *PIXEL_TO_MM,
                      "--report", str(out / "dual-axis")],
        "contour": ["contour", "--simulate", "--sim-frames", "40", "--workers", "1", "--report", str(out / "contour")],
        "iso230-2": ["iso230-2", "--data", str(EXAMPLES / "x_runs.csv"), "--axis", "X", "--plot", str(out / "iso230-2.png"),
                     "--report", str(out / "iso230-2")],
        "board": ["board", "--out", str(out / "board.json"), "--svg", str(out / "board.svg"),
                  "--pdf", str(out / "board.pdf")],
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path, help="folder for the reports and screenshots")
    p.add_argument("--chromium", default=shutil.which("chromium") or shutil.which("chromium-browser"),
                   help="headless Chromium for the screenshots (default: from PATH; none: no screenshots)")
    a = p.parse_args(argv)
    from kinid.cli import main as kinid

    a.out.mkdir(parents=True, exist_ok=True)
    for name, args in commands(a.out).items():
        status = kinid(args)
        print(f"{name:10} exit {status}", flush=True)
        page = a.out / name / "index.html"
        if status == 0 and page.is_file() and a.chromium:
            subprocess.run([a.chromium, "--headless", "--no-sandbox", "--hide-scrollbars", "--window-size=1200,9000",
                            f"--screenshot={a.out / name}.png", page.as_uri()], capture_output=True, timeout=120)
            print(f"{'':10} screenshot {a.out / name}.png", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
