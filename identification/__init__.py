"""Identification of machine kinematic errors from alignment observations."""
