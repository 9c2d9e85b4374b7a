"""ctrkin.cli.from_config: options generated from a dataclass, and the one KEY=VALUE parser."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import click
import pytest
from click.testing import CliRunner

from ctrkin.cli.from_config import config_options, option_help, parse_key_values


def _help(text: str) -> dict[str, str]:
    return {"help": text}


@dataclass(frozen=True)
class Settings:
    count: int = field(default=3, metadata=_help("How many."))
    rate: float = field(default=0.5, metadata=_help("How fast."))
    name: str = field(default="a", metadata=_help("Which one."))
    mode: Literal["x", "y"] = field(default="x", metadata=_help("x or y."))
    limit: float | None = field(default=None, metadata=_help("Upper bound, or none."))
    check: bool = field(default=True, metadata=_help("Check it."))
    extra: dict[str, Any] = field(default_factory=dict, metadata=_help("Anything else."))


def _command(**kw: Any) -> click.Command:
    @click.command()
    @config_options(Settings, exclude=("extra",), **kw)
    def cmd(**settings: Any) -> None:
        click.echo(repr(Settings(**settings)))

    return cmd


def _params(cmd: click.Command, args: list[str]) -> dict[str, Any]:
    return cmd.make_context("cmd", args).params


def test_each_field_is_an_option_with_its_type_default_and_help() -> None:
    cmd = _command()
    options = {p.name: p for p in cmd.params if isinstance(p, click.Option)}
    assert list(options) == ["count", "rate", "name", "mode", "limit", "check"]      # field order
    assert _params(cmd, []) == {"count": 3, "rate": 0.5, "name": "a", "mode": "x", "limit": None,
                                "check": True}
    given = _params(cmd, ["--count", "4", "--rate", "1e-2", "--name", "b", "--mode", "y", "--limit", "2",
                          "--no-check"])
    assert given == {"count": 4, "rate": 0.01, "name": "b", "mode": "y", "limit": 2.0, "check": False}
    text = CliRunner().invoke(cmd, ["--help"]).output
    for words in ("--count INTEGER", "How many.", "[default: 3]", "--mode [x|y]", "--check / --no-check",
                  "Upper bound, or none."):
        assert words in text


@dataclass(frozen=True)
class Levels:
    levels: tuple[float, ...] = field(default=(8.0, 20.0), metadata=_help("Which levels."))
    names: tuple[str, ...] | None = field(default=None, metadata=_help("Which names, or none."))


def test_a_tuple_field_is_a_comma_separated_list() -> None:
    @click.command()
    @config_options(Levels)
    def cmd(**settings: Any) -> None:
        click.echo(repr(Levels(**settings)))

    assert _params(cmd, ["--names", "a,b"])["names"] == ("a", "b") and _params(cmd, [])["names"] is None
    assert _params(cmd, [])["levels"] == (8.0, 20.0)
    assert _params(cmd, ["--levels", "4, 12,20"])["levels"] == (4.0, 12.0, 20.0)
    assert "[default: 8.0,20.0]" in CliRunner().invoke(cmd, ["--help"]).output
    with pytest.raises(click.BadParameter):
        _params(cmd, ["--levels", "4,x"])


def test_bad_values_are_usage_errors() -> None:
    cmd = _command()
    for args in (["--count", "2.5"], ["--mode", "z"], ["--rate", "fast"]):
        res = CliRunner().invoke(cmd, args)
        assert res.exit_code == 2 and "Invalid value" in res.stderr, args


def test_aliases_required_and_other_defaults() -> None:
    cmd = _command(aliases={"count": ("--n",)}, required=("name",), defaults={"rate": 2.0})
    assert _params(cmd, ["--n", "7", "--name", "c"])["count"] == 7
    assert _params(cmd, ["--count", "7", "--name", "c"])["rate"] == 2.0
    res = CliRunner().invoke(cmd, [])
    assert res.exit_code == 2 and "Missing option '--name'" in res.stderr


def test_a_field_the_command_line_cannot_take_must_be_excluded() -> None:
    with pytest.raises(TypeError, match=r"Settings.extra: .* exclude it"):
        config_options(Settings)

    @dataclass(frozen=True)
    class Undocumented:
        count: int = 1

    with pytest.raises(TypeError, match=r"Undocumented\.count has no help"):
        config_options(Undocumented)
    with pytest.raises(TypeError, match="no fields"):
        config_options(Settings, exclude=("extra", "nope"))


def test_key_values_are_typed_by_their_look_without_a_config() -> None:
    got = parse_key_values(["a=1", "b=-2", "c=0.5", "d=1e-3", "e=true", "f=False", "g=L128|D64", "h=",
                            " i =x=y"], "--option")
    assert got == {"a": 1, "b": -2, "c": 0.5, "d": 1e-3, "e": True, "f": False, "g": "L128|D64", "h": "",
                   "i": "x=y"}
    assert isinstance(got["a"], int) and isinstance(got["c"], float)
    assert parse_key_values([], "--option") == {}


def test_key_values_are_typed_by_the_config() -> None:
    got = parse_key_values(["count=2", "rate=1", "name=7", "mode=y", "limit=none", "check=no"], "--set",
                           Settings)
    assert got == {"count": 2, "rate": 1.0, "name": "7", "mode": "y", "limit": None, "check": False}
    assert isinstance(got["rate"], float)


@pytest.mark.parametrize(("item", "words"), [
    ("count", "expected KEY=VALUE, got 'count'"),
    ("=3", "expected KEY=VALUE, got '=3'"),
    ("nope=1", "unknown key 'nope'"),
    ("extra=1", "unknown key 'extra'"),
    ("count=2.5", "count: '2.5' is not a valid integer"),
    ("mode=z", "mode: 'z' is not one of 'x', 'y'"),
])
def test_bad_key_values_are_one_usage_error(item: str, words: str) -> None:
    with pytest.raises(click.BadParameter) as caught:
        parse_key_values([item], "--set", Settings)
    assert caught.value.exit_code == 2
    assert words in caught.value.format_message() and "--set" in caught.value.format_message()


@pytest.mark.parametrize(("command", "config", "own"), [
    ("ctrkin.cli.train:train_cmd", "ctrkin.training.config:TrainConfig",
     {"options": ("structure", "model_options")}),
    ("ctrkin.cli.dataset:import_cmd", "ctrkin.data.import_config:ImportConfig",
     {"mapping": ("maps",), "quaternion_columns": ("quat_cols",), "sequence_gap": ("gap_text",),
      "cleaning": ("keep_outliers", "no_average")}),
    ("ctrkin.cli.reproduce:reproduce_cmd", "ctrkin.evaluation.scales:ReproduceConfig",
     {"virtual": ("settings",)}),
    ("ctrkin.cli.dataset:split_cmd", "ctrkin.cli.dataset:SplitConfig", {}),
    ("ctrkin.cli.collect:collect_cmd", "ctrkin.cli.collect:CollectConfig", {}),
    ("ctrkin.cli.mechanics:solve_cmd", "ctrkin.cli.mechanics:SolveConfig", {}),
    ("ctrkin.cli.mechanics:sweep_cmd", "ctrkin.cli.mechanics:SweepConfig", {}),
    *((f"ctrkin.cli.{module}:{command}", f"ctrkin.cli.{module}:{config}", {}) for module, command, config in (
        ("plan", "plan_cmd", "PlanCommandConfig"), ("calibrate", "calibrate_cmd", "CalibrateConfig"),
        ("evaluate", "evaluate_cmd", "EvaluateConfig"), ("predict", "predict_cmd", "PredictConfig"),
        ("show", "show_cmd", "ShowConfig"), ("export", "export_cmd", "ExportConfig"),
        ("robot", "template_cmd", "TemplateConfig"), ("dataset", "info_cmd", "InfoConfig"))),
])
def test_commands_take_every_field_of_their_config(command: str, config: str, own: dict) -> None:
    """Each field of the command's configuration is an option of the command (with the field's help
    where the command generates it), or one the command reads into that field itself (`own`)."""
    import dataclasses
    import importlib

    def load(spec: str) -> Any:
        module, name = spec.split(":")
        return getattr(importlib.import_module(module), name)

    cmd, cfg = load(command), load(config)
    params = {p.name: p for p in cmd.params}
    for f in dataclasses.fields(cfg):
        if f.name in own:
            assert all(p in params for p in own[f.name]), f.name
        elif isinstance(params.get(f.name), click.Argument):       # arguments have no help of their own
            assert f.metadata.get("argument"), f.name
        else:
            assert f.name in params, f.name
            assert params[f.name].help == f.metadata["help"], f.name


def test_the_reproduce_config_names_every_scale_and_refuses_bad_values() -> None:
    from typing import get_args

    from ctrkin.errors import CtrkinError
    from ctrkin.evaluation.scales import SCALES, ReproduceConfig, Scale

    assert set(get_args(Scale)) == set(SCALES)
    with pytest.raises(CtrkinError, match="workers"):
        ReproduceConfig(workers=0)
    with pytest.raises(CtrkinError, match="executor"):
        ReproduceConfig(executor="cluster")  # type: ignore[arg-type]


@dataclass(frozen=True)
class Bounded:
    points: int | None = field(default=None, metadata={"range": (1, 100), **_help("How many points.")})
    step: float = field(default=1.0, metadata={"range": (1e-3, 360.0), **_help("Step (deg).")})


def test_a_field_range_bounds_its_option() -> None:
    @click.command()
    @config_options(Bounded)
    def cmd(**settings: Any) -> None:
        click.echo(repr(Bounded(**settings)))

    assert _params(cmd, ["--points", "100", "--step", "360"]) == {"points": 100, "step": 360.0}
    assert _params(cmd, []) == {"points": None, "step": 1.0}
    runner = CliRunner()
    for args, option in ((["--points", "0"], "--points"), (["--points", "101"], "--points"),
                         (["--step", "0"], "--step"), (["--step", "361"], "--step")):
        res = runner.invoke(cmd, args)
        assert res.exit_code == 2 and option in res.output and "range" in res.output, (args, res.output)


def test_a_range_on_a_field_that_is_not_a_number_is_refused() -> None:
    @dataclass(frozen=True)
    class Wrong:
        name: str = field(default="a", metadata={"range": (1, 2), **_help("A name.")})

    with pytest.raises(TypeError, match="range applies to int and float"):
        config_options(Wrong)


# Options a command adds beside its configuration's: the shared output options, and where a command's
# line reads into a field of its configuration (or of a library configuration) by hand.
SHARED = {"overwrite", "force", "as_json", "settings"}      # --overwrite, --force, --json, --set
OWN = {
    "train": {"list_models", "data_dir", "out_dir", "structure", "model_options"},
    "dataset import": {"log_files", "robot_spec", "profile_file", "out_dir", "maps", "units", "quat_cols",
                       "gap_text", "keep_outliers", "no_average"},
    "collect": {"protocol", "rig_file", "out_dir"},
    "reproduce": {"out"},
    "plan": {"out_dir"},
    "sweep": {"out_dir"},
}


def _commands() -> dict[str, click.Command]:
    from ctrkin.cli.main import COMMANDS, cli

    ctx = click.Context(cli)
    out = {}
    for name in COMMANDS:
        cmd = cli.get_command(ctx, name)
        assert cmd is not None
        subs = cmd.commands if isinstance(cmd, click.Group) else {"": cmd}
        out |= {f"{name} {sub}".strip(): c for sub, c in subs.items()}
    return out


def test_every_command_is_generated_from_its_configuration() -> None:
    """Each command of `ctrkin` (sub-commands included) takes its options from a typed configuration
    (ctrkin.cli.from_config.config_options); beside them only the shared output options and the
    hand-read options listed in OWN."""
    import dataclasses

    from ctrkin.cli.from_config import CONFIG

    commands = _commands()
    assert {"calibrate", "evaluate", "predict", "show", "export", "robot template", "dataset info",
            "train", "plan"} <= set(commands)
    for name, cmd in commands.items():
        cfg = getattr(cmd.callback, CONFIG, None)
        assert cfg is not None and dataclasses.is_dataclass(cfg), name
        fields = {f.name for f in dataclasses.fields(cfg)}
        extra = {p.name for p in cmd.params if p.name not in fields and p.name != "help"}
        assert extra <= SHARED | OWN.get(name, set()), (name, extra - SHARED - OWN.get(name, set()))


@dataclass(frozen=True, kw_only=True)
class Shapes:
    folder: str = field(metadata=option_help("A folder.", path="folder", argument=True))
    out: str = field(metadata=option_help("Where to write.", path="out"))
    q: tuple[str, ...] = field(default=(), metadata=option_help("Joints.", repeat=True, metavar="JOINTS"))
    loso: bool = field(default=False, metadata=option_help("Also this.", flag=True))


def test_arguments_paths_flags_and_repeated_options(tmp_path) -> None:
    @click.command()
    @config_options(Shapes)
    def cmd(**settings: Any) -> None:
        click.echo(repr(Shapes(**settings)))

    given = _params(cmd, [str(tmp_path), "--out", "x", "--q", "1,2", "--q", "3,4", "--loso"])
    assert given == {"folder": str(tmp_path), "out": "x", "q": ("1,2", "3,4"), "loso": True}
    assert _params(cmd, [str(tmp_path), "--out", "x"])["q"] == ()
    runner = CliRunner()
    text = runner.invoke(cmd, ["--help"]).output
    assert "FOLDER" in text and "--q JOINTS" in text and "--no-loso" not in text
    missing = runner.invoke(cmd, [str(tmp_path / "nope"), "--out", "x"])
    assert missing.exit_code == 1 and "does not exist" in missing.output          # an input: exit 1
    res = runner.invoke(cmd, [str(tmp_path)])
    assert res.exit_code == 2 and "Missing option '--out'" in res.output          # no default: required


def test_shapes_the_field_cannot_take_are_refused() -> None:
    @dataclass(frozen=True)
    class FlagOnNumber:
        n: int = field(default=1, metadata=option_help("A number.", flag=True))

    @dataclass(frozen=True)
    class PathOnNumber:
        n: int = field(default=1, metadata=option_help("A number.", path="folder"))

    @dataclass(frozen=True)
    class RepeatOnText:
        s: str = field(default="", metadata=option_help("Text.", repeat=True))

    for cls, words in ((FlagOnNumber, "a flag is a bool"), (PathOnNumber, "a path is a str"),
                       (RepeatOnText, "a repeated option is a tuple")):
        with pytest.raises(TypeError, match=words):
            config_options(cls)
