"""`ctrkin collect --rig`: the output rule (resume the same collection, refuse a foreign folder,
--overwrite replaces only what a collection writes) and the dry run of a CANopen rig file."""

from __future__ import annotations

import json
import os
from pathlib import Path

from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.data import Dataset

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "rigs"


def _collect(*args: str):
    return CliRunner().invoke(cli, ["collect", "--protocol", "sweeps", "--levels", "4", *args])


def test_collect_on_the_virtual_rig_and_the_output_rule(tmp_path):
    rig = str(EXAMPLES / "virtual.toml")
    out = tmp_path / "data"
    r = _collect("--rig", rig, "--out", str(out), "--json")
    assert r.exit_code == 0, r.output
    summary = json.loads(r.stdout[r.stdout.index("{"):])
    assert summary["samples"] == 721 and summary["complete"]
    ds = Dataset.load(out)
    assert ds.meta["rig"]["name"] == "virtual-paper" and "tracker_status" in ds.frame
    assert ds.frame["snap"].dtype == bool
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    # the output rule of every command (issue 27): a folder of the user's is never written into,
    # with or without --overwrite (until the fsafe merge a rig collection wrote beside notes.txt)
    for extra in ((), ("--overwrite",)):
        r = _collect("--rig", rig, "--out", str(foreign), *extra)
        assert r.exit_code == 1 and "not a ctrkin output" in r.output
        assert os.listdir(foreign) == ["notes.txt"] and (foreign / "notes.txt").read_text() == "mine"
    r = CliRunner().invoke(cli, ["collect", "--protocol", "sweeps", "--levels", "8", "--rig", rig,
                                 "--out", str(out)])
    assert r.exit_code == 1 and "another protocol" in r.output
    assert len(Dataset.load(out).frame) == 721                   # the collection there is untouched
    r = _collect("--rig", rig, "--out", str(tmp_path / "x"), "--set", "noise_mm=0.1", "--robot-seed", "2")
    assert r.exit_code == 2 and "--robot-seed, --set: not used with --rig" in r.output


def test_dry_run_of_the_paper_rig_drives_simulated_canopen_nodes(tmp_path):
    r = CliRunner().invoke(cli, ["collect", "--rig", str(EXAMPLES / "paper_dry_run.toml"), "--protocol",
                                 "random-points", "--n-points", "1", "--seed", "2", "--out",
                                 str(tmp_path / "dry")])
    assert r.exit_code == 0, r.output
    ds = Dataset.load(tmp_path / "dry")
    # the encoders report counts: 64 per motor turn, 64 turns per tube turn
    step = 360 / 64 / 64
    a = ds.frame["alpha_1"].to_numpy()
    assert abs(a / step - (a / step).round()).max() < 1e-6
