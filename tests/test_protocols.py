"""The simulated stages implement the hardware protocols, and the stage methods accept any object that does."""
import numpy as np
import pytest

from kinid.errors import StageError
from kinid.stages.backlash import SimulatedStage
from kinid.stages.dual_axis import SimulatedGantry
from kinid.stages.protocols import ActuatorStage, CameraStage, DualAxisGantry
from kinid.stages.uvw import SimulatedUVWStage, calibrate


def test_simulators_satisfy_their_protocols():
    assert isinstance(SimulatedStage(rng=np.random.default_rng(0)), CameraStage)
    assert isinstance(SimulatedGantry(rng=np.random.default_rng(0)), DualAxisGantry)
    assert isinstance(SimulatedUVWStage(rng=np.random.default_rng(0)), ActuatorStage)
    assert not isinstance(SimulatedUVWStage(rng=np.random.default_rng(0)), CameraStage)


def test_uvw_calibrate_takes_the_stage_object_or_its_move():
    by_object = calibrate(SimulatedUVWStage(noise_um=0.0, rng=np.random.default_rng(3)), lead_um=2000.0, repeats=1,
                          actuators=("X1",), harmonics=1, degree=1)
    by_function = calibrate(SimulatedUVWStage(noise_um=0.0, rng=np.random.default_rng(3)).move, lead_um=2000.0,
                            repeats=1, actuators=("X1",), harmonics=1, degree=1)
    assert by_object.command("X1", 1234.0) == pytest.approx(by_function.command("X1", 1234.0), abs=1e-9)


def test_uvw_calibrate_names_a_stage_without_move():
    with pytest.raises(StageError, match="stage must have a move"):
        calibrate(object(), lead_um=2000.0)
