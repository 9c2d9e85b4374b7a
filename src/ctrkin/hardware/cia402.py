"""CiA 402 (CANopen drives and motion control) as ctrkin uses it: object indices, the power state
machine of the controlword / statusword, and the profile position and homing modes. One table for
the drive client (canopen_drive.py) and the simulated drive (cia402_sim.py).

State machine (CiA 402 part 2, Fig. "Finite state automaton"), statusword bits 0-3, 5, 6:

    Switch on disabled  xxxx xxxx x1xx 0000      controlword Shutdown 0x06 -> Ready to switch on
    Ready to switch on  xxxx xxxx x01x 0001      Switch on 0x07 -> Switched on
    Switched on         xxxx xxxx x01x 0011      Enable operation 0x0F -> Operation enabled
    Operation enabled   xxxx xxxx x01x 0111      Quick stop 0x0B -> Quick stop active
    Quick stop active   xxxx xxxx x00x 0111      Disable voltage 0x00 -> Switch on disabled
    Fault               xxxx xxxx x0xx 1000      Fault reset (bit 7 rising) -> Switch on disabled

Profile position (mode 1): target 0x607A and profile velocity 0x6081 are taken on a rising edge of
controlword bit 4 (new set-point; bit 5 change immediately, bit 6 relative), acknowledged by
statusword bit 12; bit 10 is set when the target is reached. Homing (mode 6): bit 4 starts it,
statusword bit 12 "homing attained" with bit 10 when done, bit 13 a homing error.
"""

from __future__ import annotations

from pathlib import Path

EDS_FILE = Path(__file__).resolve().parent / "data" / "cia402_pp.eds"

CONTROLWORD = 0x6040
STATUSWORD = 0x6041
MODES_OF_OPERATION = 0x6060
MODES_DISPLAY = 0x6061
POSITION_ACTUAL = 0x6064
VELOCITY_ACTUAL = 0x606C
TARGET_POSITION = 0x607A
HOME_OFFSET = 0x607C
SOFTWARE_LIMITS = 0x607D
PROFILE_VELOCITY = 0x6081
HOMING_METHOD = 0x6098
ERROR_CODE = 0x603F

PROFILE_POSITION = 1
HOMING = 6

SHUTDOWN = 0x0006
SWITCH_ON = 0x0007
ENABLE_OPERATION = 0x000F
QUICK_STOP = 0x000B
DISABLE_VOLTAGE = 0x0000
FAULT_RESET = 0x0080
NEW_SETPOINT = 0x0010         # bit 4: new set-point (pp) / start homing (hm)
CHANGE_IMMEDIATELY = 0x0020   # bit 5
HALT = 0x0100                 # bit 8

TARGET_REACHED = 1 << 10
SETPOINT_ACK = 1 << 12        # homing attained in homing mode
HOMING_ERROR = 1 << 13
FAULT_BIT = 1 << 3

STATE_MASKS = {   # state: (mask, value) over bits 0-3, 5, 6
    "switch on disabled": (0x4F, 0x40),
    "ready to switch on": (0x6F, 0x21),
    "switched on": (0x6F, 0x23),
    "operation enabled": (0x6F, 0x27),
    "quick stop active": (0x6F, 0x07),
    "fault": (0x4F, 0x08),
}
STATE_WORDS = {name: value for name, (_, value) in STATE_MASKS.items()}


def state(statusword: int) -> str:
    """The power state a statusword reports ("not ready" when none matches)."""
    for name, (mask, value) in STATE_MASKS.items():
        if statusword & mask == value:
            return name
    return "not ready to switch on"
