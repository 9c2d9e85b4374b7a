"""`ctrkin collect --rig RIG.toml`: a protocol on a rig (ctrkin.acquisition.rig_recorder).

--out is the collection's folder: its journal (readings.csv, rig_session.json) and the dataset
built from it (data.parquet, meta.json). The output rule, as for `train`: the same command resumes
the collection in --out; another collection there needs --overwrite, which replaces only the files
a collection writes; any other non-empty folder is refused.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ctrkin.cli.common import emit_json, output_folder, say
from ctrkin.errors import CtrkinError
from ctrkin.util.folders import folder_lock

if TYPE_CHECKING:
    from ctrkin.acquisition.plan import Plan
    from ctrkin.acquisition.rig_recorder import RigCollection
    from ctrkin.robots import Robot


def collect_on_rig(rig_file: str, protocol: str, plan_for: Callable[[Robot], Plan], out_dir: str,
                   overwrite: bool, as_json: bool) -> None:
    """Run `protocol`, planned by plan_for(the rig's robot), on the rig `rig_file` describes into
    out_dir (resumed where its journal is; --overwrite starts over)."""
    from ctrkin.acquisition.rig_recorder import (
        OWNED_FILES,
        SESSION_FILE,
        RigCollection,
        RigInterrupted,
        write_dataset,
    )
    from ctrkin.hardware import RigDescription, open_rig
    from ctrkin.hardware.interfaces import HardwareError, RigStop

    rig = RigDescription.from_toml(rig_file)
    out = Path(out_dir)
    resuming = (out / SESSION_FILE).is_file() and not overwrite
    # the ownership rule of every output (a rig's journal counts as the dataset's own files)
    output_folder(out, "dataset", overwrite, inputs=[rig_file], reuse=resuming)
    plan = plan_for(rig.robot)
    with folder_lock(out, CtrkinError, "collect"):
        if overwrite:
            for name in OWNED_FILES:            # only what a collection writes, never anything else
                (out / name).unlink(missing_ok=True)
        actuator, tracker = open_rig(rig)
        collection = RigCollection(plan, rig, actuator, tracker, out, progress=True,
                                   log=lambda m: click.echo(m, err=True))
        try:
            ds = collection.run()
        except (RigInterrupted, RigStop, HardwareError) as e:
            kept = _write_partial(collection, out)
            click.echo(f"{'stopped' if isinstance(e, RigInterrupted) else 'error'}: {e}", err=True)
            if kept:
                click.echo(f"the {kept} samples recorded so far are in {out} (data.parquet, meta.json: "
                           "collection.complete = false)", err=True)
            sys.exit(130 if isinstance(e, RigInterrupted) else 1)
        write_dataset(ds, out)
    f = ds.frame
    say(f"{protocol} on rig {rig.name}: {len(f)} samples in {f['sequence_id'].nunique()} sequences, "
        f"{int(f['readings_rejected'].sum())} readings refused by the safety rules; wrote {out}")
    if as_json:
        emit_json({"protocol": protocol, "rig": rig.name, "robot": rig.robot.name, "samples": len(f),
                   "sequences": int(f["sequence_id"].nunique()),
                   "readings_rejected": int(f["readings_rejected"].sum()),
                   "complete": ds.meta["collection"]["complete"], "out": out})


def _write_partial(collection: RigCollection, out: Path) -> int:
    """Write the dataset of what the journal holds; returns its samples (0: nothing yet)."""
    from ctrkin.acquisition.rig_recorder import write_dataset
    from ctrkin.hardware.interfaces import HardwareError

    try:
        ds = collection.dataset(complete=False)
    except HardwareError:
        return 0
    write_dataset(ds, out)
    return len(ds.frame)
