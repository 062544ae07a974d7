"""The fit: the model pass and its residuals, the Levenberg-Marquardt step, identifiability, σ, leverages,
gross errors, the prior, the held-out check, and what the fitted machine predicts (the axis readings
that align it with a mark, simulated runs); FIT.json.

Imports :mod:`~kinid.identification.model` and :mod:`~kinid.identification.data`.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "solve_axes": "alignment", "MIN_GAIN_SE": "crossval", "cross_validate": "crossval", "FitResult": "fit",
    "fit": "fit", "model_effects": "fit", "load_fit": "fit_file", "load_trusted_fit": "fit_file",
    "save_fit": "fit_file", "untrusted": "fit_file", "analyse": "identifiability", "axis_residuals": "leverage",
    "hat_diagonal": "leverage", "model_pass": "leverage", "noise_from_replicates": "leverage",
    "studentized": "leverage", "NOISE_RATIO_LIMIT": "noise", "Noise": "noise", "noise_ratio": "noise",
    "resolve_noise": "noise", "set_aside_outliers": "outliers", "set_aside_with_fit": "outliers",
    "PRIOR_UM": "prior", "PRIOR_URAD": "prior", "choose_prior": "prior", "held_out_check": "prior",
    "prior_std": "prior", "pose_folds": "prior", "design": "residuals", "effect_columns": "residuals",
    "joint_values": "residuals",
    "residuals": "residuals", "PATENT_MARKS_MM": "simulate", "errors_from_mapping": "simulate",
    "load_errors": "simulate", "load_plan": "simulate", "patent_plan": "simulate", "simulate": "simulate",
    "Start": "start", "closed_form_start": "start", "rigid_transform": "start",
    "ORIENTATION_LIMIT_DEG": "orientation", "OrientationCheck": "orientation", "check_orientation": "orientation",
    "OrientationResiduals": "orientation", "orientation_residuals": "orientation",
    "tool_rotations": "residuals", "rotation_residual_urad": "residuals",
}

__all__ = ["FitResult", "MIN_GAIN_SE", "NOISE_RATIO_LIMIT", "Noise", "ORIENTATION_LIMIT_DEG", "OrientationCheck",
           "OrientationResiduals", "PATENT_MARKS_MM", "PRIOR_UM", "PRIOR_URAD", "Start", "analyse",
           "axis_residuals", "check_orientation", "choose_prior", "closed_form_start", "cross_validate", "design",
           "effect_columns", "errors_from_mapping", "fit", "hat_diagonal", "held_out_check", "joint_values",
           "load_errors", "load_fit", "load_plan", "load_trusted_fit", "model_effects", "model_pass",
           "noise_from_replicates", "noise_ratio", "orientation_residuals", "patent_plan", "pose_folds", "prior_std",
           "residuals", "resolve_noise", "rigid_transform", "rotation_residual_urad", "save_fit",
           "set_aside_outliers", "set_aside_with_fit", "simulate", "solve_axes", "studentized", "tool_rotations",
           "untrusted"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
