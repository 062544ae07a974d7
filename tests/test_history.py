"""`kinid history`: five quarterly calibrations of a B/C machine whose pivot EX0C drifts 8 µm a quarter.

Each calibration is simulated and identified through kinid.cli.main (as a user runs them), added to a
history and shown: EX0C is flagged and no other term; the same against a second database given by a
sqlite:/// URL. The truth of the trend is the plain straight line through the simulated values.
"""
from __future__ import annotations

import datetime as dt
import json
import sqlite3

import numpy as np
import pytest

from kinid.cli import main
from kinid.urdf import path

BC = str(path("five_axis_bc"))
DATES = ("2026-01-15", "2026-04-15", "2026-07-15", "2026-10-15", "2027-01-15")
#: The pivot of C in X grows 8 µm a quarter; the rest of the machine stays.
DRIFT_UM = 8.0
START_UM = 12.0
STAYS = {"EA0B": -25.0, "EC0Y": 8.0, "EX0W": 1.5}


def _one_line(capsys):
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1, err
    return err[0]


@pytest.fixture(scope="module")
def quarters(tmp_path_factory):
    d = tmp_path_factory.mktemp("quarters")
    fits = []
    for q in range(len(DATES)):
        errors = d / f"errors{q}.json"
        errors.write_text(json.dumps({"EX0C": START_UM + DRIFT_UM * q, **STAYS}))
        assert main(["simulate", "--machine", BC, "--errors", str(errors), "--noise-um", "1", "--seed", str(10 + q),
                     "--out", str(d / f"obs{q}.csv")]) == 0
        assert main(["identify", "--machine", BC, "--data", str(d / f"obs{q}.csv"), "--noise-um", "1",
                     "--out", str(d / f"fit{q}.json")]) == 0
        fits.append(d / f"fit{q}.json")
    return d, fits


def _add_all(db, fits, capsys):
    for fit, date in zip(fits, DATES):
        assert main(["history", "add", "--db", db, "--machine-id", "mill-7", "--fit", str(fit), "--date", date]) == 0
    capsys.readouterr()


def _show_json(db, capsys, *extra):
    assert main(["history", "show", "--db", db, "--machine-id", "mill-7", "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("form", ["path", "url"])
def test_the_drifting_pivot_is_flagged_and_nothing_else(quarters, tmp_path, capsys, form):
    _, fits = quarters
    file = tmp_path / "history.sqlite"
    db = str(file) if form == "path" else "sqlite:///" + str(file)  # sqlite:////abs/path: the URL's absolute form
    _add_all(db, fits, capsys)
    shown = _show_json(db, capsys)
    assert [c["date"] for c in shown["calibrations"]] == list(DATES)
    assert shown["flagged"] == ["EX0C"]
    terms = {t["name"]: t for t in shown["terms"]}
    ex0c = terms["EX0C"]
    assert len(ex0c["flags"]) == len(DATES) - 1  # every quarter's step
    values = np.array([p["value"] for p in ex0c["points"]])
    std = np.array([p["std"] for p in ex0c["points"]])
    truth = START_UM + DRIFT_UM * np.arange(len(DATES))
    assert np.all(np.abs(values - truth) < 4 * std)
    days = np.array([(dt.date.fromisoformat(d) - dt.date.fromisoformat(DATES[0])).days for d in DATES])
    slope = np.polyfit(days / 365.25, truth, 1)[0]  # ≈ 32 µm a year
    assert abs(ex0c["trend_per_year"] - slope) < 4 * ex0c["trend_std_per_year"]
    # the terms that stay are there, each identified every quarter, and none flagged
    for name in ("EA0B", "EC0Y", "EX0B", "EB0C"):
        assert all(p["value"] is not None for p in terms[name]["points"]) and not terms[name]["flagged"]
    assert shown["comparisons"] == sum(len(DATES) - 1 for t in shown["terms"] if t["kind"] == "machine"
                                       and all(p["value"] is not None for p in t["points"]))
    # the table a person reads
    assert main(["history", "show", "--db", db, "--machine-id", "mill-7"]) == 0
    text = capsys.readouterr().out
    assert "flagged: EX0C" in text and any(line.startswith("* EX0C ") for line in text.splitlines())
    assert sum(line.startswith("* ") for line in text.splitlines()) == 1


def test_a_tolerance_flags_a_term_that_departs_from_its_first_value(quarters, tmp_path, capsys):
    _, fits = quarters
    db = str(tmp_path / "h.sqlite")
    _add_all(db, fits, capsys)
    shown = _show_json(db, capsys, "--tolerance", "EA0B=0.001", "EX0C=1000")
    terms = {t["name"]: t for t in shown["terms"]}
    first = terms["EA0B"]["points"][0]["value"]
    moved = [p for p in terms["EA0B"]["points"][1:] if abs(p["value"] - first) > 0.001]
    assert terms["EA0B"]["flagged"] == bool(moved) and moved  # fitted anew each quarter: it moves by noise
    assert all("tolerance" in f for f in terms["EA0B"]["flags"])
    assert not any("tolerance" in f for f in terms["EX0C"]["flags"])  # 32 µm is within 1000 µm
    assert sorted(shown["flagged"]) == ["EA0B", "EX0C"]


def test_the_same_fit_twice_is_refused_and_show_changes_nothing(quarters, tmp_path, capsys):
    _, fits = quarters
    file = tmp_path / "h.sqlite"
    _add_all(str(file), fits, capsys)
    before = file.read_bytes()
    assert main(["history", "add", "--db", str(file), "--machine-id", "mill-7", "--fit", str(fits[2]),
                 "--date", "2027-04-15"]) == 2
    line = _one_line(capsys)
    assert "already in the history" in line and "2026-07-15" in line
    assert main(["history", "show", "--db", str(file), "--machine-id", "mill-7"]) == 0
    assert main(["history", "plot", "--db", str(file), "--machine-id", "mill-7", "--out", str(tmp_path / "t.png")]) == 0
    assert file.read_bytes() == before
    with sqlite3.connect(file) as conn:
        assert conn.execute("SELECT COUNT(*) FROM calibrations").fetchone()[0] == len(DATES)


def test_plot_draws_the_flagged_terms(quarters, tmp_path, capsys):
    _, fits = quarters
    db = str(tmp_path / "h.sqlite")
    _add_all(db, fits, capsys)
    assert main(["history", "plot", "--db", db, "--machine-id", "mill-7", "--out", str(tmp_path / "trends.png")]) == 0
    assert capsys.readouterr().out.startswith("1 term of mill-7 over 5 calibrations")
    assert main(["history", "plot", "--db", db, "--machine-id", "mill-7", "--all", "--out", str(tmp_path / "all.png")]) == 0
    said = capsys.readouterr().out
    import matplotlib.image as mpimg

    one, every = mpimg.imread(tmp_path / "trends.png"), mpimg.imread(tmp_path / "all.png")
    assert every.shape[0] > 3 * one.shape[0]  # one panel against a grid of every identified term
    assert int(said.split()[0]) > 10


def test_the_verification_figures_are_kept(quarters, tmp_path, capsys):
    d, fits = quarters
    assert main(["verify", "--fit", str(fits[1]), "--data", str(d / "obs1.csv"), "--json"]) == 0
    (tmp_path / "verify.json").write_text(capsys.readouterr().out)
    figures = json.loads((tmp_path / "verify.json").read_text())
    db = str(tmp_path / "h.sqlite")
    assert main(["history", "add", "--db", db, "--machine-id", "mill-7", "--fit", str(fits[1]), "--date", DATES[1],
                 "--verify", str(tmp_path / "verify.json")]) == 0
    capsys.readouterr()
    shown = _show_json(db, capsys)
    kept = shown["calibrations"][0]["verify"]
    assert kept["after_3d_um"] == figures["after_um"]["3d"] and kept["before_3d_um"] == figures["before_um"]["3d"]
    assert kept["at_noise_level"] == figures["at_noise_level"]


def test_bad_input_is_one_line_and_exit_2(quarters, tmp_path, capsys):
    d, fits = quarters
    db = tmp_path / "h.sqlite"
    assert main(["history", "add", "--db", str(db), "--machine-id", "mill-7", "--fit", str(fits[0]),
                 "--date", DATES[0]]) == 0
    capsys.readouterr()
    # a database file that is not SQLite: refused, left as it was
    text = tmp_path / "notes.sqlite"
    text.write_text("calibration notes\n")
    for verb in (["add", "--fit", str(fits[1])], ["show"]):
        assert main(["history", verb[0], "--db", str(text), "--machine-id", "mill-7", *verb[1:]]) == 2
        assert "not a SQLite database" in _one_line(capsys)
    assert text.read_text() == "calibration notes\n"
    # a SQLite database of something else: refused, left as it was
    other = tmp_path / "other.db"
    with sqlite3.connect(other) as conn:
        conn.execute("CREATE TABLE parts (n INTEGER)")
    kept = other.read_bytes()
    assert main(["history", "add", "--db", str(other), "--machine-id", "mill-7", "--fit", str(fits[1])]) == 2
    assert "not a kinid history" in _one_line(capsys) and other.read_bytes() == kept
    # the figure may not overwrite the history it is drawn from
    kept = db.read_bytes()
    assert main(["history", "plot", "--db", str(db), "--machine-id", "mill-7", "--out", str(db)]) == 2
    assert "--out names the input file given as --db" in _one_line(capsys) and db.read_bytes() == kept
    # a missing fit
    assert main(["history", "add", "--db", str(db), "--machine-id", "mill-7", "--fit", str(tmp_path / "no.json")]) == 2
    assert "no such fit file" in _one_line(capsys)
    # an unknown machine id names the ones the history holds
    assert main(["history", "show", "--db", str(db), "--machine-id", "mill-8"]) == 2
    line = _one_line(capsys)
    assert "--machine-id 'mill-8' has no calibration" in line and "mill-7" in line
    # a database server's URL names its scheme
    assert main(["history", "show", "--db", "postgresql://user@host/kinid", "--machine-id", "mill-7"]) == 2
    assert "'postgresql'" in _one_line(capsys)
    # no database at all: show does not create one
    assert main(["history", "show", "--db", str(tmp_path / "none.sqlite"), "--machine-id", "mill-7"]) == 2
    assert "no history database" in _one_line(capsys) and not (tmp_path / "none.sqlite").exists()
    # a date that is no date, a tolerance that is no number, a term the machine lacks
    assert main(["history", "add", "--db", str(db), "--machine-id", "mill-7", "--fit", str(fits[1]),
                 "--date", "2026-02-30"]) == 2
    assert "--date" in _one_line(capsys)
    assert main(["history", "show", "--db", str(db), "--machine-id", "mill-7", "--tolerance", "EX0C=lots"]) == 2
    assert "--tolerance" in _one_line(capsys)
    assert main(["history", "show", "--db", str(db), "--machine-id", "mill-7", "--tolerance", "EQQ=5"]) == 2
    assert "EQQ" in _one_line(capsys)
    # a fit that cannot be trusted is not stored
    bad = json.loads(fits[1].read_text())
    bad["success"] = False
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    assert main(["history", "add", "--db", str(db), "--machine-id", "mill-7", "--fit", str(tmp_path / "bad.json")]) == 2
    assert "did not converge" in _one_line(capsys)
    # a verification file that is not kinid verify --json's
    assert main(["history", "add", "--db", str(db), "--machine-id", "mill-7", "--fit", str(fits[1]),
                 "--verify", str(d / "obs1.csv")]) == 2
    assert "obs1.csv" in _one_line(capsys)
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT COUNT(*) FROM calibrations").fetchone()[0] == 1
