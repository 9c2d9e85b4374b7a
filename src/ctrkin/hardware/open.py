"""Build the actuator and tracker a rig file describes (the implementations are imported only
when used: the CANopen and NDI libraries are an extra)."""

from __future__ import annotations

from ctrkin.hardware.interfaces import Actuator, Tracker
from ctrkin.hardware.rig import RigDescription


def open_rig(rig: RigDescription) -> tuple[Actuator, Tracker]:
    """(actuator, tracker) of `rig`, not yet started: the virtual robot, replayed logs, CANopen
    drives (real, or simulated with `simulate = true`) and an NDI tracker (or the virtual one
    over simulated drives, a dry run)."""
    a, t = rig.actuator, rig.tracker
    if a.kind == "replay":
        from ctrkin.hardware.replay import replay_rig

        return replay_rig(rig)
    inner: Actuator | None = None
    if a.kind == "canopen":
        from ctrkin.hardware.canopen_drive import CANopenActuator, Simulation

        inner = CANopenActuator(rig, Simulation(rig) if a.simulate else None)
    if t.kind == "virtual":
        from ctrkin.hardware.virtual import virtual_rig

        actuator, tracker, _ = virtual_rig(rig, inner)
        return actuator, tracker
    from ctrkin.hardware.interfaces import HardwareError
    from ctrkin.hardware.ndi import NDITracker

    if inner is None:         # parse_rig allows a real tracker only with CANopen drives
        raise HardwareError(f"{rig.source}: an NDI tracker needs CANopen drives ([actuator] kind)")
    return inner, NDITracker(t, rig.folder)
