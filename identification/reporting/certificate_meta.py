"""The certificate's metadata file (META.json): who, what, where, with which instrument, at which temperatures.

A small JSON object (docs/certificate.md, ``examples/certificate_meta.json``) checked at the door: an unknown
key (with the closest known one), a required key missing, a date that is not YYYY-MM-DD, a temperature outside
what a workshop has, a text too long for one line of the page — each one line naming the file and the key.
What is valid but questionable is a warning (:func:`warnings.warn`) that the certificate also shows: an
instrument calibrated after the measurement, or more than :data:`CALIBRATION_VALID_DAYS` before it.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from datetime import date

from kinid.errors import DataError

__all__ = ["CertificateMeta", "read_meta", "check_meta", "META_KEYS", "CALIBRATION_VALID_DAYS", "TEMPERATURE_RANGE_C"]

#: Keys of META.json -> (required, what it is, longest text). Dates are YYYY-MM-DD, temperatures °C.
META_KEYS = {
    "machine": (True, "the machine's make and model", 80),
    "serial_number": (True, "the machine's serial number", 40),
    "customer": (True, "the customer (company, site)", 80),
    "operator": (True, "who measured", 60),
    "place": (False, "where the machine stands", 80),
    "measurement_date": (True, "the date of the measurement, YYYY-MM-DD", 10),
    "instrument": (True, "the measuring instrument (make and model)", 80),
    "instrument_serial": (True, "the instrument's serial number", 40),
    "instrument_calibration_date": (True, "the date of the instrument's last calibration, YYYY-MM-DD", 10),
    "instrument_calibration_certificate": (False, "the number of the instrument's calibration certificate", 60),
    "machine_temperature_c": (True, "the machine's temperature during the measurement, °C", None),
    "air_temperature_c": (True, "the air's temperature during the measurement, °C", None),
    "certificate_number": (False, "the certificate's number", 40),
    "issued_by": (False, "the company or laboratory issuing the certificate", 80),
    "remarks": (False, "a remark printed on the certificate", 300),
}

#: Temperatures a machine or the air of a workshop can have, °C (outside: °F or K given, or a typo).
TEMPERATURE_RANGE_C = (0.0, 45.0)
#: An instrument's calibration older than this at the measurement is flagged (the usual interval is one year).
CALIBRATION_VALID_DAYS = 366


@dataclass(frozen=True)
class CertificateMeta:
    """The checked META.json: ``values`` (key -> str, or float for temperatures) and the ``warnings`` to show."""

    values: dict
    warnings: tuple = ()

    def get(self, key: str, default: str = "") -> str:
        v = self.values.get(key)
        return default if v is None else v

    @property
    def measured(self) -> date:
        return date.fromisoformat(self.values["measurement_date"])


def read_meta(path, *, today: date | None = None) -> CertificateMeta:
    """Read and check META.json (:func:`check_meta`); a DataError naming the file and the key otherwise."""
    from kinid.files import read_json
    from kinid.schema import Fields, Number, Text, validate

    data = read_json(path, what="certificate metadata file")
    meta = check_meta(data, path=path, today=today)  # the messages a person acts on: did you mean, °F given
    schema = {k: Number(low=TEMPERATURE_RANGE_C[0], high=TEMPERATURE_RANGE_C[1]) if k.endswith("_c") else Text()
              for k in META_KEYS}
    validate(data, Fields({k: v for k, v in schema.items() if META_KEYS[k][0]},
                          optional={k: Text(null=True) for k in schema if not META_KEYS[k][0]}), path=path)
    return meta


def check_meta(data, *, path=None, today: date | None = None) -> CertificateMeta:
    """The metadata object ``data`` checked; warnings for an instrument calibration after the measurement or
    older than :data:`CALIBRATION_VALID_DAYS` (issued with :func:`warnings.warn` and kept for the page).

    Raises
    ------
    DataError
        One line naming ``path`` and the key: not an object, an unknown key (the closest known one), a required
        key missing, a text empty or too long, a date not YYYY-MM-DD or in the future, a temperature not a number
        or outside :data:`TEMPERATURE_RANGE_C`.
    """
    from kinid.options import did_you_mean

    if not isinstance(data, dict):
        raise DataError(f"must be one JSON object of {', '.join(k for k, v in META_KEYS.items() if v[0])}", path=path)
    for key in data:
        if key not in META_KEYS:
            raise DataError(f"unknown key {key!r}{did_you_mean(key, META_KEYS)}; known keys: "
                            f"{', '.join(META_KEYS)}", path=path)
    for key, (required, what, _) in META_KEYS.items():
        if required and data.get(key) is None:
            raise DataError(f"key {key!r} is missing: {what}", path=path)
    values = {}
    for key, value in data.items():
        if value is None:
            continue
        values[key] = _temperature(key, value, path) if key.endswith("_c") else _text(key, value, path)
    today = today or date.today()
    measured = _date("measurement_date", values["measurement_date"], path)
    calibrated = _date("instrument_calibration_date", values["instrument_calibration_date"], path)
    if measured > today:
        raise DataError(f"key 'measurement_date': {measured} is in the future (today is {today}); a typo of the "
                        f"year or month?", path=path)
    notes = []
    if calibrated > measured:
        notes.append(f"the instrument's calibration ({calibrated}) is dated after the measurement ({measured}): the "
                     f"instrument was not shown calibrated when it measured")
    elif (measured - calibrated).days > CALIBRATION_VALID_DAYS:
        notes.append(f"the instrument's calibration ({calibrated}) was {(measured - calibrated).days} days old at the "
                     f"measurement ({measured}): more than a year, recalibrate the instrument")
    for note in notes:
        warnings.warn(note, stacklevel=2)
    return CertificateMeta(values, tuple(notes))


def _text(key: str, value, path) -> str:
    longest = META_KEYS[key][2]
    if not isinstance(value, str):
        raise DataError(f"key {key!r} must be a text (in quotes), got {value!r}", path=path)
    text = " ".join(value.split())
    if not text:
        raise DataError(f"key {key!r} is empty: {META_KEYS[key][1]}", path=path)
    if longest is not None and len(text) > longest and not key.endswith("_date"):
        raise DataError(f"key {key!r} is {len(text)} characters long; at most {longest} fit its line on the "
                        f"certificate", path=path)
    return text


def _date(key: str, text: str, path) -> date:
    try:
        if len(text) != 10:
            raise ValueError
        return date.fromisoformat(text)
    except ValueError:
        raise DataError(f"key {key!r} must be a date YYYY-MM-DD (e.g. 2026-03-14), got {text!r}", path=path) from None


def _temperature(key: str, value, path) -> float:
    lo, hi = TEMPERATURE_RANGE_C
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DataError(f"key {key!r} must be a number of °C, got {value!r}", path=path)
    if not lo <= value <= hi:
        hint = " (°F given?)" if 32 <= value <= 120 else " (kelvin given?)" if 250 <= value <= 330 else ""
        raise DataError(f"key {key!r}: {value:g} °C is outside {lo:g} .. {hi:g} °C, no workshop's{hint}", path=path)
    return float(value)
