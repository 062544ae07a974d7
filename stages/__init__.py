"""Stage models, simulators and calibration routines."""
