"""CiA 402 drives over CANopen: ctrkin's drive client against simulated drives that are real CANopen
nodes (canopen.LocalNode, an SDO server with ctrkin's EDS) on python-can's virtual bus. Both ends
are the canopen stack; nothing of ctrkin is replaced."""

from __future__ import annotations

import threading
import time

import canopen
import numpy as np
import pytest

from ctrkin.hardware import cia402 as c
from ctrkin.hardware.canopen_drive import CANopenActuator, Simulation
from ctrkin.hardware.cia402_sim import SimulatedBus, SimulatedDrive
from ctrkin.hardware.interfaces import HardwareError


@pytest.fixture
def remote():
    """One simulated drive (node 5) and a plain canopen client node for it."""
    drive = SimulatedDrive(5, counts_per_turn=1000.0, velocity_unit="counts/s", speedup=50.0,
                           stops=(-5000.0, 5000.0), start=1234.0)
    bus = SimulatedBus([drive], channel=f"test-remote-{id(drive)}")
    net = canopen.Network()
    net.connect(interface="virtual", channel=f"test-remote-{id(drive)}")
    node = net.add_node(5, str(c.EDS_FILE))
    yield drive, node
    net.disconnect()
    bus.close()


def _wait_word(node, test, timeout=5.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        word = node.sdo[c.STATUSWORD].raw
        if test(word):
            return word
        time.sleep(0.002)
    raise AssertionError(f"statusword 0x{word:04X} never matched")


def test_the_simulated_drive_follows_the_cia402_state_machine(remote):
    drive, node = remote
    assert node.sdo[0x1000].raw == 0x00020192                        # a CiA 402 device
    assert c.state(node.sdo[c.STATUSWORD].raw) == "switch on disabled"
    node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION                 # not allowed from here: no change
    assert c.state(node.sdo[c.STATUSWORD].raw) == "switch on disabled"
    for command, state in ((c.SHUTDOWN, "ready to switch on"), (c.SWITCH_ON, "switched on"),
                           (c.ENABLE_OPERATION, "operation enabled"), (c.QUICK_STOP, "quick stop active"),
                           (c.DISABLE_VOLTAGE, "switch on disabled")):
        node.sdo[c.CONTROLWORD].raw = command
        assert c.state(node.sdo[c.STATUSWORD].raw) == state
    drive.inject_fault(0x7300)
    assert c.state(node.sdo[c.STATUSWORD].raw) == "fault" and node.sdo[c.ERROR_CODE].raw == 0x7300
    node.sdo[c.CONTROLWORD].raw = c.FAULT_RESET
    assert c.state(node.sdo[c.STATUSWORD].raw) == "switch on disabled"


def test_profile_position_move_with_the_set_point_handshake(remote):
    _, node = remote
    for command in (c.SHUTDOWN, c.SWITCH_ON, c.ENABLE_OPERATION):
        node.sdo[c.CONTROLWORD].raw = command
    node.sdo[c.MODES_OF_OPERATION].raw = c.HOMING                   # home on the current position
    node.sdo[c.HOMING_METHOD].raw = 37
    node.sdo[c.HOME_OFFSET].raw = 100
    node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION | c.NEW_SETPOINT
    _wait_word(node, lambda w: w & c.SETPOINT_ACK and w & c.TARGET_REACHED)
    assert node.sdo[c.POSITION_ACTUAL].raw == 100                  # the position is the home offset now
    node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION
    node.sdo[c.MODES_OF_OPERATION].raw = c.PROFILE_POSITION
    node.sdo[c.TARGET_POSITION].raw = 2100
    node.sdo[c.PROFILE_VELOCITY].raw = 20000                         # counts/s: 0.1 s, 2 ms simulated x50
    node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION | c.NEW_SETPOINT
    word = _wait_word(node, lambda w: w & c.SETPOINT_ACK)
    node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION
    assert not node.sdo[c.STATUSWORD].raw & c.SETPOINT_ACK           # acknowledged, then released
    _wait_word(node, lambda w: w & c.TARGET_REACHED)
    assert node.sdo[c.POSITION_ACTUAL].raw == 2100 and word & c.SETPOINT_ACK
    node.sdo[0x607D][2].raw = 3000                                  # a target beyond the software limit
    node.sdo[c.TARGET_POSITION].raw = 4000
    node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION | c.NEW_SETPOINT
    assert c.state(node.sdo[c.STATUSWORD].raw) == "fault"
    assert node.sdo[c.POSITION_ACTUAL].raw == 2100                  # it never moved


def test_actuator_homes_moves_and_reads_encoders_in_joint_units(canopen_rig):
    act = CANopenActuator(canopen_rig, Simulation(canopen_rig))
    try:
        q = act.home()
        np.testing.assert_allclose(q, canopen_rig.home, atol=1e-2)
        target = np.array([30.0, -15.0, -25.0, -3.0])
        got = act.move(target, canopen_rig.velocity())
        # one encoder count is 360 / (4096 * 35) deg and 1 / (4096 * 5) mm
        count = np.array([360 / 4096 / 35] * 2 + [1 / 4096 / 5] * 2)
        assert (np.abs(got - target) <= count).all(), got - target
        np.testing.assert_allclose(act.read(), got)
        drives = act.simulation.bus.drives
        beta2 = drives[3]
        # direction -1: the encoder counts the other way
        assert beta2._get(c.TARGET_POSITION) == round(3.0 * 4096 * 5)
    finally:
        act.close()


def test_velocity_is_capped_at_the_drive_limit(canopen_rig):
    act = CANopenActuator(canopen_rig, Simulation(canopen_rig))
    try:
        act.home()
        act.move(np.array([20.0, 0.0, -20.0, 0.0]), np.array([1e6, 1e6, 1e6, 1e6]))   # asks far too much
        drive = act.simulation.bus.drives[0]
        rpm = drive._get(c.PROFILE_VELOCITY)
        cap = 90.0 * 4096 * 35 / 360 / 4096 * 60                   # 90 deg/s at the output, in motor rpm
        assert 0 < rpm <= round(cap)
    finally:
        act.close()


def test_stop_halts_a_move_in_progress_and_a_fault_is_reported(canopen_rig):
    act = CANopenActuator(canopen_rig, Simulation(canopen_rig))
    drives = act.simulation.bus.drives
    try:
        act.home()
        errors = []

        def slow_move():
            try:
                act.move(np.array([720.0, 0.0, -20.0, 0.0]), np.array([5.0, 5.0, 1.0, 1.0]))
            except HardwareError as e:
                errors.append(str(e))

        t = threading.Thread(target=slow_move)
        t.start()
        time.sleep(0.3)
        act.stop()
        t.join(10)
        assert errors and "stopped" in errors[0]
        a1 = act.read()[0]
        assert 0.0 < a1 < 720.0                       # halted on the way, not at the target
        time.sleep(0.1)
        assert act.read()[0] == a1                    # and it stays there
        assert drives[0].motion is None
        with pytest.raises(HardwareError, match="home them again"):
            act.move(np.array([0.0, 0.0, -20.0, 0.0]), canopen_rig.velocity())
        act.home()                                    # homing enables the drives again
        drives[2].inject_fault(0x8611)
        with pytest.raises(HardwareError, match=r"fault.*0x8611"):
            act.move(np.array([0.0, 0.0, -21.0, 0.0]), canopen_rig.velocity())
    finally:
        act.close()


def test_homing_on_a_mechanical_stop():
    drive = SimulatedDrive(7, counts_per_turn=100.0, velocity_unit="counts/s", stops=(-800.0, 800.0),
                           start=0.0, speedup=100.0)
    bus = SimulatedBus([drive], channel="test-homing-stop")
    net = canopen.Network()
    net.connect(interface="virtual", channel="test-homing-stop")
    node = net.add_node(7, str(c.EDS_FILE))
    try:
        for command in (c.SHUTDOWN, c.SWITCH_ON, c.ENABLE_OPERATION):
            node.sdo[c.CONTROLWORD].raw = command
        node.sdo[c.MODES_OF_OPERATION].raw = c.HOMING
        node.sdo[c.HOMING_METHOD].raw = -4                           # EPOS4: hard stop, negative speed
        node.sdo[c.HOME_OFFSET].raw = -50
        node.sdo[0x6099][1].raw = 4000
        node.sdo[c.CONTROLWORD].raw = c.ENABLE_OPERATION | c.NEW_SETPOINT
        _wait_word(node, lambda w: w & c.SETPOINT_ACK and w & c.TARGET_REACHED)
        assert drive.mechanical == -800.0 and node.sdo[c.POSITION_ACTUAL].raw == -50
    finally:
        net.disconnect()
        bus.close()


def test_sdo_transactions_from_two_threads_do_not_take_each_others_responses(canopen_rig):
    """A move polls its drives while stop() writes to them from another thread: without one SDO
    transaction at a time, a read could take a write's response ("Unexpected response 0x60")."""
    act = CANopenActuator(canopen_rig, Simulation(canopen_rig))
    try:
        errors: list[str] = []
        rpm = act._read(0, c.PROFILE_VELOCITY)

        def reads():
            try:
                for _ in range(300):
                    act.read()
            except HardwareError as e:
                errors.append(str(e))

        t = threading.Thread(target=reads)
        t.start()
        try:
            for _ in range(300):
                act._write(0, c.PROFILE_VELOCITY, rpm)      # a write that changes nothing
        except HardwareError as e:
            errors.append(str(e))
        t.join(30)
        assert not t.is_alive() and errors == []
    finally:
        act.close()
