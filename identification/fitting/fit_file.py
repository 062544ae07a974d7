"""FIT.json: a fit written whole, read back only when every value is of its kind and within physical ranges.

The file's schema (:data:`FIT_SCHEMA`, checked by :func:`kinid.schema.validate`) is what
:func:`fit_to_dict` writes: a tampered or hand-edited file — a string where a number goes, a negative
standard deviation, a value of 1e300, a range given backwards — is refused with the key named, before
anything is computed from it. The ranges are wide on purpose: a parameter beyond ±10⁷ in its unit
(10 m in µm, 10 rad in µrad) is no machine's error.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from kinid.errors import DataError, KinidError
from kinid.files import read_json, write_json
from kinid.schema import Fields, Flag, Items, Number, Row, Table, Text, validate

from ..model import implausible_effects, machine_from_urdf, parse_effect
from ..data import SetAside
from .fit import FIT_FORMAT, FitResult
from .identifiability import Alias
from .noise import NOISE_RATIO_LIMIT, Noise, noise_ratio

__all__ = ["fit_to_dict", "save_fit", "load_fit", "load_trusted_fit", "untrusted", "FIT_SCHEMA"]

#: The largest size of a parameter, a standard deviation or a residual in its own unit (µm, µrad, ...).
LARGEST = 1e7
_SIZE = Number(low=-LARGEST, high=LARGEST, null=True)
_STD = Number(low=0, high=LARGEST, null=True)
_COUNT = Number(low=0, integer=True)

#: What a FIT.json holds (docs/formats.md); keys a later version adds are allowed at the top level.
FIT_SCHEMA = Fields(
    required={
        "format": Text((FIT_FORMAT,)),
        "machine": Fields({"urdf": Text()}, optional={"path": Text(null=True)}),
        "effects": Items(Text()),
        "parameters": Items(Fields({"name": Text(), "value": _SIZE, "unit": Text(), "identified": Flag()},
                                   optional={"std": _STD})),
    },
    optional={
        "unidentifiable": Items(Fields({"name": Text(), "kind": Text()},
                                       optional={"partners": Items(Row((Text(), Number(null=True)))),
                                                 "message": Text()})),
        "rank": _COUNT, "condition_number": Number(low=0, null=True), "o1": Number(low=0, null=True),
        "o3": Number(low=0, null=True), "rms_um": Number(low=0, high=LARGEST, null=True),
        "noise_um": Number(low=0, high=LARGEST, open_low=True, null=True), "noise_source": Text(),
        "dof": Number(integer=True), "n_observations": _COUNT, "iterations": _COUNT, "success": Flag(),
        "message": Text(), "singular_values": Items(Number(low=0, null=True)),
        "set_aside": Items(Fields({}, optional={"line": Number(low=0, integer=True, null=True), "mark": Text(),
                                                "residual_um": _SIZE, "sigmas": Number(null=True)})),
        "axis_ranges": Table(Items(Number(low=-LARGEST, high=LARGEST, null=True), length=2, ordered=True)),
        "axis_readings": Table(Items(Number(low=-LARGEST, high=LARGEST))),
        "shared_std": Table(Items(Number(low=-LARGEST, high=LARGEST, null=True))),  # signed changes
        "prior": Text(), "prior_std": Items(_STD, null=True), "start": Text(), "stated_std": Fields({}, other=True),
        "implausible": Items(Fields({}, other=True)),
        "correlation": Items(Items(Number(low=-1.000001, high=1.000001, null=True)), null=True),
        "board_pose": Fields({}, optional={"passes": _COUNT, "move_um": Number(low=0, high=LARGEST, null=True),
                                           "noise_um": Number(low=0, high=LARGEST, null=True), "settled": Flag()}),
    },
    other=True)


def _finite(x):
    """A float for JSON, or None where it is not finite (JSON has no NaN or infinity)."""
    x = float(x)
    return x if np.isfinite(x) else None


def _finite_tree(x):
    """``x`` (dicts, lists, numbers, text) with every float finite or None, for JSON."""
    if isinstance(x, dict):
        return {str(k): _finite_tree(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite_tree(v) for v in x]
    return _finite(x) if isinstance(x, float) else x


def fit_to_dict(result: FitResult) -> dict:
    """The FIT.json object of ``result`` (docs/formats.md); every number finite or null."""
    params = []
    for n, v, s, u, ok in zip(result.param_names, result.values, result.std, result.units, result.identifiable):
        params.append({"name": n, "value": _finite(v) if ok else None, "std": _finite(s) if ok else None, "unit": u,
                       "identified": bool(ok)})
    return {
        "format": FIT_FORMAT,
        "machine": {"path": result.machine.path, "urdf": result.machine.urdf},
        "effects": list(result.effect_names),
        "parameters": params,
        "unidentifiable": [{"name": a.name, "kind": a.kind, "partners": [[p, _finite(c)] for p, c in a.partners],
                            "message": a.message} for a in result.aliases],
        "rank": result.rank,
        "condition_number": _finite(result.condition_number),
        "o1": _finite(result.o1),
        "o3": _finite(result.o3),
        "rms_um": _finite(result.rms_um),
        "noise_um": _finite(result.noise_um),
        "noise_source": result.noise_source,
        "dof": result.dof,
        "n_observations": result.n_observations,
        "iterations": result.iterations,
        "success": result.success,
        "message": result.message,
        "singular_values": [_finite(v) for v in result.singular_values],
        "set_aside": [{"line": a.line, "mark": a.mark, "residual_um": _finite(a.residual_um),
                       "sigmas": _finite(a.sigmas)} for a in result.set_aside],
        "axis_ranges": {k: [_finite(lo), _finite(hi)] for k, (lo, hi) in result.axis_ranges.items()},
        "axis_readings": {k: [float(x) for x in v] for k, v in result.axis_readings.items()},
        "shared_std": {k: [_finite(x) for x in v] for k, v in result.shared_std.items()},
        "prior": result.prior,
        "prior_std": None if result.prior_std is None else [_finite(v) for v in result.prior_std],
        "correlation": None if result.correlation is None else [[_finite(x) for x in row]
                                                                 for row in np.asarray(result.correlation)],
        "start": result.start,
        "stated_std": _finite_tree(result.stated_std),
        "board_pose": {k: _finite(v) if k.endswith("_um") else v for k, v in result.board_pose.items()},
        "implausible": [{"effect": a.effect, "size": _finite(a.size), "limit": a.limit, "unit": a.unit,
                         "undetermined": a.undetermined}
                        for a in result.implausible()],
    }


def _correlation(rows, n: int):
    """The parameters' correlation (n, n) as FIT.json keeps it (null where held), or None (an older file)."""
    if rows is None:
        return None
    out = np.array([[np.nan if x is None else float(x) for x in row] for row in rows], float)
    if out.shape != (n, n):
        raise ValueError(f"correlation is {out.shape[0]} rows of {out.shape[1] if out.ndim == 2 else '?'}, "
                         f"the parameters are {n}")
    return out


def save_fit(result: FitResult, path) -> None:
    """Write a fit as JSON (whole or not at all); it embeds the machine's URDF."""
    write_json(path, fit_to_dict(result))


def _number(data: dict, key: str) -> float:
    v = data.get(key)
    return float("nan") if v is None else float(v)


def load_fit(path) -> FitResult:
    """Read a fit written by :func:`save_fit` (its ``residuals_um`` is None).

    Raises
    ------
    DataError
        If the file is missing, not JSON, or not a kinid fit.
    """
    path = Path(path)
    data = read_json(path, what="fit file")
    if not isinstance(data, dict) or data.get("format") != FIT_FORMAT:
        raise DataError(f"not a kinid fit (expected \"format\": \"{FIT_FORMAT}\")", path=path)
    validate(data, FIT_SCHEMA, path=path)
    try:
        machine = machine_from_urdf(data["machine"]["urdf"], data["machine"].get("path", str(path)))
        effects = tuple(parse_effect(n, machine, source="effect") for n in data["effects"])
        params = data["parameters"]
        names = tuple(p["name"] for p in params)
        ok = np.array([bool(p["identified"]) for p in params], dtype=bool)
        values = np.array([float(p["value"]) if p["identified"] else np.nan for p in params])
        std = np.array([float(p["std"]) if p["identified"] and p.get("std") is not None else np.nan for p in params])
        units = tuple(str(p["unit"]) for p in params)
        aliases = tuple(Alias(str(a["name"]), str(a["kind"]), tuple((str(n), float(c)) for n, c in a.get("partners", ())),
                              str(a.get("message", ""))) for a in data.get("unidentifiable", ()))
        noise = Noise(_number(data, "noise_um"), str(data.get("noise_source", "given")))
        result = FitResult(
            machine=machine, effects=effects, param_names=names, units=units, values=values, std=std, identifiable=ok,
            aliases=aliases, rank=int(data.get("rank", int(ok.sum()))),
            condition_number=_number(data, "condition_number"), o1=_number(data, "o1"), o3=_number(data, "o3"),
            residuals_um=None, n_observations=int(data.get("n_observations", 0)),
            rms_um=_number(data, "rms_um"), noise=noise, dof=int(data.get("dof", 0)),
            iterations=int(data.get("iterations", 0)), success=bool(data.get("success", True)),
            message=str(data.get("message", "")),
            singular_values=np.array([np.nan if v is None else float(v) for v in data.get("singular_values", ())]),
            set_aside=tuple(SetAside(-1, None if a.get("line") is None else int(a["line"]), str(a.get("mark", "")),
                                     _number(a, "residual_um"), _number(a, "sigmas"))
                            for a in data.get("set_aside", ())),
            axis_ranges={str(k): (float(v[0]), float(v[1])) for k, v in data.get("axis_ranges", {}).items()
                         if str(k) in machine.axis_names and None not in v},
            axis_readings={str(k): np.unique(np.asarray(v, float)) for k, v in data.get("axis_readings", {}).items()
                           if str(k) in machine.axis_names and len(v)},
            shared_std={str(k): np.array([np.nan if x is None else float(x) for x in v])
                        for k, v in data.get("shared_std", {}).items()},
            prior=str(data.get("prior", "")),
            prior_std=None if data.get("prior_std") is None else np.array(
                [np.inf if v is None else float(v) for v in data["prior_std"]]),
            correlation=_correlation(data.get("correlation"), len(names)),
            start=str(data.get("start", "")), stated_std=dict(data.get("stated_std") or {}),
            board_pose={str(k): (np.nan if v is None else v) for k, v in data.get("board_pose", {}).items()})
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise DataError(f"malformed kinid fit ({exc.__class__.__name__}: {exc})", path=path) from None
    except KinidError as exc:
        raise DataError(f"malformed kinid fit: {exc}", path=path) from None
    if sum(e.n_params for e in effects) != len(names):
        raise DataError("malformed kinid fit: the parameters do not match the effects", path=path)
    return result


#: σ typed in mm instead of µm leaves a residual this many times σ, give or take the factor SIGMA_MM_SPREAD.
_SIGMA_MM_RATIO = 1000.0
_SIGMA_MM_SPREAD = 5.0


def _um(x: float) -> str:
    return f"{x:.4g}" if abs(x) < 1e4 else f"{x:.0f}"


def untrusted(result: FitResult, hints=()) -> str:
    """Why ``result`` cannot be trusted, as one clause with the likely mistake; "" if it can.

    A fit that did not converge, or whose residual RMS is more than :data:`~.noise.NOISE_RATIO_LIMIT` times
    the σ given (:func:`~.noise.noise_ratio`), is not a machine's errors; nor is one of data with a unit
    mistake, ``hints`` (:func:`kinid.identification.data.unit_hints`), however well it fits them (an effect
    such as a scale error can take an axis read in inches). The hints are named as the likely mistake;
    without one, a residual about 1000× σ names σ typed in mm.
    """
    ratio = noise_ratio(result.rms_um, result.noise)
    if not result.success:
        why = f"the fit did not converge in {result.iterations} iterations (residual RMS {_um(result.rms_um)} µm)"
    elif ratio > NOISE_RATIO_LIMIT:
        why = (f"the residual RMS {_um(result.rms_um)} µm is {ratio:.0f}× the σ given ({result.noise_um:g} µm; "
               f"refused beyond {NOISE_RATIO_LIMIT:g}×)")
    elif hints:
        why = f"the data hold a unit mistake (the fit leaves a residual RMS of {_um(result.rms_um)} µm)"
    else:
        return ""
    if hints:
        return f"{why}; likely {'; '.join(h.describe() for h in hints)}"
    if ratio > 0 and abs(np.log(ratio / _SIGMA_MM_RATIO)) <= np.log(_SIGMA_MM_SPREAD):
        return (f"{why}; likely σ typed in mm: --noise-um is in µm ({result.noise_um:g} mm is "
                f"{result.noise_um * 1000:g} µm)")
    if not result.success:
        odd = [o for o in implausible_effects(result) if not o.undetermined]
        if odd:
            return (f"{why}, with sizes no machine has ({'; '.join(o.describe() for o in odd[:3])}): the observations "
                    f"look inconsistent — a sensor offset or board file that is not the set-up measured, a camera "
                    f"model, a unit; check them before adding effects")
        return f"{why}; check the units of the marks and the readings and that the URDF is the machine measured"
    return (f"{why}; if σ is right, the model lacks an error far above the noise or the data hold gross errors: "
            f"fit without --noise-um (σ from the residuals) and run kinid diagnose")


def load_trusted_fit(path) -> FitResult:
    """:func:`load_fit`, refusing a fit that cannot be trusted (:func:`untrusted`: not converged, or a residual
    far above the σ given), such as an older file or one edited by hand: it must not reach a controller.

    Raises
    ------
    DataError
        Naming the file and why.
    """
    result = load_fit(path)
    why = untrusted(result)
    if why:
        raise DataError(f"{why}; a fit that cannot be trusted is not used: identify again", path=path)
    return result
