"""The benchmarks' shared data sets are built by today's package layout (a benchmark reaching a module by a string
name is not checked by its imports: bench_diagnose_scale.py's data set looked for the modules' old places)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))


def test_the_diagnosis_scale_data_set_is_built():
    import bench_diagnose_scale

    import kinid.identification as ident

    m, obs, effects = bench_diagnose_scale.data_set(ident)
    assert len(obs) == 3360 and obs.axes.shape == (3360, len(m.axes)) and np.all(np.isfinite(obs.w_mm))
    assert [e.name for e in effects] == [e.name for e in ident.default_model(m)]
