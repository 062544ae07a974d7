"""Benchmark: ``kinid demo`` as a user waits for it, and where its time goes.

Prints the wall and CPU time (user + system of the child process) of

- ``python -c "import pinocchio"`` — the floor of any command that touches a machine;
- ``kinid demo --out DIR`` — the whole command, a fresh process each time;

the medians over ``repeats`` rounds, interleaved (every round runs each once, so load on the machine hits both
alike); then, in one fresh process, the demo's parts, each wall and CPU (``time.process_time``):

- import: the demo's command module and what it imports at the top (NumPy, Pinocchio, the identification floors);
- simulate: the machine, the plan, the simulated alignments and the held-out truth;
- fit: forward selection less its diagnoses — the fits, the gross-error check, the held-out checks;
- diagnose: the diagnoses of forward selection (score test, period search, local errors);
- figures: the report's PNGs (the rest of the report's time: tables, residuals.csv, matplotlib's import);
- HTML: ``index.html`` and the one-file page with its figures inside;
- PDF: ``report.pdf``.

Run: ``python benchmarks/bench_demo.py [repeats]`` (default 3), with ``OPENBLAS_NUM_THREADS=1 MPLBACKEND=Agg``
as a user's shell would have them or not: the script sets both for its child processes.
"""
from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_startup import kinid_command  # noqa: E402 (the installed script, as users run it: one definition)

PARTS = r'''
import sys, time, json
clock = lambda: (time.perf_counter(), time.process_time())
spent = {}
def add(name, t0):
    t1 = clock()
    w, c = spent.get(name, (0.0, 0.0))
    spent[name] = (w + t1[0] - t0[0], c + t1[1] - t0[1])
t0 = clock()
import kinid.identification.commands.demo as demo
add("import", t0)
import kinid.reports.html as html, kinid.reports.pdf as pdf
from kinid.identification.diagnosis import selection

def timed(module, attr, name):
    real = getattr(module, attr)
    def wrapper(*a, **k):
        t = clock()
        try:
            return real(*a, **k)
        finally:
            add(name, t)
    setattr(module, attr, wrapper)

for attr in ("load_machine", "demo_truth", "errors_from_mapping", "patent_plan", "simulate", "_heldout_plan",
             "solve_axes"):
    timed(demo, attr, "simulate")
timed(demo, "forward_select", "_select")
timed(selection, "diagnose", "diagnose")
timed(demo, "selection_report", "_report")
timed(pdf, "write_pdf", "PDF")
timed(html, "report_page", "HTML")
timed(html, "write_one_file", "HTML")
t = clock()
demo.run_demo(sys.argv[1], stream=open("/dev/null", "w"))
add("_total", t)
w, c = spent.pop("_select")
spent["fit"] = (w - spent["diagnose"][0], c - spent["diagnose"][1])
w, c = spent.pop("_report")
spent["figures"] = (w - spent["HTML"][0] - spent["PDF"][0], c - spent["HTML"][1] - spent["PDF"][1])
print(json.dumps(spent))
'''


def run(cmd, env, cwd) -> tuple:
    """Wall and CPU (user + system of the child) seconds of ``cmd``; its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{out.stderr}")
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return wall, cpu, out.stdout


def main() -> None:
    import json

    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    kinid = kinid_command()
    with tempfile.TemporaryDirectory() as tmp:
        cases = {"import pinocchio": [sys.executable, "-c", "import pinocchio"],
                 "kinid demo": [*kinid, "demo", "--out", str(Path(tmp) / "demo")]}
        times = {name: [] for name in cases}
        for _ in range(repeats):
            for name, cmd in cases.items():
                times[name].append(run(cmd, env, tmp)[:2])
        parts = json.loads(run([sys.executable, "-c", PARTS, str(Path(tmp) / "parts")], env, tmp)[2])
    print(f"medians of {repeats} fresh processes each, interleaved; kinid = {' '.join(kinid)}; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'command':22s} {'wall s':>8s} {'CPU s':>8s}")
    for name, t in times.items():
        print(f"{name:22s} {statistics.median(w for w, _ in t):8.2f} {statistics.median(c for _, c in t):8.2f}")
    print("the demo's parts, one process:")
    total = parts.pop("_total")
    for name in ("import", "simulate", "fit", "diagnose", "figures", "HTML", "PDF"):
        w, c = parts.get(name, (0.0, 0.0))
        print(f"  {name:20s} {w:8.2f} {c:8.2f}")
    print(f"  {'run_demo, all':20s} {total[0]:8.2f} {total[1]:8.2f}")


if __name__ == "__main__":
    main()
