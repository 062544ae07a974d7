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
from kinid.lazy import front_door as _front_door

#: Each public name and the module of this package that defines it. The module is imported on first
#: use of the name (PEP 562), so that importing the package (for instance to build the ``kinid``
#: command line's parsers) does not import Pinocchio, CasADi or SciPy.
_SOURCES = {
    "load_machine": "machine", "tool_in_workpiece_mm": "machine",
    "read_observations": "observations", "write_observations": "observations",
    "parse_effect": "effects", "default_model": "effects",
    "fit": "fit", "save_fit": "fit_file", "load_fit": "fit_file",
    "diagnose": "diagnose", "forward_select": "selection", "solve_axes": "alignment",
    "simulate": "simulate", "load_errors": "simulate",
}

__all__ = ["load_machine", "read_observations", "write_observations", "parse_effect", "default_model", "fit",
           "save_fit", "load_fit", "diagnose", "forward_select", "solve_axes", "simulate", "load_errors",
           "tool_in_workpiece_mm", "urdf_builder"]


#: ``fit``, ``diagnose`` and ``simulate`` stay the functions after their modules of the same name load.
__getattr__, __dir__ = _front_door(__name__, _SOURCES)
