"""Benchmark: ``identify --auto`` (forward selection) on 3 360 alignments, in-process wall time.

The patent plan (336 alignments) measured 10 times with 1 µm noise on the B/C machine, a 13.3 mm lead of X
hidden (a period the library does not list); one BLAS thread. Prints the time of the default fit, of one
diagnosis, and of the whole selection, with what it added. To compare two versions of kinid on this
shared machine, run this file under each alternately (``PYTHONPATH=<other checkout> python …``) and
compare medians.

Run: ``python benchmarks/bench_auto_scale.py [--repeat N]``
"""
import argparse
import statistics
import sys
import time
from pathlib import Path


def main():
    from threadpoolctl import threadpool_limits

    import kinid.identification as ident
    from kinid.identification import diagnose, fit, forward_select

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_diagnose_scale import data_set  # the same 3 360 alignments

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    m, obs, effects = data_set(ident)
    times = {"fit": [], "diagnose": [], "auto": []}
    with threadpool_limits(1):
        for _ in range(args.repeat):
            t = time.perf_counter()
            fit(m, obs, effects, noise_um=1.0)
            times["fit"].append(time.perf_counter() - t)
            t = time.perf_counter()
            diagnose(m, obs, effects, noise_um=1.0)
            times["diagnose"].append(time.perf_counter() - t)
            t = time.perf_counter()
            steps = forward_select(m, obs, effects, noise_um=1.0)
            times["auto"].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"{len(obs)} alignments: fit {med['fit']:.3f} s, diagnose {med['diagnose']:.3f} s "
          f"({med['diagnose'] / med['fit']:.1f} fits), --auto {med['auto']:.3f} s ({med['auto'] / med['fit']:.1f} fits); "
          f"added {[s.added for s in steps[1:]]} (median of {args.repeat})")


if __name__ == "__main__":
    main()
