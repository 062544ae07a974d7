"""Benchmark: ``diagnose`` and ``identify --auto`` against one fit, on 3 360 alignments, in-process wall time.

The data set of ``bench_auto_scale.py``: the patent plan (336 alignments) measured 10 times with 1 µm noise
on the B/C machine, a 13.3 mm lead of X hidden (a period the library does not list); one BLAS thread.
Prints the median time of one fit of the default model, one diagnosis and one forward selection, and
their ratios to the fit (the issue's yardstick: diagnose ≤ 5 fits, --auto ≤ 15 fits).

``--against DIR`` times another version of ``identification/`` (a folder, for instance one written by
``git archive HEAD identification | tar -x -C DIR``) in the same process, alternating with this one, each
on its own data (the same numbers), so that the load of a shared machine falls on both alike.
``--profile`` prints the cProfile of one diagnosis instead (cumulative and own time).

Run: ``python benchmarks/bench_diagnose_scale.py [--repeat N] [--against DIR] [--auto/--no-auto] [--profile]``
"""
import argparse
import importlib
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def data_set(ident):
    """(machine, observations, default model) of the benchmark, built by the package ``ident``."""
    from kinid.urdf import path

    m = ident.load_machine(path("five_axis_bc"))
    effects = ident.default_model(m)
    rng = np.random.default_rng(5)
    theta = rng.normal(0, 15.0, sum(e.n_params for e in effects))
    Observations = importlib.import_module(ident.__name__ + ".data.observations").Observations
    base = importlib.import_module(ident.__name__ + ".fitting.simulate").patent_plan(m)
    plan = Observations(base.marks * 10, np.tile(base.w_mm, (10, 1)), np.tile(base.axes, (10, 1)))
    obs = ident.simulate(m, plan, effects, theta, noise_um=1.0, rng=rng)
    # the lead: the reading that put the tool on the mark is the one with x + e(x) = the aligned position
    k = m.axis_names.index("X")
    x0 = obs.axes[:, k].copy()
    x = x0.copy()
    for _ in range(30):
        x = x0 - 2.5e-3 * np.sin(2 * np.pi * x / 13.3 + 0.7)
    axes = obs.axes.copy()
    axes[:, k] = x
    return m, Observations(obs.marks, obs.w_mm, axes, obs.t_s, obs.directions, obs.lines, "<bench>"), effects


def other_version(folder: str):
    """The ``identification`` package in ``folder`` imported as ``kinid_other.identification``."""
    root = Path(tempfile.mkdtemp(prefix="kinid_other_"))
    (root / "kinid_other").mkdir()
    (root / "kinid_other" / "__init__.py").write_text("")
    shutil.copytree(Path(folder) / "identification" if (Path(folder) / "identification").is_dir() else folder,
                    root / "kinid_other" / "identification")
    sys.path.insert(0, str(root))
    return importlib.import_module("kinid_other.identification")


def timings(ident, data, auto: bool) -> dict:
    m, obs, effects = data
    out = {}
    t = time.perf_counter()
    ident.fit(m, obs, effects, noise_um=1.0)
    out["fit"] = time.perf_counter() - t
    t = time.perf_counter()
    ident.diagnose(m, obs, effects, noise_um=1.0)
    out["diagnose"] = time.perf_counter() - t
    if auto:
        t = time.perf_counter()
        ident.forward_select(m, obs, effects, noise_um=1.0)
        out["auto"] = time.perf_counter() - t
    return out


def line(label, runs) -> str:
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    text = f"{label:<8} fit {med['fit']:.3f} s, diagnose {med['diagnose']:.3f} s ({med['diagnose'] / med['fit']:.1f} fits)"
    if "auto" in med:
        text += f", --auto {med['auto']:.3f} s ({med['auto'] / med['fit']:.1f} fits)"
    return text


def main():
    from threadpoolctl import threadpool_limits

    import kinid.identification as this

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--against", default=None, help="folder holding another version's identification/ package")
    ap.add_argument("--auto", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    versions = {"this": this}
    if args.against:
        versions["other"] = other_version(args.against)
    data = {k: data_set(v) for k, v in versions.items()}
    with threadpool_limits(1):
        if args.profile:
            import cProfile
            import pstats

            m, obs, effects = data["this"]
            this.diagnose(m, obs, effects, noise_um=1.0)  # warm
            prof = cProfile.Profile()
            prof.runcall(this.diagnose, m, obs, effects, noise_um=1.0)
            for key in ("cumulative", "tottime"):
                pstats.Stats(prof).sort_stats(key).print_stats(30)
            return
        runs = {k: [] for k in versions}
        for _ in range(args.repeat):
            for k, v in versions.items():
                runs[k].append(timings(v, data[k], args.auto))
    print(f"{len(data['this'][1])} alignments, median of {args.repeat} (alternating in one process):")
    for k in versions:
        print(line(k, runs[k]))


if __name__ == "__main__":
    main()
