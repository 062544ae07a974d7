"""Identification of machine kinematic errors from alignment observations.

The few names a machine builder needs; everything else lives in the modules
(``kinid.identification.fit``, ``.diagnose``, ...):

- :func:`load_machine` — a URDF with ISO 230-1 error joints (docs/machines.md);
- :func:`read_observations`, :func:`write_observations` — the observation CSV (docs/formats.md);
- :func:`parse_effect`, :func:`default_model` — effects (docs/formats.md);
- :func:`fit`, :func:`save_fit`, :func:`load_fit` — identification and FIT.json;
- :func:`diagnose`, :func:`forward_select` — where the model fails and what is missing;
- :func:`solve_axes` — the axis readings that align the fitted machine with each mark;
- :func:`simulate`, :func:`load_errors` — synthetic data from a known error set;
- :func:`tool_in_workpiece_mm` — nominal or erroneous kinematics of one pose;
- :mod:`urdf_builder` — write machine URDFs with error joints (docs/machines.md).

Example
-------
>>> from kinid.identification import load_machine, read_observations, fit   # doctest: +SKIP
>>> machine = load_machine("urdf/five_axis_bc.urdf")                         # doctest: +SKIP
>>> result = fit(machine, read_observations("obs.csv", machine), noise_um=1.0)  # doctest: +SKIP
"""
from importlib import import_module

#: Public name -> the module that defines it. Imported on first use, so that
#: ``import kinid.identification`` stays cheap (scipy.stats, for one, is only
#: needed by the diagnosis).
_EXPORTS = {
    "load_machine": ".machine", "tool_in_workpiece_mm": ".machine",
    "read_observations": ".observations", "write_observations": ".observations",
    "parse_effect": ".effects", "default_model": ".effects",
    "fit": ".fit", "save_fit": ".fit", "load_fit": ".fit",
    "diagnose": ".diagnose", "forward_select": ".diagnose",
    "solve_axes": ".alignment",
    "simulate": ".simulate", "load_errors": ".simulate",
    "urdf_builder": None,
}

__all__ = list(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = _EXPORTS[name]
    value = import_module(f".{name}", __name__) if module is None else getattr(import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
