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
    ("ctrkin.cli.train:train_cmd", "ctrkin.cli.train:TrainCommand", {}),
    ("ctrkin.cli.dataset:import_cmd", "ctrkin.data.import_config:ImportConfig",
     {"mapping": ("mapping",), "quaternion_columns": ("quaternion_columns",),
      "sequence_gap": ("sequence_gap",), "cleaning": ("keep_outliers", "no_average")}),
    ("ctrkin.cli.dataset:import_cmd", "ctrkin.cli.dataset:ImportCommand", {}),
    ("ctrkin.cli.reproduce:reproduce_cmd", "ctrkin.evaluation.scales:ReproduceConfig", {}),
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


# Options a command adds beside its configurations': the shared output options alone (every option a
# command reads, paths and model options included, is a field of a typed configuration).
SHARED = {"overwrite", "force", "as_json"}      # --overwrite, --force, --json


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
    shared output options (SHARED): no option is read by hand."""
    import dataclasses

    from ctrkin.cli.from_config import CONFIG

    commands = _commands()
    assert {"calibrate", "evaluate", "predict", "show", "export", "robot template", "dataset info",
            "dataset import", "train", "plan", "collect", "reproduce", "sweep"} <= set(commands)
    for name, cmd in commands.items():
        configs = getattr(cmd.callback, CONFIG, ())
        assert configs and all(dataclasses.is_dataclass(c) for c in configs), name
        fields = {f.name for c in configs for f in dataclasses.fields(c)}
        extra = {p.name for p in cmd.params if p.name not in fields and p.name != "help"}
        assert extra <= SHARED, (name, extra - SHARED)


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


def _listed() -> None:
    click.echo("listed")


@dataclass(frozen=True, kw_only=True)
class Line:
    listing: bool = field(default=False, metadata=option_help("List and exit.", eager=_listed))
    kind: str = field(default="a", metadata=option_help("Which kind.", choices=("a", "b")))
    gap: float | str | None = field(default="auto", metadata=option_help(
        "A gap, auto or none.", parse=lambda t: None if t == "none" else t if t == "auto" else float(t)))
    columns: tuple[str, ...] = field(default=(), metadata=option_help(
        "Columns.", parse=lambda t: tuple(t.split(",")), name="--cols", metavar="C1,C2"))
    options: dict[str, Any] = field(default_factory=dict, metadata=option_help(
        "KEY=VALUE options.", key_values=True, name="--option", metavar="KEY=VALUE"))
    settings: Settings = field(default_factory=Settings, metadata=option_help(
        "Settings.", key_values=True, name="--set"))


def test_choices_parsed_text_key_values_and_an_eager_flag() -> None:
    @click.command()
    @config_options(Line)
    def cmd(**given: Any) -> None:
        click.echo(repr(Line(**given)))

    assert _params(cmd, []) == {"kind": "a", "gap": "auto", "columns": (), "options": {},
                                "settings": Settings()}
    given = _params(cmd, ["--kind", "b", "--gap", "2.5", "--cols", "x,y", "--option", "n=3",
                          "--option", "s=S3", "--set", "count=7", "--set", "mode=y"])
    assert given == {"kind": "b", "gap": 2.5, "columns": ("x", "y"), "options": {"n": 3, "s": "S3"},
                     "settings": Settings(count=7, mode="y")}
    assert _params(cmd, ["--gap", "none"])["gap"] is None
    runner = CliRunner()
    for args, words in ((["--kind", "c"], "--kind"), (["--gap", "soon"], "--gap"),
                        (["--set", "nope=1"], "unknown key 'nope'"),
                        (["--option", "n"], "expected KEY=VALUE")):
        res = runner.invoke(cmd, args)
        assert res.exit_code == 2 and words in res.output, (args, res.output)
    listed = runner.invoke(cmd, ["--listing", "--kind", "c"])       # eager: before the other checks
    assert listed.exit_code == 0 and listed.output == "listed\n"
    text = runner.invoke(cmd, ["--help"]).output
    assert "--cols C1,C2" in text and "--set" in text and "--listing" in text and "[default: auto]" in text


def test_stacked_configurations_are_all_named_and_split_by_only() -> None:
    from ctrkin.cli.from_config import CONFIG

    @click.command()
    @config_options(Line, only=("kind",))
    @config_options(Settings, exclude=("extra",))
    @config_options(Line, only=("gap",))
    def cmd(**given: Any) -> None:
        pass

    assert [p.name for p in cmd.params] == ["kind", "count", "rate", "name", "mode", "limit", "check", "gap"]
    assert set(getattr(cmd.callback, CONFIG)) == {Line, Settings}
    with pytest.raises(TypeError, match="no fields"):
        config_options(Line, only=("nope",))


def test_a_parsed_option_can_be_required() -> None:
    @click.command()
    @config_options(Line, only=("gap",), required=("gap",))
    def cmd(**given: Any) -> None:
        pass

    res = CliRunner().invoke(cmd, [])
    assert res.exit_code == 2 and "Missing option '--gap'" in res.output
    assert _params(cmd, ["--gap", "3"])["gap"] == 3.0
