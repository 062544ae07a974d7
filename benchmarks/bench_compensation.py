"""How much of the identified error each controller file leaves, as the controller applies it (prints figures).

Run: ``python benchmarks/bench_compensation.py`` (a few seconds).

The README's five-axis example: ``examples/errors.json`` (a 10 mm lead of X among location errors) on
the patent plan with 1 µm noise, fitted with ``EXX:periodic:10``, compensated by ``kinid compensate``
with every registered controller format, once with the tables over the measured readings (the
default) and once over the URDF travel (``--table-range travel``). Each file is read back as its controller
reads it (tests/controller_consumers.py: its units, signs, point rules, modulo and held ends) and its
interpolation compared with the fitted model inside the measured range.

Printed per file: points, the identified error's RMS, what the controller leaves of it (RMS and
largest) and the share; the bound kinid aims at is 10 % of the error's RMS (or the format's
resolution).
"""
from __future__ import annotations

import io
import json
import sys
import tempfile
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from controller_consumers import READERS  # noqa: E402

from kinid.axis_tables import CONTROLLER_FORMATS  # noqa: E402
from kinid.cli import main as kinid  # noqa: E402
from kinid.identification import fit, load_machine, save_fit  # noqa: E402
from kinid.identification.compensation.compensate import positioning_table  # noqa: E402
from kinid.identification.fitting.fit import model_effects  # noqa: E402
from kinid.identification.fitting.simulate import errors_from_mapping, load_plan, simulate  # noqa: E402
from kinid.urdf import path  # noqa: E402


def main(seed: int = 0):
    folder = Path(tempfile.mkdtemp())
    m = load_machine(path("five_axis_bc"))
    effects, theta = errors_from_mapping(json.loads((ROOT / "examples" / "errors.json").read_text()), m)
    obs = simulate(m, load_plan("patent", m), effects, theta, noise_um=1.0, rng=np.random.default_rng(seed))
    result = fit(m, obs, model_effects(m, ["EXX:periodic:10"]), noise_um=1.0)
    save_fit(result, folder / "fit.json")
    print("README example: examples/errors.json, patent plan (336 alignments), σ 1 µm, fitted with EXX:periodic:10")
    print(f"{'range':<7} {'file':<16} {'points':>6} {'error RMS':>10} {'left RMS':>9} {'left max':>9} {'share':>6}")
    for policy in ("data", "travel"):
        out = folder / policy
        with redirect_stdout(io.StringIO()):
            kinid(["compensate", "--fit", str(folder / "fit.json"), "--out", str(out), "--table-range", policy,
                   "--format", *sorted(CONTROLLER_FORMATS)])
        info = json.loads((out / "compensation.json").read_text())
        for e in info["controller_files"]:
            fmt = CONTROLLER_FORMATS[e["format"]]
            rotary = e["unit"] == "µrad"
            lo, hi = result.axis_ranges[e["axis"]]
            x = np.linspace(lo, hi, 4001)
            model = positioning_table(result, e["axis"], x)
            reads = READERS[e["format"]]((out / e["file"]).read_text(), rotary)
            to_model = (lambda v: np.radians(v) * 1e6) if rotary else (lambda v: v * 1e3)
            if fmt.bidirectional:
                left = np.concatenate([to_model(reads(x, True)) - model.forward,
                                       to_model(reads(x, False)) - model.backward])
                err = np.concatenate([model.forward, model.backward])
            else:
                err = 0.5 * (model.forward + model.backward)
                left = to_model(reads(x)) - err
            rms_e, rms_l = np.sqrt(np.mean(err ** 2)), np.sqrt(np.mean(left ** 2))
            print(f"{policy:<7} {e['file']:<16} {e['points']:>6} {rms_e:8.3f} {e['unit']:<2}"
                  f"{rms_l:8.3f} {np.abs(left).max():9.3f} {rms_l / rms_e:6.1%}")


if __name__ == "__main__":
    main()
