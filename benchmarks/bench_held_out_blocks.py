"""How the held-out check's blocks are dealt, measured: a lead of X the B-head's patent plan must add, and noise it
must not add to.

Run: ``python benchmarks/bench_held_out_blocks.py [--deals stratified random ...] [--lead-seeds 6] [--noise-seeds 20]``.

- **lead**: the B-head + C layout (urdf/five_axis_bhead_c.urdf), the patent plan (7 B × 12 C × 4 marks, marks
  innermost), the demo's constant errors and its 12.7 mm lead of X (2.5 µm), σ = 1 µm given: does ``--auto`` add
  ``EXX:periodic:12.7`` (within 1 %)? ``--lead-scale`` sizes the lead (0.25: 0.6 µm, at the edge). Before the blocks were whole poses, each block was one mark, and on two
  seeds of three the lead was refused.
- **noise**: the same, no hidden effect, σ given right: does ``--auto`` add anything?

For each deal of :data:`~kinid.identification.fitting.crossval.DEALS`, prints the leads added, the seeds that added to
noise, and the held-out gains of the lead (standard errors).
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def run(kind: str, seed: int, deal: str, scale: float = 1.0) -> tuple:
    """(what the selection added, the held-out gain of the first candidate in standard errors)."""
    import kinid.identification.fitting.crossval as crossval
    from kinid.identification import forward_select, load_machine
    from kinid.identification.commands.demo import demo_truth
    from kinid.identification.fitting import errors_from_mapping, patent_plan, simulate
    from kinid.identification.model.effects import default_model
    from kinid.urdf import path

    crossval.DEAL = deal
    machine = load_machine(path("five_axis_bhead_c"))
    rng = np.random.default_rng(seed)
    truth = demo_truth(machine, rng, "EXX:periodic:12.7")
    if kind == "noise":
        del truth["EXX:periodic:12.7"]
    else:
        truth["EXX:periodic:12.7"] = [scale * v for v in truth["EXX:periodic:12.7"]]
    effects, theta = errors_from_mapping(truth, machine)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=1.0, rng=rng)
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    cv = steps[0].held_out
    return [s.added for s in steps[1:]], (None if cv is None else cv.gain_se)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--deals", nargs="+", help="default: every deal of DEALS")
    ap.add_argument("--lead-seeds", type=int, default=6)
    ap.add_argument("--noise-seeds", type=int, default=20)
    ap.add_argument("--lead-scale", type=float, default=1.0, help="the lead's size over the demo's 2.5 µm")
    args = ap.parse_args(argv)
    if not args.deals:
        from kinid.identification.fitting.crossval import DEALS

        args.deals = list(DEALS)
    for deal in args.deals:
        t0 = time.perf_counter()
        leads = [run("lead", s, deal, args.lead_scale) for s in range(args.lead_seeds)]
        found = sum(any(a.startswith("EXX:periodic:") and abs(float(a.split(":")[2]) - 12.7) <= 0.127 for a in added)
                    for added, _ in leads)
        noise = [run("noise", s, deal) for s in range(args.noise_seeds)]
        spurious = [(s, added) for s, (added, _) in enumerate(noise) if added]
        print(f"{deal:<11} lead added {found}/{len(leads)}  gains "
              f"{' '.join(f'{g:.1f}' if g is not None else '-' for _, g in leads)}  "
              f"noise: added on {len(spurious)}/{len(noise)} {spurious}  ({time.perf_counter() - t0:.0f} s)",
              flush=True)


if __name__ == "__main__":
    main()
