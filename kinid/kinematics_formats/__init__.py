"""The rotary axes' geometry written as a controller's kinematics description (docs/compensation.md).

- :mod:`kinid.kinematics_formats.geometry` — :class:`RotaryGeometry`: per rotary axis its pivot point and
  direction at home, nominal and calibrated, and the kinematic type;
- :mod:`kinid.kinematics_formats.formats` — the kinematics formats' registry (:func:`register_kinematics_format`);
- :mod:`kinid.kinematics_formats.sinumerik` — SINUMERIK swivel data for CYCLE800 (``$TC_CARR``);
- :mod:`kinid.kinematics_formats.linuxcnc` — LinuxCNC trunnion kinematics (``xyz[ab]c-trt-kins``).
"""
from .formats import (KINEMATICS_FORMATS, KinematicsFit, KinematicsFormat, default_kinematics_formats,
                      kinematics_format, register_kinematics_format)
from .geometry import KINDS, LinearAxisMapping, RotaryAxisGeometry, RotaryGeometry
from .linuxcnc import linuxcnc_trt_text, trt_parameters
from .sinumerik import sinumerik_swivel_text, swivel_vectors

__all__ = ["KINDS", "KINEMATICS_FORMATS", "KinematicsFit", "KinematicsFormat", "LinearAxisMapping",
           "RotaryAxisGeometry", "RotaryGeometry", "default_kinematics_formats", "kinematics_format",
           "linuxcnc_trt_text", "register_kinematics_format", "sinumerik_swivel_text", "swivel_vectors",
           "trt_parameters"]
