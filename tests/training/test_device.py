"""`--device auto|cpu|cuda` (ctrkin.training.device, issue 26 goal 4), on a machine without CUDA: cpu
and auto train exactly what the CPU trained before; cuda is refused with a message that says what to
pass; the copy-on-a-device path of the engine (Adam stepping a copy whose weights come back after every
epoch) gives the same weights as training the network in place, for the paper's model and the
snap-aware one (whose loss draws its augmentation on the CPU)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.errors import ModelError
from ctrkin.evaluation.scales import ReproduceConfig
from ctrkin.models.store import read_json
from ctrkin.training import TrainConfig, train
from ctrkin.training import engine as engine_module
from ctrkin.training.device import resolve_device

pytestmark = pytest.mark.skipif(torch.cuda.is_available(), reason="checks the behaviour without CUDA")


def _weights(folder) -> dict[str, np.ndarray]:
    state = torch.load(folder / "weights.pt", map_location="cpu", weights_only=True)
    return {k: v.numpy() for k, v in state.items()}


def test_resolve_without_cuda():
    assert resolve_device("cpu") == (torch.device("cpu"), None)
    device, note = resolve_device("auto")
    assert device == torch.device("cpu") and note is not None and "CPU" in note
    with pytest.raises(ModelError, match="--device cpu"):
        resolve_device("cuda")
    with pytest.raises(ModelError, match="device must be one of"):
        resolve_device("tpu")


def test_configs_validate_device():
    with pytest.raises(ModelError, match="device"):
        TrainConfig(device="gpu")
    with pytest.raises(Exception, match="device"):
        ReproduceConfig(device="gpu")
    with pytest.raises(Exception, match="Ray tasks reserve CPUs only"):
        ReproduceConfig(device="cuda", executor="ray")
    # the device is how, not what, is trained: a run may resume or be reused on another device
    assert TrainConfig(device="cpu").differences(TrainConfig(device="cuda")) == []


CASES = {"paper": TrainConfig(task="fk", max_epochs=2, threads=1, batch_size=64,
                              options={"structure": "L8|D8"}),
         "branch": TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=2, threads=1, batch_size=64,
                               options={"structure": "L8|D8", "gate_units": 4})}


@pytest.mark.parametrize("case", sorted(CASES))
def test_copy_on_device_equals_in_place(case, sweeps, tmp_path, monkeypatch):
    """The engine's device path, run on the CPU (a copy stepped and synced back each epoch), trains the
    same weights bit for bit as training the bundle's network itself, and the auto note is logged."""
    cfg = CASES[case]
    said: list[str] = []
    train(sweeps, cfg, tmp_path / "in_place", progress=False, log=said.append)
    assert any("no CUDA device" in s for s in said)
    monkeypatch.setattr(engine_module, "_needs_copy", lambda device: True)
    train(sweeps, cfg, tmp_path / "copy", progress=False)
    a, b = _weights(tmp_path / "in_place"), _weights(tmp_path / "copy")
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    ha = (tmp_path / "in_place" / "history.csv").read_text().splitlines()
    hb = (tmp_path / "copy" / "history.csv").read_text().splitlines()
    assert [r.split(",")[:3] for r in ha] == [r.split(",")[:3] for r in hb]      # epoch, train, val loss


def test_cpu_and_auto_train_the_same(sweeps, tmp_path):
    cfg = CASES["paper"]
    train(sweeps, cfg, tmp_path / "auto", progress=False)
    from dataclasses import replace

    train(sweeps, replace(cfg, device="cpu"), tmp_path / "cpu", progress=False)
    a, b = _weights(tmp_path / "auto"), _weights(tmp_path / "cpu")
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert read_json(tmp_path / "cpu" / "config.json")["train"]["device"] == "cpu"


def test_cli_cuda_refused_and_auto_falls_back(sweeps, tmp_path):
    data = tmp_path / "data"
    sweeps.save(data)
    runner = CliRunner()
    res = runner.invoke(cli, ["train", "--task", "fk", "--data", str(data), "--out", str(tmp_path / "m"),
                              "--device", "cuda", "--epochs", "1", "--structure", "L8|D8"])
    assert res.exit_code == 1, res.output
    assert "--device cuda" in res.output and "--device cpu" in res.output
    assert not (tmp_path / "m" / "weights.pt").exists()
    res = runner.invoke(cli, ["train", "--task", "fk", "--data", str(data), "--out", str(tmp_path / "m"),
                              "--device", "auto", "--epochs", "1", "--structure", "L8|D8", "--threads", "1"])
    assert res.exit_code == 0, res.output
    assert "no CUDA device found, training on the CPU" in res.output
    res = runner.invoke(cli, ["reproduce", "--scale", "tiny", "--device", "cuda",
                              "--out", str(tmp_path / "r")])
    assert res.exit_code == 1 and "--device cuda" in res.output
    assert not (tmp_path / "r").exists()
