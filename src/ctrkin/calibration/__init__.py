"""Calibration of a real robot: tracker registration and the TCM parameters a lab identifies, fitted by
least squares to an imported dataset (`ctrkin calibrate`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["CalibratedTCM", "CalibrationResult", "ParameterSet", "calibrate", "leave_one_sequence_out"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.calibration.fit import CalibrationResult, calibrate, leave_one_sequence_out
    from ctrkin.calibration.model import CalibratedTCM
    from ctrkin.calibration.params import ParameterSet

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
