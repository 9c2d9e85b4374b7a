"""The NDI tracker adapter against a fake of the documented `ndicapy` API, only at that boundary:
the fake answers the calls NDI's Combined API guide and scikit-surgery's nditracker make, with the
same argument kinds (a port handle is one byte for the BX getters) and return values (a transform
tuple (q0, qx, qy, qz, x, y, z, rms) or "MISSING"/"DISABLED", a port status bit field). The real
module, installed with the hardware extra, must offer every function the fake stands in for."""

from __future__ import annotations

import importlib.util
from types import SimpleNamespace

import numpy as np
import pytest

from ctrkin.hardware.interfaces import MISSING, OK, OUT_OF_VOLUME, PARTIAL, HardwareError
from ctrkin.hardware.ndi import NDITracker
from ctrkin.hardware.rig import TrackerSpec


class FakeCapi:
    """ndicapy as documented: a device object from ndiOpen / ndiOpenNetwork, text commands, and
    getters for the reply of the last BX command."""

    NDI_OKAY = 0

    def __init__(self, ports: dict[int, object], status: dict[int, int] | None = None,
                 serial: list[str] | None = None) -> None:
        self.ports, self.status = ports, status or {}
        self.serial = serial if serial is not None else ["/dev/ttyUSB0"]
        self.commands: list[str] = []
        self.loaded: dict[int, str] = {}
        self.closed = False
        self._next = 0x0A

    def ndiDeviceName(self, i: int) -> str | None:
        return self.serial[i] if i < len(self.serial) else None

    def ndiProbe(self, name: str) -> int:
        assert isinstance(name, str)
        return 0 if name in self.serial else 1

    def ndiOpen(self, name: str) -> object:
        return SimpleNamespace(kind="serial", name=name)

    def ndiOpenNetwork(self, host: str, port: int) -> object:
        assert isinstance(host, str) and isinstance(port, int)
        return SimpleNamespace(kind="network", name=host)

    def ndiCommand(self, device: object, fmt: str, *args: object) -> str:
        assert device is not None
        self.commands.append(fmt % args if args else fmt)
        return "OKAY"

    def ndiGetError(self, device: object) -> int:
        return 0

    def ndiErrorString(self, err: int) -> str:
        return f"error {err}"

    def ndiGetPHRQHandle(self, device: object) -> int:
        self._next += 1
        return self._next

    def ndiPVWRFromFile(self, device: object, handle: int, path: str) -> int:
        assert isinstance(handle, int) and isinstance(path, str)
        self.loaded[handle] = path
        return 0

    def ndiGetPHSRNumberOfHandles(self, device: object) -> int:
        return len(self.ports)

    def ndiGetPHSRHandle(self, device: object, i: int) -> int:
        return sorted(self.ports)[i]

    def ndiGetBXTransform(self, device: object, port: bytes) -> object:
        assert isinstance(port, bytes) and len(port) == 1          # a C char in the wrapper
        return self.ports[port[0]]

    def ndiGetBXPortStatus(self, device: object, port: bytes) -> int:
        assert isinstance(port, bytes) and len(port) == 1
        return self.status.get(port[0], 0x31)        # occupied, initialised, enabled

    def ndiClose(self, device: object) -> None:
        self.closed = True

    def ndiCloseNetwork(self, device: object) -> None:
        self.closed = True


def test_aurora_sensors_are_found_enabled_and_read_with_their_status():
    xf = (0.9, 0.1, 0.2, 0.3, 10.0, -20.0, -300.0, 0.12)
    capi = FakeCapi({0x01: xf, 0x02: "MISSING", 0x03: xf}, status={0x03: 0x31 | 0x40})
    spec = TrackerSpec(kind="ndi", device="aurora", sensor_tool=1, reference_tool=3)
    tr = NDITracker(spec, capi=capi, clock=lambda: 12.5)
    tr.start()
    assert capi.commands[:2] == ["INIT:", "COMM:50000"]                  # 115200 baud, 8N1, no handshake
    assert "PHSR:02" in capi.commands and capi.commands[-1] == "TSTART:"
    assert [c for c in capi.commands if c.startswith(("PINIT", "PENA"))] == [
        "PINIT:01", "PENA:01D", "PINIT:02", "PENA:02D", "PINIT:03", "PENA:03D"]
    f = tr.read()
    assert capi.commands[-1] == "BX:0801"
    assert f.time == 12.5 and f.status == (OK, MISSING, OUT_OF_VOLUME)
    np.testing.assert_allclose(f.poses[0], [10.0, -20.0, -300.0, 0.9, 0.1, 0.2, 0.3])
    assert np.isnan(f.poses[1]).all() and f.error[0] == pytest.approx(0.12)
    assert f.ok(0) and not f.ok(1) and not f.ok(2) and f.ok(2, accept=(OK, OUT_OF_VOLUME))
    tr.stop()
    assert capi.commands[-1] == "TSTOP:" and capi.closed
    tr.stop()                                                          # twice is harmless


def test_polaris_loads_its_tool_files_and_partial_volume_is_reported(tmp_path):
    roms = []
    for name in ("tip.rom", "ref.rom"):
        (tmp_path / name).write_bytes(b"\x00" * 16)
        roms.append(name)
    xf = (1.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 0.2)
    capi = FakeCapi({0x0B: xf, 0x0C: xf}, status={0x0C: 0x31 | 0x80})
    spec = TrackerSpec(kind="ndi", device="polaris", port="/dev/ttyUSB0", tools=tuple(roms),
                       sensor_tool=1, reference_tool=2)
    tr = NDITracker(spec, folder=tmp_path, capi=capi)
    tr.start()
    assert capi.loaded == {0x0B: str(tmp_path / "tip.rom"), 0x0C: str(tmp_path / "ref.rom")}
    assert capi.commands.count("PHRQ:*********1****") == 2 and "PHSR:02" not in capi.commands
    assert tr.read().status == (OK, PARTIAL)


def test_vega_opens_the_network_and_errors_say_what_to_do(tmp_path):
    capi = FakeCapi({0x0B: "DISABLED"})
    (tmp_path / "tip.rom").write_bytes(b"\x00")
    spec = TrackerSpec(kind="ndi", device="vega", host="10.0.0.5", tools=("tip.rom",))
    tr = NDITracker(spec, folder=tmp_path, capi=capi)
    tr.start()
    assert "COMM:50000" not in capi.commands
    assert tr.read().status == ("disabled",)
    missing = NDITracker(TrackerSpec(kind="ndi", device="polaris", tools=("nope.rom",)), folder=tmp_path,
                         capi=FakeCapi({}))
    with pytest.raises(HardwareError, match=r"nope\.rom does not exist"):
        missing.start()
    nobody = NDITracker(TrackerSpec(kind="ndi", device="aurora"), capi=FakeCapi({}, serial=[]))
    with pytest.raises(HardwareError, match="dialout"):
        nobody.start()
    too_few = NDITracker(TrackerSpec(kind="ndi", device="aurora", sensor_tool=2),
                         capi=FakeCapi({1: "MISSING"}))
    with pytest.raises(HardwareError, match="1 tool"):
        too_few.start()


@pytest.mark.skipif(importlib.util.find_spec("ndicapy") is None,
                    reason="ndicapi (hardware extra) not installed")
def test_the_real_ndicapy_offers_what_the_fake_stands_in_for():
    import ndicapy

    used = [n for n in dir(FakeCapi) if n.startswith("ndi") or n == "NDI_OKAY"]
    assert not [n for n in used if not hasattr(ndicapy, n)]
    assert ndicapy.NDI_OKAY == 0 and ndicapy.NDI_OUT_OF_VOLUME == 0x40
    assert ndicapy.NDI_PARTIALLY_IN_VOLUME == 0x80
    assert (ndicapy.NDI_115200, ndicapy.NDI_8N1, ndicapy.NDI_NOHANDSHAKE) == (5, 0, 0)
