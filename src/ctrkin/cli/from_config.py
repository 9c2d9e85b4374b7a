"""Command-line options generated from a configuration dataclass, and the one KEY=VALUE parser.

A command that runs on a configuration does not repeat its fields by hand: each field becomes an
option with the field's name, type, default and help, so a field added to the dataclass is on the
command line at once, with the same default.

    @click.command("train")
    @config_options(TrainConfig, aliases={"max_epochs": ("--epochs",)}, exclude=("options",))
    def train_cmd(**settings: Any) -> None:
        cfg = TrainConfig(**settings)

Field -> option: `max_epochs` -> `--max-epochs` (and its aliases), passed to the command as
`max_epochs`; int, float and str fields take a value of that type; `X | None` the same, default None;
`Literal["a", "b"]` a choice; bool `--name/--no-name`; `tuple[X, ...]` of int, float or str a
comma-separated list ("8,14,20" -> (8.0, 14.0, 20.0)); an int or float field with
`metadata={"range": (lo, hi)}` a value in that closed range (click.IntRange, FloatRange). The help is
the field's `field(metadata={"help": ...})`. A field without a default is a required option. A field
without help, or of another type (a dict, a list), is an error where the command is defined, unless
excluded (the command then sets it from options of its own).

Further metadata keys shape the option where a command's line is not the plain form:
`{"path": kind}` a path (PATHS: an existing folder or file, refused with exit status 1, or an output
path); `{"argument": True}` a positional argument (its name upper-cased, e.g. MODEL_DIR) instead of an
option; `{"flag": True}` a bool as one flag `--name` (no `--no-name`); `{"repeat": True}` a tuple field
given by repeating the option (`--q A --q B`) instead of a comma-separated list; `{"metavar": "..."}`
the value's name in --help; `{"name": "--set"}` the option's name where it is not the field's;
`{"choices": (...)}` the values a str field takes (a list known only at run time); `{"parse": f}` a
value the command line gives as text (a repeated option's tuple of texts) that `f` turns into the
field's value (its click.BadParameter, or a CtrkinError or ValueError, a usage error), the field's own
type then needing no command-line form; `{"key_values": True}` a field set by a repeated KEY=VALUE
option: a dict (values read by their look) or a dataclass (keys its fields, values typed by them,
built; parse_key_values); `{"eager": f}` a bool field as an eager flag that runs `f()` and exits
(`--list-models`; not passed to the command).

A command may stack several `config_options` (a command's own configuration, e.g. its input and
output paths, around a library's configuration): each adds its fields' options where it stands, and
the command's function names every class it is generated from (CONFIG, a tuple).

`--option KEY=VALUE` style settings go through `parse_key_values`: one error message (a usage error,
exit status 2) and values typed by the dataclass's fields or, without one, read as int, float, bool
(true/false) or str.
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Literal, TypeVar, Union, get_args, get_origin, get_type_hints

import click

from ctrkin.cli.common import InputPath
from ctrkin.errors import CtrkinError

F = TypeVar("F", bound=Callable[..., Any])

HELP = "help"      # the metadata key of a field's help text
RANGE = "range"    # the metadata key of an int or float field's bounds (lo, hi), inclusive (None: open)
PATH = "path"      # ... of a path field's kind, a key of PATHS
ARGUMENT = "argument"    # ... True: a positional argument
FLAG = "flag"      # ... True: a bool field as one flag, --name without --no-name
REPEAT = "repeat"  # ... True: a tuple field given by repeating the option
METAVAR = "metavar"  # ... the value's name in --help
NAME = "name"      # ... the option's name where it is not --field-name
CHOICES = "choices"  # ... the values a str field takes
PARSE = "parse"    # ... a function: the option's text(s) -> the field's value
KEY_VALUES = "key_values"  # ... True: a repeated KEY=VALUE option into a dict or a dataclass
EAGER = "eager"    # ... a function an eager flag runs before the command exits
CONFIG = "ctrkin_config"   # the attribute of a command's function naming its configuration classes


def option_help(text: str, **metadata: Any) -> dict[str, Any]:
    """A field's metadata: its help text and any of the keys above, e.g.
    `field(default=None, metadata=option_help("Dataset folder.", path="folder"))`."""
    return {HELP: text, **metadata}


def option(text: str, default: Any = dataclasses.MISSING, **metadata: Any) -> Any:
    """A configuration field with its help and option shape (option_help): `data: str | None =
    option("Dataset folder.", None, path="folder")`; without a default, a required option."""
    return dataclasses.field(default=default, metadata=option_help(text, **metadata))


# path kind -> its click type: an existing folder or file (InputPath: exit status 1 where it is not
# there), an output file or folder, an output file
PATHS: dict[str, Callable[[], click.ParamType]] = {
    "folder": lambda: InputPath(file_okay=False),
    "file": lambda: InputPath(dir_okay=False),
    "out": click.Path,
    "out_file": lambda: click.Path(dir_okay=False),
}


def _option_name(field_name: str) -> str:
    return "--" + field_name.replace("_", "-")


class CommaList(click.ParamType):
    """A comma-separated list of one type: "8,14,20" -> (8.0, 14.0, 20.0) for float items."""

    def __init__(self, item: type) -> None:
        self.item = click.types.convert_type(item)
        self.name = f"{item.__name__},..."

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        parts = [p.strip() for p in str(value).split(",") if p.strip()]
        try:
            return tuple(self.item.convert(p, param, ctx) for p in parts)
        except click.BadParameter:
            self.fail(f"expected comma-separated {self.name.split(',')[0].lower()} values, got {value!r}",
                      param, ctx)


def _click_type(hint: Any) -> tuple[Any, bool]:
    """(click type, whether None is allowed) of a field annotation; TypeError if it has no
    command-line form."""
    optional = False
    if get_origin(hint) in (Union, types.UnionType):
        rest = [a for a in get_args(hint) if a is not type(None)]
        if len(rest) != 1:
            raise TypeError(f"{hint} is not one type or one type | None")
        optional, hint = True, rest[0]
    if get_origin(hint) is Literal and all(isinstance(a, str) for a in get_args(hint)):
        return click.Choice(get_args(hint)), optional
    args = get_args(hint)
    if get_origin(hint) is tuple and len(args) == 2 and args[1] is Ellipsis and args[0] in (int, float, str):
        return CommaList(args[0]), optional
    if hint in (bool, int, float, str):
        return hint, optional
    raise TypeError(f"{hint} has no command-line form")


def _default(f: dataclasses.Field[Any]) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def config_options(cls: type, *, aliases: Mapping[str, Sequence[str]] | None = None,
                   exclude: Iterable[str] = (), only: Iterable[str] | None = None,
                   required: Iterable[str] = (),
                   defaults: Mapping[str, Any] | None = None) -> Callable[[F], F]:
    """A decorator adding one click option (or argument) per field of the dataclass `cls`, in field
    order.

    aliases: field -> older option names that also set it (listed first in --help); exclude: fields
    the command sets otherwise; only: these fields alone (the others' options stand elsewhere, from
    another config_options of the same class); required, defaults: where the command line differs
    from the dataclass (a required option; another default). Options pass the field's value to the
    command under the field's name; the function's attribute CONFIG names `cls` (beside the classes
    of the command's other config_options)."""
    aliases, defaults = dict(aliases or {}), dict(defaults or {})
    exclude, required = set(exclude), set(required)
    hints = get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    if only is not None:
        exclude |= names - set(only)
    unknown = (set(aliases) | set(defaults) | exclude | required | set(only or ())) - names
    if unknown:
        raise TypeError(f"{cls.__name__} has no fields {sorted(unknown)}")
    decorators = [_parameter(f, hints[f.name], f"{cls.__name__}.{f.name}", aliases.get(f.name, ()),
                             f.name in required, defaults)
                  for f in dataclasses.fields(cls) if f.name not in exclude and f.init]

    def decorate(func: F) -> F:
        for add in reversed(decorators):     # click lists the outermost decorator first
            func = add(func)
        configs = getattr(func, CONFIG, ())     # the configurations the command is generated from
        setattr(func, CONFIG, configs if cls in configs else (cls, *configs))
        return func

    return decorate


def _parameter(f: dataclasses.Field[Any], hint: Any, where: str, aliases: Sequence[str], required: bool,
               defaults: Mapping[str, Any]) -> Callable[[F], F]:
    """The click option (or argument) of one field (config_options)."""
    meta = f.metadata
    if not meta.get(HELP):
        raise TypeError(f"{where} has no help: field(..., metadata={{'help': ...}})")
    if EAGER in meta:
        return _eager_flag(f, where)
    parse = meta.get(PARSE)
    if meta.get(KEY_VALUES):
        parse = _key_values(hint, meta.get(NAME, _option_name(f.name)))
    if parse is not None:
        return _parsed(f, parse, aliases, required)
    try:
        kind, _optional = _click_type(hint)
    except TypeError as e:
        raise TypeError(f"{where}: {e}; exclude it and give the command its own option") from None
    if CHOICES in meta:
        if kind is not str:
            raise TypeError(f"{where}: choices apply to str fields")
        kind = click.Choice(tuple(meta[CHOICES]))
    if RANGE in meta:
        if kind not in (int, float):
            raise TypeError(f"{where}: a range applies to int and float fields")
        lo, hi = meta[RANGE]
        kind = click.IntRange(lo, hi) if kind is int else click.FloatRange(lo, hi)
    repeat = bool(meta.get(REPEAT))
    if repeat:
        if not isinstance(kind, CommaList):
            raise TypeError(f"{where}: a repeated option is a tuple[X, ...] field")
        kind = kind.item
    if PATH in meta:
        if kind is not click.STRING and kind is not str:
            raise TypeError(f"{where}: a path is a str field (or a repeated one), one of {', '.join(PATHS)}")
        kind = PATHS[meta[PATH]]()
    required = required or (f.name not in defaults and f.default is dataclasses.MISSING
                            and f.default_factory is dataclasses.MISSING)
    if meta.get(ARGUMENT):
        return click.argument(f.name, type=kind, required=required, nargs=-1 if repeat else 1)
    name = meta.get(NAME, _option_name(f.name))
    kw: dict[str, Any] = {"help": meta[HELP], "show_default": True}
    if meta.get(FLAG):
        if kind is not bool:
            raise TypeError(f"{where}: a flag is a bool field")
        kw["is_flag"] = True
    elif kind is bool:
        name += "/" + _option_name("no_" + f.name)
    if repeat:
        kw["multiple"] = True
    if METAVAR in meta:
        kw["metavar"] = meta[METAVAR]
    if required:
        kw["required"] = True
    else:
        default = defaults.get(f.name, _default(f))
        if isinstance(kind, CommaList) and default:     # shown and parsed as typed: "8,14,20"
            default = ",".join(map(str, default))
        kw["default"] = default
    return click.option(*aliases, name, f.name, type=kind, **kw)


def _eager_flag(f: dataclasses.Field[Any], where: str) -> Callable[[F], F]:
    """An eager flag (`--list-models`): given, it runs the field's EAGER function and the command
    exits before its other options are checked."""
    run = f.metadata[EAGER]
    if f.default is not False:
        raise TypeError(f"{where}: an eager flag is a bool field with default False")

    def callback(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
        if value and not ctx.resilient_parsing:
            run()
            ctx.exit()

    return click.option(f.metadata.get(NAME, _option_name(f.name)), f.name, is_flag=True, expose_value=False,
                        is_eager=True, callback=callback, help=f.metadata[HELP])


def _parsed(f: dataclasses.Field[Any], parse: Callable[[Any], Any], aliases: Sequence[str],
            required: bool) -> Callable[[F], F]:
    """The option of a field the command line gives as text and `parse` turns into its value (a
    repeated option: parse gets the tuple of texts; its default is none given). required: the
    command's required=, or a field without a default."""
    meta = f.metadata
    repeat = bool(meta.get(REPEAT) or meta.get(KEY_VALUES))

    def callback(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
        if value is None:
            return _default(f)
        try:
            return parse(value)
        except click.BadParameter as e:
            if e.param is None and e.param_hint is None:
                e.param = param
            raise
        except (CtrkinError, ValueError) as e:
            raise click.BadParameter(str(e), ctx, param) from None

    kw: dict[str, Any] = {"help": meta[HELP], "callback": callback, "metavar": meta.get(METAVAR)}
    if repeat:
        kw |= {"multiple": True, "default": ()}
    else:       # a default that is text is parsed as given; none given is the field's default
        default = _default(f)
        kw |= {"default": default if isinstance(default, str) else None, "show_default": True}
    if required or (f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING):
        kw["required"] = True
        kw.pop("default")
    return click.option(*aliases, meta.get(NAME, _option_name(f.name)), f.name, **kw)


def _key_values(hint: Any, option: str) -> Callable[[tuple[str, ...]], Any]:
    """The parse of a KEY_VALUES field: KEY=VALUE settings into a dict, or into the dataclass `hint`
    (keys its fields, values typed by them; its own checks' errors usage errors)."""
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        cls = hint

        def build(items: tuple[str, ...]) -> Any:
            try:
                return cls(**parse_key_values(items, option, cls))
            except CtrkinError as e:
                raise click.BadParameter(str(e), param_hint=option) from None

        return build
    if get_origin(hint) is dict or hint is dict:
        return lambda items: parse_key_values(items, option)
    raise TypeError(f"{hint}: KEY=VALUE settings go into a dict or a dataclass")


def _infer(text: str) -> Any:
    """A value without a declared type: int, float, bool (true/false) or, failing those, the text."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def _settable(config: type) -> dict[str, tuple[Any, bool]]:
    """The fields of a dataclass that a command-line value can set: name -> (click type, optional)."""
    hints = get_type_hints(config)
    out = {}
    for f in dataclasses.fields(config):
        try:
            out[f.name] = _click_type(hints[f.name])
        except TypeError:
            continue
    return out


def parse_key_values(items: Iterable[str], option: str, config: type | None = None) -> dict[str, Any]:
    """("a=1", "b=x") -> {"a": 1, "b": "x"}: the KEY=VALUE settings of a repeatable `option`.

    With `config` (a dataclass) the keys must be its fields (of a type `config_options` takes) and
    each value is converted to the field's type ("none" is None where the field allows it); without,
    a value is read as int, float, bool (true/false) or str. Anything else is a usage error
    (click.BadParameter: exit status 2, the message on stderr)."""
    kinds = {} if config is None else _settable(config)
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise click.BadParameter(f"expected KEY=VALUE, got {item!r}", param_hint=option)
        if config is None:
            out[key] = _infer(text)
            continue
        if key not in kinds:
            raise click.BadParameter(f"unknown key {key!r}; one of: {', '.join(kinds)}", param_hint=option)
        kind, optional = kinds[key]
        if optional and text.lower() == "none":
            out[key] = None
            continue
        try:
            out[key] = click.types.convert_type(kind).convert(text, None, None)
        except click.BadParameter as e:
            raise click.BadParameter(f"{key}: {e.message}", param_hint=option) from None
    return out


def virtual_config(settings: Iterable[str]) -> Any:
    """The VirtualConfig of --set KEY=VALUE settings (the one parser, typed by VirtualConfig's fields,
    parse_key_values); an unknown key or a bad value is a usage error."""
    from ctrkin.virtual.config import VirtualConfig

    return _key_values(VirtualConfig, "--set")(tuple(settings))
