"""Calibration of a real robot: tracker registration and the TCM parameters a lab identifies, fitted by
least squares to an imported dataset (`ctrkin calibrate`)."""

from ctrkin.calibration.fit import CalibrationResult, calibrate, leave_one_sequence_out
from ctrkin.calibration.model import CalibratedTCM
from ctrkin.calibration.params import ParameterSet

__all__ = ["CalibratedTCM", "CalibrationResult", "ParameterSet", "calibrate", "leave_one_sequence_out"]
