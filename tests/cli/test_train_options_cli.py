"""`ctrkin train` options are generated from TrainConfig (ctrkin.cli.from_config): every field is
reachable, with the dataclass's default, and the option names of earlier versions still work."""

from __future__ import annotations

import dataclasses
from typing import Any

import click
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.cli.train import ALIASES, DEFAULTS, REQUIRED, train_cmd
from ctrkin.training import TrainConfig

# every option `ctrkin train` had before its options were generated, with the field it sets
EARLIER_OPTIONS = {
    "--task": "task", "--model": "model", "--ib": "ib", "--no-delta": "delta", "--angles": "angle_encoding",
    "--output-activation": "output_activation", "--pose": "pose_source", "--split": "split",
    "--epochs": "max_epochs", "--patience": "patience", "--batch-size": "batch_size", "--lr": "lr",
    "--lr-schedule": "lr_schedule", "--loop": "loop", "--val-smoothing": "val_smoothing",
    "--max-seconds": "max_seconds", "--seed": "seed", "--threads": "threads",
}
EARLIER_OTHERS = ("--list-models", "--data", "--out", "--structure", "--option", "--overwrite", "--json")
HAND_SET = {"options": ("--structure", "--option")}     # fields the command sets from other options


def _options() -> dict[str, click.Option]:
    return {p.name: p for p in train_cmd.params if isinstance(p, click.Option) and p.name}


def _other_value(option: click.Option, default: Any) -> tuple[list[str], Any]:
    """Command-line words giving `option` a value other than `default`, and that value."""
    if option.is_flag:
        return [option.secondary_opts[0] if default else option.opts[0]], not default
    if isinstance(option.type, click.Choice):
        value = next(c for c in option.type.choices if c != default)
        return [option.opts[0], str(value)], value
    if option.type is click.INT:           # an optional int (max_epochs: None, the adaptive budget) too
        value = 7 if default is None else default + 1
        return [option.opts[0], str(value)], value
    if option.type is click.FLOAT:
        value = 0.25 if default is None else default + 0.25
        return [option.opts[0], str(value)], value
    return [option.opts[0], "other"], "other"


def test_every_field_of_train_config_is_reachable_from_the_command_line() -> None:
    options = _options()
    for f in dataclasses.fields(TrainConfig):
        if f.name in HAND_SET:
            assert set(HAND_SET[f.name]) <= {o for p in options.values() for o in p.opts}
            continue
        assert f.name in options, f"TrainConfig.{f.name} has no `ctrkin train` option"
        default = TrainConfig().to_dict()[f.name]
        words, value = _other_value(options[f.name], default)
        params = train_cmd.make_context("train", ["--task", "ik", "--data", ".", "--out", "m", *words]).params
        assert params[f.name] == value, (f.name, words)


def test_defaults_are_the_dataclass_defaults_but_for_the_stated_overrides() -> None:
    options = _options()
    defaults = TrainConfig().to_dict() | {"target_frame": None}     # None: the model's own frame
    for name, option in options.items():
        if name not in defaults:
            continue                                  # --data, --out, --structure, ...
        if name in REQUIRED:
            assert option.required, name
        elif name in DEFAULTS:                        # --model: the task's recommended model (issue 23)
            assert option.default == DEFAULTS[name] and not option.required, name
        else:
            assert option.default == defaults[name] and not option.required, name
        assert option.help, name


def test_every_earlier_option_name_sets_the_same_field() -> None:
    options = _options()
    names = {o for p in options.values() for o in (*p.opts, *p.secondary_opts)}
    assert set(EARLIER_OPTIONS) | set(EARLIER_OTHERS) <= names
    for opt, field_name in EARLIER_OPTIONS.items():
        assert opt in (*options[field_name].opts, *options[field_name].secondary_opts), opt
    assert {opt for opts in ALIASES.values() for opt in opts} <= set(EARLIER_OPTIONS)
    help_text = CliRunner().invoke(cli, ["train", "--help"]).output
    assert all(opt in help_text for opt in names)
    assert help_text.rstrip().splitlines()[-1].strip().startswith("ctrkin train --task fk")   # example last


@pytest.fixture
def ran(monkeypatch, tmp_path) -> dict[str, Any]:
    """`ctrkin train` with the training replaced by a recorder: what reached TrainConfig."""
    import ctrkin.cli.train as train_module

    seen: dict[str, Any] = {}

    class _Data:
        def __init__(self) -> None:
            self.meta: dict[str, Any] = {}

    def fake_train(ds: Any, cfg: TrainConfig, out: str, **_kw: Any) -> Any:
        seen["cfg"] = cfg
        metrics = {"training": {"epochs": 1, "best_epoch": 1, "best_val_loss": 0.0, "seconds": 0.0}}
        return type("R", (), {"out": out, "metrics": metrics})()

    monkeypatch.setattr("ctrkin.training.train", fake_train)
    monkeypatch.setattr(train_module.Dataset, "load", staticmethod(lambda _d: _Data()))
    (tmp_path / "data").mkdir()     # beside, not around, the model folder: --out inside --data is refused
    seen["data"], seen["out"] = str(tmp_path / "data"), str(tmp_path / "model")
    return seen


def test_the_earlier_command_line_gives_the_same_config(ran) -> None:
    # --model named: without it `ctrkin train` now trains the task's recommended model (issue 23)
    res = CliRunner().invoke(cli, [
        "train", "--task", "fk", "--model", "lstm_mlp", "--data", ran["data"], "--out", ran["out"],
        "--epochs", "3", "--no-delta",
        "--angles", "sincos", "--pose", "true", "--structure", "L8|D8", "--threads", "1", "--seed", "4",
        "--max-seconds", "60", "--lr", "2e-3"], env={"CTRKIN_NO_PROGRESS": "1"})
    assert res.exit_code == 0, res.output
    assert ran["cfg"] == TrainConfig(task="fk", max_epochs=3, delta=False, angle_encoding="sincos",
                                     pose_source="true", options={"structure": "L8|D8"}, threads=1, seed=4,
                                     max_seconds=60.0, lr=2e-3)


def test_model_options_are_typed(ran) -> None:
    res = CliRunner().invoke(cli, [
        "train", "--task", "fk", "--model", "cnn", "--data", ran["data"], "--out", ran["out"],
        "--option", "channels=8"], env={"CTRKIN_NO_PROGRESS": "1"})
    assert res.exit_code == 0, res.output
    assert ran["cfg"].options == {"channels": 8} and ran["cfg"].model == "cnn"
    assert ran["cfg"].to_dict() == {**TrainConfig(model="cnn").to_dict(), "options": {"channels": 8}}


def test_a_setting_without_a_value_is_a_usage_error(ran) -> None:
    res = CliRunner().invoke(cli, ["train", "--task", "fk", "--data", ran["data"], "--out", ran["out"],
                                   "--option", "channels"])
    assert res.exit_code == 2 and "cfg" not in ran
    assert "Invalid value for --option: expected KEY=VALUE, got 'channels'" in res.stderr
    res = CliRunner().invoke(cli, ["train", "--data", ran["data"], "--out", ran["out"]])
    assert res.exit_code == 2 and "Missing option '--task'" in res.stderr


@pytest.mark.parametrize(("setting", "words"), [
    ("noise_mm", "expected KEY=VALUE, got 'noise_mm'"),
    ("readings_per_sample=2.5", "readings_per_sample: '2.5' is not a valid integer"),
    ("noise=0.1", "unknown key 'noise'"),
    ("noise_mm=-1", "noise_mm"),                               # VirtualConfig's own check
])
def test_collect_settings_share_the_parser(tmp_path, setting: str, words: str) -> None:
    res = CliRunner().invoke(cli, ["collect", "--protocol", "sweeps", "--set", setting,
                                   "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "Invalid value for --set:" in res.stderr and words in res.stderr
    assert not (tmp_path / "x").exists()
