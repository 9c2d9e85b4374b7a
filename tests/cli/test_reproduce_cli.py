"""`ctrkin reproduce` arguments (the pipeline itself is tested in tests/evaluation)."""

from __future__ import annotations

from click.testing import CliRunner

from ctrkin.cli.main import cli


def test_help_lists_scales() -> None:
    res = CliRunner().invoke(cli, ["reproduce", "--help"])
    assert res.exit_code == 0
    for word in ("quick", "full", "tiny", "--out", "--workers", "--executor", "RAY_ADDRESS"):
        assert word in res.output


def test_unknown_scale_is_refused() -> None:
    res = CliRunner().invoke(cli, ["reproduce", "--scale", "huge"])
    assert res.exit_code == 2 and "huge" in res.output


def test_malformed_robot_file_is_refused(tmp_path) -> None:
    bad = tmp_path / "robot.toml"
    bad.write_text("[[tubes]]\nod = 1\n")
    res = CliRunner().invoke(cli, ["reproduce", "--robot", str(bad), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1 and "missing field" in res.stderr
    assert not (tmp_path / "o" / "results.json").exists()


class _Stop(Exception):
    """Raised by the stand-in reproduction: the command got that far with these arguments."""


def _captured(monkeypatch) -> dict:
    seen: dict = {}

    def fake(robot, scale, out, **kw):
        seen.update(robot=robot, scale=scale, out=out, **kw)
        raise _Stop

    monkeypatch.setattr("ctrkin.evaluation.reproduce.reproduce", fake)
    return seen


def test_set_gives_reproduce_the_virtual_robots_effects_as_collect_does(monkeypatch, tmp_path) -> None:
    from ctrkin.virtual import VirtualConfig

    seen = _captured(monkeypatch)
    res = CliRunner().invoke(cli, ["reproduce", "--scale", "tiny", "--out", str(tmp_path / "o"),
                                   "--set", "noise_mm=0.1", "--set", "readings_per_sample=3"])
    assert isinstance(res.exception, _Stop), res.output
    assert seen["virtual"] == VirtualConfig(noise_mm=0.1, readings_per_sample=3)
    seen.clear()
    res = CliRunner().invoke(cli, ["reproduce", "--scale", "tiny", "--out", str(tmp_path / "p")])
    assert isinstance(res.exception, _Stop) and seen["virtual"] == VirtualConfig()


def test_set_refuses_what_collect_refuses(monkeypatch, tmp_path) -> None:
    _captured(monkeypatch)
    for bad, word in (("bogus=1", "unknown key 'bogus'"), ("noise_mm=abc", "noise_mm"),
                      ("noise_mm", "KEY=VALUE"), ("noise_mm=1e6", "implausibly large")):
        for cmd in (["reproduce", "--out", str(tmp_path / "o")],
                    ["collect", "--protocol", "sweeps", "--out", str(tmp_path / "c")]):
            res = CliRunner().invoke(cli, [*cmd, "--set", bad])
            assert res.exit_code == 2 and word in res.output, (cmd, bad, res.output)
    assert not (tmp_path / "o").exists() and not (tmp_path / "c").exists()
