"""What ``tml COMMAND --help`` tells the operator, for every command the parser has."""

from __future__ import annotations

import argparse
import re

import pytest

from tml.commands.cli import build_parser, main

ADDRESS = "ADDRESS"
"""The one word for a MAVLink connection address, in every command's help."""
ADDRESS_OPTIONS = ("--connect", "--out")
"""The options that take a MAVLink connection address (docs/connections.md)."""
LISTEN_OPTIONS = ("--host", "--bind")
"""The options that take the local address a service or the simulator listens on."""


def _commands() -> list[str]:
    """The subcommands, as the parser knows them (not a list kept here)."""
    subparsers = next(action for action in build_parser()._actions
                      if isinstance(action, argparse._SubParsersAction))
    return sorted(subparsers.choices)


COMMANDS = _commands()


def _help(command: str, capsys: pytest.CaptureFixture[str]) -> str:
    assert main([command, "--help"]) == 0
    return capsys.readouterr().out


def _options(text: str) -> dict[str, str | None]:
    """Each option the help lists, with the word shown for its value (None: a flag)."""
    found: dict[str, str | None] = {}
    for line in text.splitlines():
        if not line.startswith("  -"):
            continue
        for spelling in line.strip().split("  ")[0].split(", "):
            option, _, metavar = spelling.partition(" ")
            found[option] = metavar or None
    return found


def test_the_commands_are_found_in_the_parser() -> None:
    assert {"validate", "verify", "run", "serve", "sim", "command", "companion",
            "import"} <= set(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_no_help_says_default_none(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    text = _help(command, capsys)
    assert text.startswith(f"usage: tml {command} ")
    # argparse's formatter adds "(default: X)" to every option: None for those that have no
    # default, a Python list for the repeatable ones, and a second default where the help
    # already says it.
    assert "default: None" not in text and "(default: [" not in text
    assert not re.search(r"\(default[^)]*\)\s*\(default", text)


@pytest.mark.parametrize("command", COMMANDS)
def test_every_address_is_called_address(command: str,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    options = _options(_help(command, capsys))
    assert options, command
    for option, metavar in options.items():
        if option in ADDRESS_OPTIONS:
            assert metavar == ADDRESS, (command, option, metavar)
        elif option in LISTEN_OPTIONS:
            assert metavar == "HOST", (command, option, metavar)
        else:  # ADDRESS means a MAVLink address, and nothing else does
            assert metavar not in (ADDRESS, "ADDR", "URL") or option == "--database", \
                (command, option, metavar)


def test_the_commands_that_reach_a_vehicle_say_address(
        capsys: pytest.CaptureFixture[str]) -> None:
    # The rule above holds for options that exist: these commands do take an address.
    taking = {command for command in COMMANDS
              if _options(_help(command, capsys)).get("--connect") == ADDRESS}
    assert taking == {"verify", "run", "serve", "command", "companion"}
    assert _options(_help("sim", capsys))["--out"] == ADDRESS


@pytest.mark.parametrize("command", ["verify", "run"])
def test_the_profile_option_lists_every_shipped_profile(
        command: str, capsys: pytest.CaptureFixture[str]) -> None:
    from tml.verify.profile import SHIPPED

    text = " ".join(_help(command, capsys).split())
    described = text.split("--profile P ", 1)[1].split(" --", 1)[0]
    for name in (*SHIPPED, "vehicle", "TOML file"):
        assert name in described, (command, name, described)
