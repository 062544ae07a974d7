"""Benchmark: start-up time of the command line, where users wait.

Measures, in fresh processes started one after the other from this one process and
interleaved (every round runs every command once, so load on the machine hits all alike),
the wall time of

- ``python -c "import pinocchio"`` — the floor of any command that touches a machine;
- ``kinid --help``;
- ``kinid VERB --help`` for every verb of :data:`kinid.cli.VERBS`;
- ``kinid identify`` on the 336-alignment plan (``kinid simulate`` with the default plan),
- ``kinid identify --auto`` on 3 360 alignments (the patent plan ten times over, a 13.3 mm lead of X hidden),

and prints the median of each with two ratios: ``kinid VERB --help`` / ``kinid --help``
(the parser of one verb should cost little more than the list of verbs) and
``kinid identify`` (and ``--auto``) / ``import pinocchio`` (what identify adds to the import it cannot avoid).

Run: ``python benchmarks/bench_startup.py [repeats]`` (default 7).
"""
from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def kinid_command() -> list[str]:
    """The installed ``kinid`` script beside this Python, as users run it; else ``python -m kinid``."""
    script = Path(sys.executable).with_name("kinid")
    if script.exists():
        return [str(script)]
    found = shutil.which("kinid")
    return [found] if found else [sys.executable, "-m", "kinid"]


def wall(cmd, env, cwd) -> float:
    t = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    elapsed = time.perf_counter() - t
    if out.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{out.stderr}")
    return elapsed


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 7
    from kinid.cli import VERBS
    from kinid.urdf import path

    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    kinid = kinid_command()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        urdf = str(path("five_axis_bc"))
        (tmp / "errors.json").write_text('{"EX0C": 12.0, "EA0B": -25.0, "EXX:periodic:10": [1.5, -0.8]}')
        subprocess.run([*kinid, "simulate", "--machine", urdf, "--errors", str(tmp / "errors.json"),
                        "--noise-um", "1", "--out", str(tmp / "obs.csv")], check=True, capture_output=True, env=env)
        rows = len((tmp / "obs.csv").read_text().splitlines()) - 1
        # the plan ten times over (its pose columns), simulated with a lead no library lists: what --auto searches
        lines = (tmp / "obs.csv").read_text().splitlines()
        keep = [i for i, c in enumerate(lines[0].split(",")) if c in ("mark", "wx_mm", "wy_mm", "wz_mm", "b_deg", "c_deg")]
        poses = [",".join(line.split(",")[i] for i in keep) for line in lines]
        (tmp / "plan10.csv").write_text("\n".join([poses[0]] + poses[1:] * 10) + "\n")
        (tmp / "errors10.json").write_text('{"EX0C": 12.0, "EA0B": -25.0, "EXX:periodic:13.3": [1.5, -0.8]}')
        subprocess.run([*kinid, "simulate", "--machine", urdf, "--errors", str(tmp / "errors10.json"), "--plan",
                        str(tmp / "plan10.csv"), "--noise-um", "1", "--out", str(tmp / "obs10.csv")], check=True,
                       capture_output=True, env=env)
        rows10 = len((tmp / "obs10.csv").read_text().splitlines()) - 1
        cases = {"import pinocchio": [sys.executable, "-c", "import pinocchio"],
                 "kinid --help": [*kinid, "--help"]}
        cases.update({f"kinid {verb} --help": [*kinid, verb, "--help"] for verb in VERBS})
        identify = f"kinid identify ({rows} rows)"
        cases[identify] = [*kinid, "identify", "--machine", urdf, "--data", str(tmp / "obs.csv"),
                           "--noise-um", "1", "--out", str(tmp / "fit.json")]
        auto = f"kinid identify --auto ({rows10} rows)"
        cases[auto] = [*kinid, "identify", "--machine", urdf, "--data", str(tmp / "obs10.csv"), "--noise-um", "1",
                       "--auto", "--out", str(tmp / "fit10.json")]
        times = {name: [] for name in cases}
        for _ in range(repeats):
            for name, cmd in cases.items():
                times[name].append(wall(cmd, env, tmp))
    med = {name: statistics.median(t) for name, t in times.items()}
    base, pin = med["kinid --help"], med["import pinocchio"]
    print(f"median wall time of {repeats} fresh processes each, interleaved; kinid = {' '.join(kinid)}")
    print(f"{'command':34s} {'median ms':>10s} {'ratio':>7s}  ratio to")
    for name, m in med.items():
        if name.endswith("--help") and name != "kinid --help":
            ratio, to = f"{m / base:6.2f}x", "kinid --help"
        elif name in (identify, auto):
            ratio, to = f"{m / pin:6.2f}x", "import pinocchio"
        else:
            ratio, to = "", ""
        print(f"{name:34s} {m * 1e3:10.1f} {ratio:>7s}  {to}")
    helps = [med[f"kinid {verb} --help"] / base for verb in VERBS]
    print(f"verb --help / kinid --help: median {statistics.median(helps):.2f}x, worst {max(helps):.2f}x "
          f"({max(VERBS, key=lambda v: med[f'kinid {v} --help'])})")


if __name__ == "__main__":
    main()
