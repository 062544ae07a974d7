"""A size no machine has within its own uncertainty is a plan that hardly determines the error, not
inconsistent observations: the warning says which, and points to the remedy that fits.

On the B-head + C table the patent plan barely tells EA0Z from EY0C: their standard deviations are of
35 000 µrad and 350 µm with 0.8 µm noise. The machine simulated has two small location errors only, so
every size flagged is the plan's weak direction, never the machine.
"""
from __future__ import annotations

import json

from kinid.cli import main
from kinid.urdf import path as urdf_path


def test_weakly_determined_error_is_not_called_inconsistent_observations(tmp_path, capsys):
    machine = str(urdf_path("five_axis_bhead_c"))
    (tmp_path / "errors.json").write_text(json.dumps({"EX0C": 8.0, "EA0C": 25.0}))
    assert main(["simulate", "--machine", machine, "--errors", str(tmp_path / "errors.json"), "--noise-um", "0.8",
                 "--seed", "1", "--out", str(tmp_path / "obs.csv")]) == 0
    capsys.readouterr()
    assert main(["identify", "--machine", machine, "--data", str(tmp_path / "obs.csv"),
                 "--out", str(tmp_path / "fit.json")]) == 0
    out = capsys.readouterr().out
    fit = json.loads((tmp_path / "fit.json").read_text())
    flagged = {a["effect"]: a for a in fit["implausible"]}
    assert flagged, "the plan should leave a location error free to take a size no machine has"
    params = {p["name"]: p for p in fit["parameters"]}
    for name, a in flagged.items():
        p = params[name]
        alone = 2 * p["std"] >= min(abs(p["value"]), a["limit"])  # the rule for one constant
        assert a["undetermined"] or not alone
        assert a["undetermined"], f"{name} = {p['value']} ± {p['std']}: only errors of the plan's weak direction"
    assert "the observations look inconsistent" not in out
    assert "not determined by these data" in out and "--prior" in out
    # the remedy named works: with the prior no size is flagged
    assert main(["identify", "--machine", machine, "--data", str(tmp_path / "obs.csv"), "--prior", "--no-check",
                 "--out", str(tmp_path / "fit_prior.json")]) == 0
    assert json.loads((tmp_path / "fit_prior.json").read_text())["implausible"] == []
    capsys.readouterr()
    assert main(["diagnose", "--fit", str(tmp_path / "fit.json"), "--data", str(tmp_path / "obs.csv")]) == 0
    out = capsys.readouterr().out
    assert "errors the plan hardly determines" in out and "look inconsistent" not in out


def test_a_weak_direction_pushed_by_a_missing_effect_is_undetermined_too(tmp_path, capsys):
    """The same table and plan with a lead of Y the 6 positions of Y cannot pin: the lead's misfit pushes EA0Z to
    −1.3e5 ± 4e4 µrad, 3 standard deviations from zero, but its uncertainty alone (U = 8e4 µrad) is beyond any
    machine's size: the plan cannot bound it, and the warning says so rather than blaming the observations — for
    EA0Z and for EY0C, which the weak direction drags to 1 270 µm."""
    machine = str(urdf_path("five_axis_bhead_c"))
    (tmp_path / "errors.json").write_text(json.dumps({"EX0C": 8.0, "EA0C": 25.0, "EYY:periodic:7.3": [1.5, -0.8]}))
    assert main(["simulate", "--machine", machine, "--errors", str(tmp_path / "errors.json"), "--noise-um", "0.8",
                 "--seed", "3", "--out", str(tmp_path / "obs.csv")]) == 0
    assert main(["identify", "--machine", machine, "--data", str(tmp_path / "obs.csv"),
                 "--out", str(tmp_path / "fit.json")]) == 0
    out = capsys.readouterr().out
    fit = json.loads((tmp_path / "fit.json").read_text())
    flagged = {a["effect"]: a for a in fit["implausible"]}
    params = {p["name"]: p for p in fit["parameters"]}
    ea0z = params["EA0Z"]
    assert abs(ea0z["value"]) > 2 * ea0z["std"] and 2 * ea0z["std"] >= flagged["EA0Z"]["limit"]
    assert flagged["EA0Z"]["undetermined"] and "its uncertainty alone reaches sizes no machine has" in out
    # EY0C, its partner in that direction, is dragged along: 1 270 µm is 3.2 U from zero on its own, but the part
    # of it the plan determines (what is left when the direction EA0Z spans is taken out) is within the limit
    ey0c = params["EY0C"]
    assert abs(ey0c["value"]) > 1000 and 2 * ey0c["std"] < abs(ey0c["value"]) and 2 * ey0c["std"] < 1000
    assert flagged["EY0C"]["undetermined"], "the partner of the weak direction was called inconsistent"
    assert "shared with EA0Z" in out and "look inconsistent" not in out
    # the report's summary does not name them among the clearest errors (EY0C is 3.2 σ from zero)
    from kinid.identification.fitting.fit_file import load_fit
    from kinid.identification.reporting.report import _largest

    clearest = _largest(load_fit(tmp_path / "fit.json"))
    assert "EY0C" not in clearest and "EA0Z" not in clearest and "flagged in the table, are left out" in clearest


def test_the_weak_direction_is_judged_together_and_only_its_share_is_excused():
    """Two constants in limit units: A with U far beyond its limit, B with U = 0.4 limit. Values on the line the
    plan cannot see (B = 0.1·A at ρ = 0.98) excuse B's 1.3 limits; the same B with A independent of it, or with a
    part off the line beyond its limit, stays a size no machine has."""
    import numpy as np

    from kinid.identification.model.plausibility import Implausible, _weak_partners

    def judged(b_value, rho):
        a = Implausible("EA0Z", 13e4, 1e4, "µrad", std=4e4)
        b = Implausible("EY0C", abs(b_value), 1e3, "µm", std=200.0)
        corr = np.array([[1.0, rho], [rho, 1.0]])
        return _weak_partners([a, b], [0, 1], np.array([-13e4, b_value]), corr)[1]

    assert not Implausible("EY0C", 1300.0, 1e3, "µm", std=200.0).undetermined  # alone: 6.5 U from zero
    on_line = judged(-1300.0, 0.98)
    assert on_line.undetermined and on_line.partners == ("EA0Z",)
    assert not judged(-1300.0, 0.0).undetermined  # nothing shared: B's size is its own
    assert not judged(+2600.0, 0.98).undetermined  # the determined remainder is beyond the limit


def test_a_candidate_is_judged_by_the_size_its_determined_coefficients_give():
    """A scored candidate's size, as a fitted effect's, is its largest value over the fitted range of its axis, from
    the coefficients the data determine (beyond twice their standard deviation): a term the noise alone can make
    large (a direction the model nearly holds) is not evidence of a size no machine has."""
    from kinid.identification.model.machine import load_machine
    from kinid.identification.model.plausibility import implausible_candidate
    from kinid.identification.diagnosis.scoring import Candidate

    machine = load_machine(urdf_path("five_axis_bc"))
    ranges = {"X": (-100.0, 100.0)}

    def scored(coefficients, std):
        return Candidate("EAX:poly2", "live", 2, 50.0, 1e-10, -10.0, 1.0, 0.0, 0.0, "µrad/mm²",
                         coefficients=coefficients, coefficient_std=std)

    odd = implausible_candidate(machine, scored((150.0, 0.0), (10.0, 1.0)), ranges)  # 150 µrad/mm over ±100 mm
    assert odd is not None and abs(odd.size - 15000.0) < 1.0 and odd.limit == 10000.0
    assert implausible_candidate(machine, scored((150.0, 0.0), (80.0, 1.0)), ranges) is None  # within 2σ of zero
    assert implausible_candidate(machine, scored((50.0, 0.0), (1.0, 1.0)), ranges) is None  # 5 000 µrad: a machine's
    assert implausible_candidate(machine, scored((), ()), ranges) is None  # values not known
