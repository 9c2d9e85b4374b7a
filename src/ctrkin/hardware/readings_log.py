"""The raw log of a rig collection: every tracker reading with the joints it was taken at.

One CSV row a reading (header on the first line):

    run, sequence, step, reading, used, time,
    cmd_alpha_1 .. cmd_beta_N          commanded joints (deg, mm)
    enc_alpha_1 .. enc_beta_N          encoder joints after the move (deg, mm)
    tool1_status, tool1_x, tool1_y, tool1_z, tool1_qw, tool1_qx, tool1_qy, tool1_qz, tool1_error,
    tool2_... (one block per tool)     tracker frame, mm; status as hardware.interfaces.STATUSES

`used` is 1 for the readings averaged into the sample, 0 for those a safety rule refused (a tool
missing or out of volume); `time` is the host's wall clock (s since the epoch). The readings of one
sample are appended in one write and flushed to disk, so the log is the collection's journal: a
resumed collection reads it to know where it stopped, and the dataset is built from it. A last
line cut by a crash is ignored. The replay device (replay.py) plays such a log back.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ctrkin.hardware.interfaces import HardwareError, TrackerFrame

TOOL_FIELDS = ("status", "x", "y", "z", "qw", "qx", "qy", "qz", "error")
INDEX_FIELDS = ("run", "sequence", "step", "reading", "used", "time")


def header(joints: list[str], n_tools: int) -> list[str]:
    return [*INDEX_FIELDS, *(f"cmd_{j}" for j in joints), *(f"enc_{j}" for j in joints),
            *(f"tool{k + 1}_{f}" for k in range(n_tools) for f in TOOL_FIELDS)]


@dataclass(eq=False)
class LoggedSample:
    """One configuration's readings. key: (run, sequence, step); command, encoder: (2N,);
    frames: every reading taken; used: (R,) bool, averaged into the sample; times: (R,) s."""

    key: tuple[int, int, int]
    command: np.ndarray
    encoder: np.ndarray
    frames: list[TrackerFrame] = field(default_factory=list)
    used: list[bool] = field(default_factory=list)
    times: list[float] = field(default_factory=list)


class ReadingsLog:
    """Append samples to (and read them back from) a readings log at `path`."""

    def __init__(self, path: Path, joints: list[str], n_tools: int) -> None:
        self.path, self.joints, self.n_tools = Path(path), list(joints), int(n_tools)
        self.columns = header(self.joints, self.n_tools)

    def start(self) -> None:
        """Create the file with its header if it does not exist."""
        if not self.path.exists() or self.path.stat().st_size == 0:
            self._append(",".join(self.columns) + "\n")

    def _append(self, text: str) -> None:
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, text.encode())
            os.fsync(fd)
        finally:
            os.close(fd)

    def append(self, sample: LoggedSample) -> None:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        for r, (frame, used, t) in enumerate(zip(sample.frames, sample.used, sample.times, strict=True)):
            row: list[object] = [*sample.key, r, int(used), repr(float(t)),
                                 *(repr(float(v)) for v in (*sample.command, *sample.encoder))]
            for k in range(self.n_tools):
                row += [frame.status[k], *(repr(float(v)) for v in (*frame.poses[k], frame.error[k]))]
            w.writerow(row)
        self._append(buf.getvalue())

    def read(self) -> list[LoggedSample]:
        """The samples in the log, in order (a partial last line is dropped)."""
        if not self.path.is_file():
            return []
        text = self.path.read_text()
        if text and not text.endswith("\n"):
            text = text[: text.rfind("\n") + 1]          # a line cut by a crash
        rows = list(csv.reader(io.StringIO(text)))
        if not rows:
            return []
        if rows[0] != self.columns:
            raise HardwareError(f"{self.path}: its columns are not those of this rig and robot "
                                f"({len(rows[0])} columns, expected {len(self.columns)}); it was written "
                                "by another rig file; use another --out or --overwrite")
        n = len(self.joints)
        out: list[LoggedSample] = []
        for line, row in enumerate(rows[1:], start=2):
            if len(row) != len(self.columns):
                raise HardwareError(f"{self.path}: line {line} has {len(row)} fields, expected "
                                    f"{len(self.columns)}")
            try:
                key = (int(row[0]), int(row[1]), int(row[2]))
                used, t = row[4] == "1", float(row[5])
                cmd = np.array([float(v) for v in row[6:6 + n]])
                enc = np.array([float(v) for v in row[6 + n:6 + 2 * n]])
                tools = row[6 + 2 * n:]
                poses = np.array([[float(v) for v in tools[9 * k + 1:9 * k + 8]]
                                  for k in range(self.n_tools)])
                err = np.array([float(tools[9 * k + 8]) for k in range(self.n_tools)])
            except ValueError as e:
                raise HardwareError(f"{self.path}: line {line}: {e}") from None
            status = tuple(tools[9 * k] for k in range(self.n_tools))
            if not out or out[-1].key != key:
                out.append(LoggedSample(key, cmd, enc))
            s = out[-1]
            s.frames.append(TrackerFrame(t, poses, status, err))
            s.used.append(used)
            s.times.append(t)
        return out

    def rewrite(self, samples: list[LoggedSample]) -> None:
        """Replace the log by `samples` (drops an incomplete last sample before a resume)."""
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        tmp.write_text(",".join(self.columns) + "\n")
        keep, self.path = self.path, tmp
        try:
            for s in samples:
                self.append(s)
        finally:
            self.path = keep
        os.replace(tmp, self.path)
