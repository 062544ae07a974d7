"""The structure test's nearest neighbours on a line (sorted, n log n) and in several readings (repeated rows by
their copies, the others pairwise) against the pairwise search (n²)."""
import numpy as np

from kinid.identification.diagnosis.structure import _neighbours


def _pairwise(x):
    x = x[:, None] if x.ndim == 1 else x
    d = np.sum((x[:, None, :] - x[None, :, :]) ** 2, axis=2)
    np.fill_diagonal(d, np.inf)
    return np.argmin(d, axis=1)  # of rows as near, the first


def test_neighbours_in_several_readings_are_the_pairwise_ones():
    """Poses measured again (rows repeated, in any order) beside poses measured once, on a grid where ties occur."""
    rng = np.random.default_rng(2)
    for k in range(300):
        n, axes = int(rng.integers(2, 300)), int(rng.integers(2, 6))
        poses = np.round(rng.uniform(0, 1, (int(rng.integers(1, 200)), axes)), [3, 1][k % 2])
        coords = poses[rng.integers(0, len(poses), n)] if k % 3 else np.round(rng.uniform(0, 1, (n, axes)), 1)
        assert np.array_equal(_neighbours(coords), _pairwise(coords)), coords


def test_neighbours_on_a_line_are_the_pairwise_ones():
    rng = np.random.default_rng(1)
    for k in range(800):
        n = int(rng.integers(2, 80))
        x = [rng.choice([0.0, 1.0, 2.0, 3.0, 5.0, -0.0], n),  # repeated values and ties either side
             rng.normal(size=n),
             np.round(rng.uniform(-3, 3, n), 1),
             rng.choice([0.1, 0.2, 0.3, 0.30000000000000004], n)][k % 4]
        assert np.array_equal(_neighbours(x[:, None]), _pairwise(x)), x


def test_replicas_solved_from_noisy_alignments_are_not_structure(tmp_path):
    """The patent plan measured ten times (`kinid simulate --plan`): the solved readings of a replica carry its
    alignment's noise, so the replicas nearest in the readings were those whose noise agreed (ratio 0.46 on pure
    noise, p = 0.002, said as structure left). Readings within 0.1 % of an axis's range are one position: noise
    is noise again, and the lead the model lacks is still seen."""
    from kinid.cli import main
    from kinid.identification import default_model, fit, load_machine
    from kinid.identification.model.effects import parse_effect
    from kinid.identification.data.observations import read_observations
    from kinid.identification.diagnosis.structure import structure_left
    from kinid.urdf import path

    urdf = str(path("five_axis_bc"))
    (tmp_path / "e.json").write_text('{"EX0C": 12.0}')
    assert main(["simulate", "--machine", urdf, "--errors", str(tmp_path / "e.json"),
                 "--out", str(tmp_path / "o.csv")]) == 0
    lines = (tmp_path / "o.csv").read_text().splitlines()
    keep = [i for i, c in enumerate(lines[0].split(",")) if c in ("mark", "wx_mm", "wy_mm", "wz_mm", "b_deg", "c_deg")]
    poses = [",".join(line.split(",")[i] for i in keep) for line in lines]
    (tmp_path / "plan10.csv").write_text("\n".join([poses[0]] + poses[1:] * 10) + "\n")
    (tmp_path / "e10.json").write_text('{"EX0C": 12.0, "EA0B": -25.0, "EXX:periodic:13.3": [1.5, -0.8]}')
    assert main(["simulate", "--machine", urdf, "--errors", str(tmp_path / "e10.json"), "--plan",
                 str(tmp_path / "plan10.csv"), "--noise-um", "1", "--out", str(tmp_path / "o10.csv")]) == 0
    machine = load_machine(urdf)
    obs = read_observations(tmp_path / "o10.csv", machine)
    names = tuple(a.name for a in machine.axes)
    full = fit(machine, obs, default_model(machine) + [parse_effect("EXX:periodic:13.3", machine)], noise_um=1.0)
    replicas = full.residuals_um.reshape(10, -1, 3).mean(axis=0)
    assert np.sqrt(np.mean(replicas**2)) < 1.2 * np.std(full.residuals_um) / np.sqrt(10)  # the replicas: noise alone
    noise = structure_left(full.residuals_um, obs.axes, obs.t_s, names=names)
    # (the ratio reported is the most extreme look's of twenty and more — each axis, each pair, time — below 1 by that
    # choice alone; the p-value counts the looks)
    assert noise.p_value > 0.05, noise
    lacking = structure_left(fit(machine, obs, default_model(machine), noise_um=1.0).residuals_um, obs.axes, obs.t_s,
                             names=names)
    assert lacking.p_value < 0.01, lacking


def test_the_permutation_null_from_the_gram_matrix_is_the_direct_one():
    """The structure test's null (each permutation's neighbour ratio) from the residuals' Gram matrix equals the
    ratio computed on the permuted residuals themselves, on residuals of any scale, neighbours with repeats."""
    from kinid.identification.diagnosis.structure import _null_ratios, _ratio

    rng = np.random.default_rng(4)
    for k in range(60):
        n = int(rng.integers(12, 400))
        r = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3)
        nn = _neighbours(np.round(rng.uniform(0, 1, (n, 2)), 1))
        perms = np.stack([rng.permutation(n) for _ in range(20)])
        direct = _ratio(r[perms], nn)
        assert np.allclose(_null_ratios(r, perms, nn), direct, rtol=1e-12, atol=1e-14), k
    zero = np.zeros((20, 3))
    assert np.all(_null_ratios(zero, np.stack([rng.permutation(20) for _ in range(5)]), np.arange(20)[::-1]) == 0.0)
