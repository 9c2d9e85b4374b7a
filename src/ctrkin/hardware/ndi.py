"""NDI Aurora, Polaris and Vega trackers through NDI's Combined API, as the `ndicapi` package's
`ndicapy` module exposes it (the PLUS toolkit's C library; `pip install ctrkin[hardware]`).

The sequence is the one of NDI's API guide and of scikit-surgery's `sksurgerynditracker`: open the
serial port (`ndiProbe`/`ndiOpen`, Aurora and Polaris) or the network (`ndiOpenNetwork`, Vega),
`INIT:`, `COMM:` (serial: 115200 baud, 8N1, no handshake); for every tool definition file a port
handle (`PHRQ:*********1****`, `ndiGetPHRQHandle`) and its ROM (`ndiPVWRFromFile`); an Aurora's
wired sensors announce themselves instead (`PHSR:02`); every handle initialised (`PINIT:%02X`) and
enabled as dynamic (`PENA:%02XD`); `TSTART:`. A reading is `BX:0801` (transforms and status), then
per handle `ndiGetBXTransform` — (q0, qx, qy, qz, x, y, z, rms) or "MISSING"/"DISABLED" — and
`ndiGetBXPortStatus` (bit 0x40 out of volume, 0x80 partially out of volume). `ndicapy` is imported
on `start()`, never at module import, so ctrkin works without it.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.hardware.interfaces import (
    DISABLED,
    MISSING,
    OK,
    OUT_OF_VOLUME,
    PARTIAL,
    HardwareError,
    Tracker,
    TrackerFrame,
)
from ctrkin.hardware.rig import TrackerSpec

PORTS_TO_PROBE = 20
BAUD_115200, FORMAT_8N1, NO_HANDSHAKE = 5, 0, 0   # ndicapy.NDI_115200, NDI_8N1, NDI_NOHANDSHAKE
OUT_OF_VOLUME_BIT, PARTIAL_BIT = 0x40, 0x80       # ndicapy.NDI_OUT_OF_VOLUME, NDI_PARTIALLY_IN_VOLUME


def import_ndicapy() -> Any:
    try:
        return importlib.import_module("ndicapy")
    except ImportError:
        raise HardwareError("the NDI tracker needs NDI's Combined API library: pip install "
                            "'ctrkin[hardware]' (the ndicapi package)") from None


class NDITracker(Tracker):
    """spec: the rig file's [tracker] table; folder: where its ROM files are; capi: the ndicapy
    module (None: imported on start()); clock: the host clock for frame times (s)."""

    def __init__(self, spec: TrackerSpec, folder: Path = Path("."), capi: Any = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.spec, self.folder, self.capi, self.clock = spec, folder, capi, clock
        self.device: Any = None
        self.handles: list[int] = []
        self.n_tools = max(len(spec.tools), spec.sensor_tool, spec.reference_tool)

    def _check(self, what: str) -> None:
        err = self.capi.ndiGetError(self.device)
        if err != self.capi.NDI_OKAY:
            raise HardwareError(f"NDI {self.spec.device}: {what} failed: {self.capi.ndiErrorString(err)}")

    def _command(self, text: str, *args: Any) -> Any:
        reply = self.capi.ndiCommand(self.device, text, *args)
        self._check(text % args if args else text)
        return reply

    def _open(self) -> None:
        capi, spec = self.capi, self.spec
        if spec.device == "vega":
            self.device = capi.ndiOpenNetwork(spec.host, spec.network_port)
            where = f"{spec.host}:{spec.network_port}"
        else:
            names = [spec.port] if spec.port else [capi.ndiDeviceName(i) for i in range(PORTS_TO_PROBE)]
            name = next((n for n in names if n and capi.ndiProbe(n) == capi.NDI_OKAY), None)
            if name is None:
                raise HardwareError(f"no NDI {spec.device} answered on {spec.port or 'any serial port'}: "
                                    "is it connected, switched on, and may this user open the port "
                                    "(Linux: the dialout group)?")
            self.device = capi.ndiOpen(name)
            where = name
        if not self.device:
            raise HardwareError(f"could not open the NDI {spec.device} at {where}")

    def start(self) -> None:
        self.capi = self.capi or import_ndicapy()
        self._open()
        self._command("INIT:")
        if self.spec.device != "vega":
            self._command("COMM:%d%03d%d", BAUD_115200, FORMAT_8N1, NO_HANDSHAKE)
        handles = []
        for rom in self.spec.tools:
            path = Path(rom) if Path(rom).is_absolute() else self.folder / rom
            if not path.is_file():
                raise HardwareError(f"tool definition file {path} does not exist ([tracker] tools)")
            self._command("PHRQ:*********1****")
            h = int(self.capi.ndiGetPHRQHandle(self.device))
            self.capi.ndiPVWRFromFile(self.device, h, str(path))
            self._check(f"loading {path.name} into port {h:02X}")
            handles.append(h)
        if not handles:       # an Aurora's wired sensors need no ROM: take the ports it reports
            self._command("PHSR:02")
            n = int(self.capi.ndiGetPHSRNumberOfHandles(self.device))
            handles = [int(self.capi.ndiGetPHSRHandle(self.device, i)) for i in range(n)]
        if len(handles) < self.n_tools:
            raise HardwareError(f"NDI {self.spec.device}: {len(handles)} tool(s) found, the rig file names "
                                f"tool {self.n_tools} ([tracker] sensor_tool / reference_tool); connect "
                                "the sensor or list its .rom in tools")
        for h in handles:
            self._command("PINIT:%02X", h)
            self._command("PENA:%02X%c", h, "D")
        self.handles = handles
        self._command("TSTART:")

    def read(self) -> TrackerFrame:
        if self.device is None:
            raise HardwareError("the NDI tracker is not started")
        self._command("BX:%04X", 0x0801)
        t = self.clock()
        k = self.n_tools
        poses = np.full((k, 7), np.nan)
        err = np.full(k, np.nan)
        status = []
        for i, h in enumerate(self.handles[:k]):
            port = bytes([h])
            xf = self.capi.ndiGetBXTransform(self.device, port)
            if isinstance(xf, str):
                status.append(MISSING if xf == "MISSING" else DISABLED)
                continue
            bits = int(self.capi.ndiGetBXPortStatus(self.device, port))
            status.append(OUT_OF_VOLUME if bits & OUT_OF_VOLUME_BIT
                          else PARTIAL if bits & PARTIAL_BIT else OK)
            q0, qx, qy, qz, x, y, z, rms = (float(v) for v in xf)
            poses[i] = (x, y, z, q0, qx, qy, qz)
            err[i] = rms
        return TrackerFrame(t, poses, tuple(status), err)

    def stop(self) -> None:
        if self.device is None:
            return
        device, self.device = self.device, None
        try:
            self.capi.ndiCommand(device, "TSTOP:")
        finally:
            if self.spec.device == "vega":
                self.capi.ndiCloseNetwork(device)
            else:
                self.capi.ndiClose(device)
