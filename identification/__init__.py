"""Identification of machine kinematic errors from alignment observations.

The few names a machine builder needs; everything else lives in the sub-packages, one per concept
(``kinid.identification.model``, ``.data``, ``.fitting``, ``.diagnosis``, ``.planning``, ``.compensation``,
``.reporting``, ``.commands``; docs/architecture.md):

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

#: Each public name and the sub-package whose front door gives it. The module that defines it is imported
#: on first use of the name (PEP 562), so that importing the package (for instance to build the ``kinid``
#: command line's parsers) does not import Pinocchio, CasADi or SciPy.
_SOURCES = {
    "load_machine": "model", "tool_in_workpiece_mm": "model", "parse_effect": "model", "default_model": "model",
    "urdf_builder": "model",
    "read_observations": "data", "write_observations": "data",
    "fit": "fitting", "save_fit": "fitting", "load_fit": "fitting", "solve_axes": "fitting",
    "simulate": "fitting", "load_errors": "fitting",
    "diagnose": "diagnosis", "forward_select": "diagnosis",
}

__all__ = ["load_machine", "read_observations", "write_observations", "parse_effect", "default_model", "fit",
           "save_fit", "load_fit", "diagnose", "forward_select", "solve_axes", "simulate", "load_errors",
           "tool_in_workpiece_mm", "urdf_builder"]


#: ``fit``, ``diagnose`` and ``simulate`` stay the functions after their modules of the same name load
#: (in the sub-packages' front doors as well).
__getattr__, __dir__ = _front_door(__name__, _SOURCES)
