"""Planning a measurement: the pool of candidate poses, the design that reaches a stated accuracy with
the fewest alignments, their order for machine time, advice on poses for held parameters, and the alignments that
settle what the data hint at (suspects).

Imports model, data and fitting.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "advice_lines": "advice", "advice_pool": "advice", "data_advice": "advice", "Augmented": "augment",
    "augment_plan": "augment", "fit_volume_u_um": "augment", "TravelModel": "order", "plan_measurement": "plan",
    "tool_point_u_um": "plan", "axis_motion": "pool", "candidate_jacobian": "pool", "candidate_poses": "pool",
    "solved_axes": "pool", "Suspect": "suspects", "suspects_of": "suspects",
}

__all__ = ["Augmented", "Suspect", "TravelModel", "advice_lines", "advice_pool", "augment_plan", "axis_motion",
           "candidate_jacobian", "candidate_poses", "data_advice", "fit_volume_u_um", "plan_measurement",
           "solved_axes", "suspects_of", "tool_point_u_um"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
