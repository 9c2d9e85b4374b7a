"""Every `--help` ends with copy-paste examples, and every option an example uses exists."""

from __future__ import annotations

import shlex

import click
from click.testing import CliRunner

from ctrkin.cli.main import cli


def _subcommands(group: click.Group) -> dict[str, click.Command]:
    """A group's sub-commands, loaded (`ctrkin` loads its own on first use)."""
    ctx = click.Context(group)
    found = {name: group.get_command(ctx, name) for name in group.list_commands(ctx)}
    return {name: cmd for name, cmd in found.items() if cmd is not None}


def _commands(group: click.Group, path: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], click.Command]]:
    found: list[tuple[tuple[str, ...], click.Command]] = [(path, group)]
    for name, cmd in _subcommands(group).items():
        if isinstance(cmd, click.Group):
            found += _commands(cmd, (*path, name))
        else:
            found.append(((*path, name), cmd))
    return found


def _options(cmd: click.Command) -> set[str]:
    return {o for p in cmd.params if isinstance(p, click.Option) for o in (*p.opts, *p.secondary_opts)}


def _examples(help_text: str) -> list[list[str]]:
    """The example command lines at the end of a help text (continuation lines joined)."""
    tail = help_text.rsplit("Examples:", 1)[1]
    joined = tail.replace("\\\n", " ")
    return [shlex.split(line.split(">")[0]) for line in joined.splitlines() if line.strip()]


def test_every_help_ends_with_examples_that_use_existing_options() -> None:
    runner = CliRunner()
    commands = _commands(cli)
    assert len(commands) == 18     # ctrkin, 12 commands, dataset and its 3, robot and its template
    for path, _cmd in commands:
        res = runner.invoke(cli, [*path, "--help"])
        assert res.exit_code == 0, path
        assert "Examples:" in res.output, f"ctrkin {' '.join(path)} --help has no examples"
        examples = _examples(res.output)
        assert examples, path
        for words in examples:
            words = [w for w in words if "=" not in w or w.startswith("-")]     # VAR=value prefixes
            assert words[0] == "ctrkin", words
            words = [w for w in words[1:] if w not in ("--quiet", "-q")]
            # the example runs this command or, for a group, one of its sub-commands
            target: click.Command = cli
            k = 0
            while isinstance(target, click.Group) and k < len(words) and words[k] in _subcommands(target):
                target = _subcommands(target)[words[k]]
                k += 1
            assert tuple(words[:len(path)]) == path, (path, words)
            for w in words[k:]:
                if w.startswith("--"):
                    assert w.split("=")[0] in _options(target), f"{w} is not an option of {words[:k]}"


def test_the_command_list_of_ctrkin_help_is_each_commands_own_help() -> None:
    """`ctrkin --help` lists the commands without importing them (ctrkin.cli.main.COMMANDS): each line
    must be the first paragraph of the command's own help, as click would list it."""
    from ctrkin.cli.main import COMMANDS

    loaded = _subcommands(cli)
    assert set(loaded) == set(COMMANDS)
    for name, cmd in loaded.items():
        first = " ".join((cmd.help or "").split("\n\n")[0].split())
        assert COMMANDS[name][2] == first, name
    out = CliRunner().invoke(cli, ["--help"]).output
    for name in COMMANDS:
        assert f"  {name} " in out
