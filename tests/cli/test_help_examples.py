"""Every `--help` ends with copy-paste examples, and every option an example uses exists."""

from __future__ import annotations

import shlex

import click
from click.testing import CliRunner

from ctrkin.cli.main import cli


def _commands(group: click.Group, path: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], click.Command]]:
    found: list[tuple[tuple[str, ...], click.Command]] = [(path, group)]
    for name, cmd in group.commands.items():
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
    assert len(commands) == 14
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
            while isinstance(target, click.Group) and k < len(words) and words[k] in target.commands:
                target = target.commands[words[k]]
                k += 1
            assert tuple(words[:len(path)]) == path, (path, words)
            for w in words[k:]:
                if w.startswith("--"):
                    assert w.split("=")[0] in _options(target), f"{w} is not an option of {words[:k]}"
