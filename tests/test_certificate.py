"""kinid certificate: one A4 page (PDF and HTML) whose values are the inputs', no word broken, metadata checked."""
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from kinid.cli import main

ROOT = Path(__file__).resolve().parents[1]
MACHINE = str(ROOT / "urdf" / "five_axis_bc.urdf")
META = ROOT / "examples" / "certificate_meta.json"
needs_poppler = pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler-utils not installed")


def _run(args, capsys):
    status = main([str(a) for a in args])
    out = capsys.readouterr()
    return status, out.out, out.err


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A fit with a hidden lead, a verification run of set-up errors only, and the ISO 230-2 result of X."""
    d = tmp_path_factory.mktemp("cert_inputs")
    assert main(["simulate", "--machine", MACHINE, "--errors", str(ROOT / "examples/errors.json"), "--plan", "patent",
                 "--noise-um", "1", "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10",
                 "--noise-um", "1", "--out", str(d / "fit.json")]) == 0
    assert main(["simulate", "--machine", MACHINE, "--errors", str(ROOT / "examples/setup_only.json"), "--plan",
                 "patent", "--noise-um", "1", "--seed", "2", "--out", str(d / "run2.csv")]) == 0
    assert main(["verify", "--fit", str(d / "fit.json"), "--data", str(d / "run2.csv"), "--report", str(d / "v")]) == 0
    import contextlib
    import io

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        assert main(["iso230-2", "--data", str(ROOT / "examples/x_runs.csv"), "--axis", "X", "--json"]) == 0
    (d / "iso_x.json").write_text(buffer.getvalue())
    return d


def _pages(pdf: Path) -> int:
    """Pages of a PDF counted from its page objects (``/Type /Page``, not ``/Pages``)."""
    return len(re.findall(rb"/Type\s*/Page(?![a-z])", pdf.read_bytes()))


def _text(pdf: Path) -> str:
    return subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout


def _g3(x: float) -> str:
    """Three significant digits, as a person reads them off the page (6.9192 -> 6.92, 0.94496 -> 0.945)."""
    return f"{float(f'{x:.3g}'):.{max(0, 2 - int(__import__('math').floor(__import__('math').log10(abs(x)))))}f}"


@needs_poppler
def test_one_page_values_of_the_inputs_and_no_word_broken(inputs, tmp_path, capsys):
    out = tmp_path / "cert"
    status, stdout, err = _run(["certificate", "--fit", inputs / "fit.json", "--verify", inputs / "v", "--iso",
                                inputs / "iso_x.json", "--meta", META, "--out", out, "--json"], capsys)
    assert status == 0, err
    shown = json.loads(stdout)
    pdf = out / "certificate.pdf"
    assert _pages(pdf) == 1
    rendered = subprocess.run(["pdftoppm", "-r", "20", "-png", str(pdf), str(tmp_path / "p")], check=True)
    assert rendered.returncode == 0 and len(list(tmp_path.glob("p*.png"))) == 1
    text = _text(pdf)
    tokens = set(text.split())
    # every word of the content is whole on the page: no line breaks inside a word
    words = set()
    for part in ("results", "uncertainty", "identification", "conditions", "traceability"):
        for item in shown[part]:
            for piece in ([item] if isinstance(item, str) else item):
                words |= set(piece.split())
    broken = sorted(w for w in words if w not in tokens)
    assert not broken, f"words not whole on the page: {broken[:10]}"
    # the metadata as given
    meta = json.loads(META.read_text())
    for key in ("machine", "serial_number", "customer", "operator", "instrument_serial", "measurement_date",
                "instrument_calibration_date", "certificate_number"):
        assert meta[key] in " ".join(text.split()), key
    assert f"machine {meta['machine_temperature_c']:.1f} °C, air {meta['air_temperature_c']:.1f} °C" in \
        " ".join(text.split())
    # ISO 230-2: A, R, E, B, M of the axis as the iso230-2 file gives them
    iso = json.loads((inputs / "iso_x.json").read_text())
    for key in ("A_um", "R_um", "E_um", "B_um", "M_um"):
        assert _g3(iso[key]) in tokens, (key, _g3(iso[key]))
    # verify: RMS before and after, 3-D max
    v = json.loads((inputs / "v" / "verify.json").read_text())
    for value in (v["before_um"]["3d"], v["after_um"]["3d"], v["before_max_3d_um"], v["after_max_3d_um"]):
        assert _g3(value) in tokens, value
    # the fit: the machine's parameters (not the set-up W/T) with |value| > 2 std, by the file's numbers
    fit = json.loads((inputs / "fit.json").read_text())
    significant = [p for p in fit["parameters"] if p["identified"] and p["std"]
                   and p["name"].split(":")[0][-1] not in "WT" and abs(p["value"]) > 2 * p["std"]]
    identified = [p for p in fit["parameters"] if p["identified"] and p["std"] and p["name"].split(":")[0][-1] not in "WT"]
    assert len(significant) >= 3
    assert f"{len(significant)} of the machine's {len(identified)} identified" in " ".join(text.split())
    for p in significant:
        assert p["name"] in tokens
        assert f"{2 * p['std']:.2g}".rstrip("0").rstrip(".") in {t.rstrip("0").rstrip(".") for t in tokens}, p
    import hashlib

    assert hashlib.sha256((inputs / "fit.json").read_bytes()).hexdigest() in tokens
    # the HTML says the same
    html = (out / "certificate.html").read_text()
    assert "size: A4" in html and meta["serial_number"] in html and _g3(iso["A_um"]) in html


def test_values_are_escaped_in_the_html(inputs, tmp_path, capsys):
    meta = json.loads(META.read_text())
    meta["customer"] = "<script>alert(1)</script> & Sons"
    (tmp_path / "meta.json").write_text(json.dumps(meta))
    status, _, err = _run(["certificate", "--iso", inputs / "iso_x.json", "--meta", tmp_path / "meta.json", "--out",
                           tmp_path / "c"], capsys)
    assert status == 0, err
    html = (tmp_path / "c" / "certificate.html").read_text()
    assert "<script>" not in html and "&lt;script&gt;alert(1)&lt;/script&gt; &amp; Sons" in html
    assert _pages(tmp_path / "c" / "certificate.pdf") == 1


def test_many_axes_shrink_to_one_page_then_refuse(inputs, tmp_path, capsys):
    iso = json.loads((inputs / "iso_x.json").read_text())
    files = []
    for i in range(60):
        iso["axis"] = f"X{i}"
        files.append(tmp_path / f"iso_{i}.json")
        files[-1].write_text(json.dumps(iso))
    status, _, err = _run(["certificate", "--fit", inputs / "fit.json", "--iso", *files[:9], "--meta", META, "--out",
                           tmp_path / "c9"], capsys)
    assert status == 0, err
    assert _pages(tmp_path / "c9" / "certificate.pdf") == 1
    status, _, err = _run(["certificate", "--fit", inputs / "fit.json", "--iso", *files, "--meta", META, "--out",
                           tmp_path / "c60"], capsys)
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and "does not fit one A4 page" in err
    assert not (tmp_path / "c60").exists()  # nothing written


def _meta(tmp_path, **change):
    meta = json.loads(META.read_text())
    for k, v in change.items():
        if v is None:
            meta.pop(k)
        else:
            meta[k] = v
    path = tmp_path / "meta.json"
    path.write_text(json.dumps(meta))
    return path


@pytest.mark.parametrize("change, message", [
    ({"costumer": "X"}, r"meta.json: unknown key 'costumer' \(did you mean customer\?\)"),
    ({"operator": None}, r"meta.json: key 'operator' is missing"),
    ({"measurement_date": "20.11.2026"}, r"meta.json: key 'measurement_date' must be a date YYYY-MM-DD"),
    ({"instrument_calibration_date": "2026-02-30"}, r"key 'instrument_calibration_date' must be a date"),
    ({"measurement_date": "2999-01-01"}, r"key 'measurement_date': 2999-01-01 is in the future"),
    ({"air_temperature_c": 68.5}, r"key 'air_temperature_c': 68.5 °C is outside 0 .. 45 °C.*°F given"),
    ({"machine_temperature_c": 293.4}, r"key 'machine_temperature_c'.*kelvin given"),
    ({"machine_temperature_c": "20"}, r"key 'machine_temperature_c' must be a number of °C"),
    ({"serial_number": 12345}, r"key 'serial_number' must be a text"),
    ({"remarks": "x" * 400}, r"key 'remarks' is 400 characters long"),
])
def test_bad_metadata_is_one_line_exit_2(inputs, tmp_path, capsys, change, message):
    status, _, err = _run(["certificate", "--iso", inputs / "iso_x.json", "--meta", _meta(tmp_path, **change),
                           "--out", tmp_path / "c"], capsys)
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("kinid certificate: ")
    assert re.search(message, err), err
    assert not (tmp_path / "c").exists()


def test_metadata_not_an_object_and_nothing_to_certify(tmp_path, capsys):
    (tmp_path / "m.json").write_text("[1, 2]")
    status, _, err = _run(["certificate", "--iso", "x.json", "--meta", tmp_path / "m.json", "--out", tmp_path / "c"],
                          capsys)
    assert status == 2 and "m.json: must be one JSON object" in err
    status, _, err = _run(["certificate", "--meta", META, "--out", tmp_path / "c"], capsys)
    assert status == 2 and "nothing to certify" in err and len(err.strip().splitlines()) == 1


@needs_poppler
@pytest.mark.parametrize("calibrated, words", [
    ("2026-11-25", "dated after the measurement"),
    ("2025-06-01", "days old at the measurement"),
])
def test_calibration_date_warns_on_stderr_and_on_the_page(inputs, tmp_path, capsys, calibrated, words):
    status, _, err = _run(["certificate", "--iso", inputs / "iso_x.json", "--meta",
                           _meta(tmp_path, instrument_calibration_date=calibrated), "--out", tmp_path / "c"], capsys)
    assert status == 0
    assert "kinid certificate: warning:" in err and words in err
    assert words in " ".join(_text(tmp_path / "c" / "certificate.pdf").split())


def test_a_verification_of_another_machine_is_refused(inputs, tmp_path, capsys):
    """kinid verify records the SHA-256 of its machine's URDF; the certificate refuses a verification whose machine
    is not the fit's (exit 2, one line, nothing written) and warns when the verification does not record it."""
    from kinid.identification.fitting import load_trusted_fit

    v = json.loads((inputs / "v" / "verify.json").read_text())
    assert v["machine_sha256"] == load_trusted_fit(inputs / "fit.json").machine.urdf_sha256
    other = dict(v, machine_sha256="0" * 64)
    (tmp_path / "other.json").write_text(json.dumps(other))
    status, _, err = _run(["certificate", "--fit", inputs / "fit.json", "--verify", tmp_path / "other.json", "--meta",
                           META, "--out", tmp_path / "c"], capsys)
    assert status == 2 and "was made with another machine than fit.json" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c").exists()
    older = {k: x for k, x in v.items() if k != "machine_sha256"}
    (tmp_path / "older.json").write_text(json.dumps(older))
    status, _, err = _run(["certificate", "--fit", inputs / "fit.json", "--verify", tmp_path / "older.json", "--meta",
                           META, "--out", tmp_path / "c"], capsys)
    assert status == 0 and "does not record its machine" in err


def test_an_iso_result_of_an_axis_the_machine_lacks_is_warned_on_the_page(inputs, tmp_path, capsys):
    iso = json.loads((inputs / "iso_x.json").read_text())
    (tmp_path / "iso_u.json").write_text(json.dumps(dict(iso, axis="U")))
    status, out, _ = _run(["certificate", "--fit", inputs / "fit.json", "--iso", tmp_path / "iso_u.json", "--meta",
                           META, "--out", tmp_path / "c"], capsys)
    assert status == 0 and "warning (on the page): The ISO 230-2 result iso_u.json is of an axis U" in out
    assert "which the fitted machine does not have" in (tmp_path / "c" / "certificate.html").read_text()
    status, out, _ = _run(["certificate", "--fit", inputs / "fit.json", "--iso", inputs / "iso_x.json", "--meta",
                           META, "--out", tmp_path / "c2"], capsys)
    assert status == 0 and "warning" not in out
