"""Every verb names the same thing the same way (docs/cli.md, 'One vocabulary'); old names still work as
hidden aliases that name the new option; a typo gets 'did you mean'."""
from __future__ import annotations

import argparse
import warnings

import pytest

from kinid.cli import VERBS, build_parser, main

#: concept -> (canonical option names, spellings no verb may show). Written here independently of kinid's
#: code: the table of docs/cli.md.
VOCABULARY = {
    "measurement a verb computes from": (("--data",), ("--log", "--moves", "--frames", "--runs", "--measurements",
                                                      "--obs", "--observations", "--input", "--in")),
    "the machine": (("--machine",), ("--urdf-machine", "--machine-urdf", "--robot")),
    "σ of a length": (("--noise-um", "--noise-mm"), ("--sigma-mm", "--sigma-um", "--sigma", "--noise-mm-um",
                                                    "--std-um")),
    "image noise": (("--noise-grey",), ("--noise", "--noise-gray", "--grey-noise")),
    "axis repeatability": (("--repeatability-um",), ("--repeat-um", "--repeatability")),
    "pixel size": (("--pixel-um",), ("--pixel-mm", "--pixel-size", "--pixel")),
    "a radius": (("--radius-mm",), ("--radius",)),
    "what a verb writes": (("--out",), ("--output", "--outfile", "-o")),
    "the result on standard output": (("--json",), ("--as-json", "--print-json")),
    "compensation tables over data or travel": (("--table-range",), ()),
}

#: Kept on purpose (docs/cli.md says why): verb -> options that look like another concept's but are not.
KEPT = {
    ("plan", "--range"): "axis ranges AXIS=START:STOP:STEP of the candidate poses",
    ("model", "--urdf"): "the source URDF converted into a machine (the output is the machine)",
    ("dual-axis", "--pixel-to-mm"): "a 2x2 matrix, mm per pixel, not one pixel size",
    ("backlash", "--plan-out"): "a mode that writes the plan to run, beside --out of the result",
}

#: Verbs that compute a result and so print it with --json.
COMPUTING = ("plan", "simulate", "identify", "diagnose", "predict", "model", "compensate", "verify", "sensor", "observe",
             "markers", "backlash", "uvw", "dual-axis", "contour", "iso230-2")


def _verb_parsers():
    for verb in VERBS:
        parser = build_parser(verb)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        yield verb, sub.choices[verb]


def _walk(parser):
    yield parser
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for p in a.choices.values():
                yield from _walk(p)


def _visible(parser):
    return {s for p in _walk(parser) for a in p._actions if a.help != argparse.SUPPRESS for s in a.option_strings}


def _hidden(parser):
    return {s: a for p in _walk(parser) for a in p._actions if a.help == argparse.SUPPRESS for s in a.option_strings}


PARSERS = dict(_verb_parsers())


@pytest.mark.parametrize("verb", list(VERBS))
def test_no_verb_shows_a_non_canonical_spelling(verb):
    shown = _visible(PARSERS[verb])
    forbidden = {old: concept for concept, (_, olds) in VOCABULARY.items() for old in olds}
    wrong = {o: forbidden[o] for o in shown if o in forbidden and (verb, o) not in KEPT}
    assert not wrong, f"kinid {verb} shows {wrong}: use the canonical name, keep the old one as a hidden alias"
    # --range only where it means axis ranges; --table-range where it means data or travel
    if "--range" in shown:
        assert (verb, "--range") in KEPT


@pytest.mark.parametrize("verb", list(VERBS))
def test_every_hidden_option_is_an_alias_of_a_shown_one(verb):
    parser = PARSERS[verb]
    for p in _walk(parser):
        shown = {s for a in p._actions if a.help != argparse.SUPPRESS for s in a.option_strings}
        for a in p._actions:
            if a.help == argparse.SUPPRESS and a.option_strings:
                assert getattr(a, "canonical", None) in shown, (verb, a.option_strings)
                assert a.dest == next(b.dest for b in p._actions if a.canonical in b.option_strings)


@pytest.mark.parametrize("verb", COMPUTING)
def test_every_computing_verb_has_json(verb):
    assert "--json" in _visible(PARSERS[verb])


def test_the_shared_concepts_are_spelled_the_same_where_they_appear():
    """The options that several verbs share: one spelling each (no --data on one verb and --log on another)."""
    uses = {}
    for verb, parser in PARSERS.items():
        for o in _visible(parser):
            uses.setdefault(o, set()).add(verb)
    assert {"identify", "diagnose", "verify", "observe", "backlash", "uvw", "dual-axis", "contour",
            "iso230-2"} <= uses["--data"]
    assert {"identify", "plan", "simulate", "observe", "sensor"} <= uses["--machine"]
    assert {"backlash", "dual-axis"} <= uses["--noise-grey"]
    assert {"backlash", "dual-axis"} <= uses["--repeatability-um"]
    assert {"backlash", "contour"} <= uses["--pixel-um"]
    assert {"sensor", "contour"} <= uses["--radius-mm"]


#: (verb and the arguments before the option, old name, new name, value): one per alias.
ALIASES = [
    (["observe", "--machine", "m.urdf", "--board", "b.json", "--sensor", "s.json", "--out", "o.csv"], "--log",
     "--data", ["run/log.csv"]),
    (["backlash"], "--log", "--data", ["log.csv"]),
    (["backlash", "--simulate"], "--noise", "--noise-grey", ["3.5"]),
    (["dual-axis", "--simulate"], "--noise", "--noise-grey", ["0.5"]),
    (["dual-axis", "--simulate"], "--repeat-um", "--repeatability-um", ["0.25"]),
    (["uvw"], "--moves", "--data", ["moves.csv"]),
    (["contour"], "--frames", "--data", ["frames"]),
    (["contour", "--simulate"], "--radius", "--radius-mm", ["8.5"]),
    (["sensor", "--machine", "m.urdf", "--hole", "h.csv", "--out", "s.json"], "--sigma-mm", "--noise-mm",
     ["0.002"]),
    (["compensate", "--fit", "f.json", "--out", "dir"], "--range", "--table-range", ["travel"]),
]


def _parse(argv):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        args = build_parser(argv[0]).parse_args(argv)
    return args, [str(w.message) for w in caught]


@pytest.mark.parametrize("before, old, new, value", ALIASES, ids=[f"{a[0][0]} {a[1]}" for a in ALIASES])
def test_an_old_name_still_works_and_names_the_new_one(before, old, new, value):
    by_old, said = _parse(before + [old, *value])
    by_new, quiet = _parse(before + [new, *value])
    plain = lambda ns: {k: v for k, v in vars(ns).items() if not callable(v)}  # noqa: E731
    assert plain(by_old) == plain(by_new)
    assert said == [f"{old} is now {new} (the old name still works)"]
    assert quiet == []


def test_contour_pixel_mm_is_read_as_mm_under_pixel_um():
    by_old, said = _parse(["contour", "--simulate", "--pixel-mm", "0.05"])
    by_new, _ = _parse(["contour", "--simulate", "--pixel-um", "50"])
    assert by_old.pixel_mm == pytest.approx(0.05) and by_new.pixel_mm == pytest.approx(0.05)
    assert said == ["--pixel-mm is now --pixel-um in µm (1000 x the mm value) (the old name still works)"]


def test_iso230_2_runs_by_position_still_work(tmp_path, capsys):
    runs = tmp_path / "runs.csv"
    rows = ["target_mm,run,direction,deviation_um"]
    rows += [f"{t},{r},{d},{0.5 * t + d + 0.1 * r}" for t in (0, 10, 20, 30, 40) for r in range(5) for d in (1, -1)]
    runs.write_text("\n".join(rows) + "\n")
    assert main(["iso230-2", "--data", str(runs), "--json"]) == 0
    new = capsys.readouterr()
    assert main(["iso230-2", str(runs), "--json"]) == 0
    old = capsys.readouterr()
    assert old.out == new.out and new.err == ""
    assert old.err == "kinid iso230-2: warning: RUNS.csv by position is now --data RUNS.csv (read by position still)\n"
    assert main(["iso230-2"]) == 2
    assert "--data RUNS.csv" in capsys.readouterr().err


def test_the_cli_says_the_old_name_once_on_stderr(capsys):
    assert main(["compensate", "--fit", "nothing.json", "--out", "dir", "--range", "travel"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "kinid compensate: warning: --range is now --table-range (the old name still works)"
    assert len(err) == 2 and "nothing.json" in err[1]


@pytest.mark.parametrize("argv, line", [
    (["identfy"], "kinid: unknown verb 'identfy' (did you mean identify?); kinid --help lists the verbs"),
    (["dual-axes"], "kinid: unknown verb 'dual-axes' (did you mean dual-axis?); kinid --help lists the verbs"),
    (["frobnicate"], "kinid: unknown verb 'frobnicate'; kinid --help lists the verbs"),
    (["identify", "--machine", "m.urdf", "--data", "o.csv", "--out", "f.json", "--nose-um", "1"],
     "kinid identify: unknown option --nose-um (did you mean --noise-um?); kinid identify --help lists its options"),
    (["identify", "--nose-um=1"],
     "kinid identify: unknown option --nose-um (did you mean --noise-um?); kinid identify --help lists its options"),
    (["compensate", "--fit", "f.json", "--out", "d", "--rnge", "travel"],
     "kinid compensate: unknown option --rnge (did you mean --table-range?); kinid compensate --help lists its "
     "options"),
    (["compensate", "--fit", "f.json", "--out", "d", "--format", "linuxcn"],
     "kinid compensate: argument --format: invalid choice: 'linuxcn' (did you mean linuxcnc?) (choose from "
     "'linuxcnc', 'sinumerik', 'twincat')"),
    (["history", "ad"], None),
    (["markers", "a.png", "--jsno"],
     "kinid markers: unknown option --jsno (did you mean --json?); kinid markers --help lists its options"),
])
def test_a_typo_gets_one_line_with_the_closest_name(argv, line, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    if line is not None:
        assert err == line + "\n"
    else:
        assert "(did you mean add?)" in err


# --- --json on the verbs that computed without it -------------------------------------------------------------

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
BC = str(ROOT / "urdf" / "five_axis_bc.urdf")


def _json_run(argv, capsys):
    import json

    assert main(argv) == 0
    out = capsys.readouterr()
    return json.loads(out.out), out.err  # stdout is one strict JSON value and nothing else


def _rows(path):
    import csv

    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_json_of_simulate_identify_predict_compensate_is_what_they_wrote(tmp_path, capsys):
    import json

    obs, fit, pred, comp = (str(tmp_path / n) for n in ("obs.csv", "fit.json", "pred.csv", "comp"))
    rows, err = _json_run(["simulate", "--machine", BC, "--errors", str(ROOT / "examples" / "errors.json"),
                           "--noise-um", "1", "--out", obs, "--json"], capsys)
    written = _rows(obs)
    assert len(rows) == len(written) > 0
    assert all(r["mark"] == w["mark"] and r["x_mm"] == pytest.approx(float(w["x_mm"]), abs=1e-9)
               for r, w in zip(rows, written))
    doc, err = _json_run(["identify", "--machine", BC, "--data", obs, "--noise-um", "1", "--out", fit, "--json"],
                         capsys)
    assert doc == json.loads(open(fit).read()) and "rms" in err.lower()  # the text went to stderr
    rows, _ = _json_run(["predict", "--fit", fit, "--poses", str(ROOT / "examples" / "poses.csv"), "--out", pred,
                         "--json"], capsys)
    assert [r["x_mm"] for r in rows] == pytest.approx([float(w["x_mm"]) for w in _rows(pred)], abs=1e-9)
    doc, _ = _json_run(["compensate", "--fit", fit, "--out", comp, "--json"], capsys)
    assert doc == json.loads(open(f"{comp}/compensation.json").read())


def test_json_of_model_names_what_the_machine_holds(tmp_path, capsys):
    import re

    out = tmp_path / "ur.urdf"
    doc, _ = _json_run(["model", "--urdf", str(ROOT / "examples" / "ur_like.urdf"), "--base", "world", "--tool",
                        "wrist_3_link", "--out", str(out), "--json"], capsys)
    assert [a["name"] for a in doc["axes"]] == [f"J{i}" for i in range(1, 7)]
    assert doc["axes"][0]["joint"] == "shoulder_pan_joint" and doc["axes"][0]["column"] == "j1_deg"
    # error joints as the written URDF declares them (joints whose name is an ISO 230-1 code, E...)
    declared = re.findall(r'<joint name="(E[A-Z0-9]+)"', out.read_text())
    assert sorted(doc["error_parameters"]) == sorted(declared) and len(declared) > 0


def test_json_of_sensor_is_the_file_and_json_with_out_dash_is_refused(tmp_path, capsys):
    import json

    out = tmp_path / "s.json"
    doc, _ = _json_run(["sensor", "--machine", BC, "--hole", str(ROOT / "examples" / "sensor_hole.csv"), "--base",
                        str(ROOT / "examples" / "run" / "sensor.json"), "--out", str(out), "--json"], capsys)
    assert doc == json.loads(out.read_text())
    assert main(["predict", "--fit", "f.json", "--poses", "p.csv", "--out", "-", "--json"]) == 2
    assert "--json and an output '-' both print" in capsys.readouterr().err


# --- a missing column names its likely typo -------------------------------------------------------------------

@pytest.mark.parametrize("old, new, hint", [
    ("x_mm", "xmm", "missing column 'x_mm' for axis X (did you mean 'xmm'?)"),
    ("wx_mm", "wxmm", "missing column 'wx_mm' (did you mean 'wxmm'? header:"),
    ("dir_x", "dir_xx", "'dir_' column for unknown axis 'xx'; did you mean 'dir_x'?"),
])
def test_a_misspelt_column_is_named(old, new, hint, tmp_path):
    from kinid.errors import DataError
    from kinid.identification import load_machine, read_observations

    header = ["mark", "wx_mm", "wy_mm", "wz_mm", "x_mm", "y_mm", "z_mm", "b_deg", "c_deg", "dir_x"]
    text = ",".join(new if h == old else h for h in header) + "\nM1,40,40,0,10,0,10,0,0,1\n"
    (tmp_path / "o.csv").write_text(text)
    with pytest.raises(DataError, match=__import__("re").escape(hint)):
        read_observations(tmp_path / "o.csv", load_machine(BC))


def test_a_column_far_from_every_name_gets_no_guess(tmp_path):
    from kinid.errors import DataError
    from kinid.identification import load_machine, read_observations

    (tmp_path / "o.csv").write_text("mark,wx_mm,wy_mm,wz_mm,temperature,y_mm,z_mm,b_deg,c_deg\nM1,0,0,0,1,2,3,4,5\n")
    with pytest.raises(DataError) as exc:
        read_observations(tmp_path / "o.csv", load_machine(BC))
    assert "missing column 'x_mm' for axis X" in str(exc.value) and "did you mean" not in str(exc.value)
