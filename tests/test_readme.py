"""README.md: its commands and examples match the project."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).parent.parent
README = (ROOT / "README.md").read_text()


def test_first_block_is_the_two_commands_and_ci_runs_the_second() -> None:
    first = re.search(r"```\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert len(first) == 2
    # Each makes and uses a virtual environment: a stock Debian/Ubuntu python3 refuses
    # `pip install` outside one (PEP 668).
    assert first[0].startswith("python3 -m venv .venv && .venv/bin/pip install . && "
                               ".venv/bin/tml run ")
    assert first[1] == ("python3 -m venv .venv && .venv/bin/pip install '.[test]' && "
                        ".venv/bin/python -m pytest -n auto")
    ci = (ROOT / ".ci" / "run").read_text()
    assert "sed -n 2p" in ci  # .ci/run takes the second line of that block


def test_xml_example_is_a_mission_file_without_comments() -> None:
    example = re.search(r"```xml\n(.*?)```", README, re.S).group(1).strip()
    named = re.search(r"`(missions/[\w.]+\.xml)`", README[:README.index("```xml")]).group(1)
    source = (ROOT / named).read_text()
    stripped = re.sub(r"<!--.*?-->", "", source[source.index("<mission"):], flags=re.S)
    assert example == "\n".join(line.rstrip() for line in stripped.splitlines()
                                if line.strip())


def test_links_point_at_existing_files_and_headings() -> None:
    for target, anchor in re.findall(r"\]\(((?:docs|missions)/[^)#]+)(?:#([^)]+))?\)", README):
        path = ROOT / target
        assert path.is_file(), target
        if anchor:
            headings = {re.sub(r"[^\w\- ]", "", h).strip().lower().replace(" ", "-")
                        for h in re.findall(r"^#+ (.+)$", path.read_text(), re.M)}
            assert anchor in headings, (target, anchor)


def _quick_start() -> list[str]:
    """The lines of the Quick start's command block, continuations joined."""
    section = README[README.index("## Quick start"):]
    block = re.search(r"```\n(.*?)```", section, re.S).group(1)
    return block.replace("\\\n", " ").splitlines()


def test_quick_start_works_in_the_shell_of_the_first_command() -> None:
    # The first block makes .venv but leaves the shell as it was: `tml` is on no PATH
    # until .venv is activated, so the Quick start does that first.
    assert "python3 -m venv .venv" in README.split("## Quick start")[0]
    assert _quick_start()[0].split("#")[0].strip() == ". .venv/bin/activate"


def test_quick_start_commands_are_tml_commands_with_options_it_has() -> None:
    import shlex

    from sitl.cli import build_parser as sim_parser
    from tml.commands.cli import build_parser

    commands = [shlex.split(c, comments=True) for line in _quick_start()[1:]
                for c in line.split(" && ")]
    assert len(commands) >= 10 and all(argv[0] == "tml" for argv in commands)
    for argv in commands:
        argv = argv[1:]
        if argv[0] == "sim":
            sim_parser("tml sim").parse_args(argv[1:])
        else:
            build_parser(argv[0]).parse_args(argv)  # exits (a test error) on a bad option
        for word in argv:
            if word.startswith("missions/"):
                assert (ROOT / word).exists(), word
