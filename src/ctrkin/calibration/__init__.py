"""Calibration of a real robot: tracker registration and the TCM parameters a lab identifies, fitted by
least squares to an imported dataset (`ctrkin calibrate`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "CalibrationResult": "ctrkin.calibration.fit", "calibrate": "ctrkin.calibration.fit",
    "leave_one_sequence_out": "ctrkin.calibration.fit", "CalibratedTCM": "ctrkin.calibration.model",
    "ParameterSet": "ctrkin.calibration.params",
}

__all__ = ["CalibratedTCM", "CalibrationResult", "ParameterSet", "calibrate", "leave_one_sequence_out"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.calibration.fit import CalibrationResult, calibrate, leave_one_sequence_out
    from ctrkin.calibration.model import CalibratedTCM
    from ctrkin.calibration.params import ParameterSet
