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


def _quick_start_commands() -> list[list[str]]:
    """The Quick start's commands after the activation, as argument lists: one started in
    the background keeps its ``&`` as its last word; ``kill %1`` stops it."""
    import shlex

    return [shlex.split(c, comments=True) for line in _quick_start()[1:]
            for c in line.split(" && ")]


def test_quick_start_commands_are_tml_commands_with_options_it_has() -> None:
    from sitl.cli import build_parser as sim_parser
    from tml.commands.cli import build_parser

    commands = _quick_start_commands()
    background = [argv for argv in commands if argv[-1] == "&"]
    # What runs in the background is the simulator, and it is stopped again.
    assert [argv[:2] for argv in background] == [["tml", "sim"]]
    assert ["kill", "%1"] in commands
    commands = [argv[:-1] if argv[-1] == "&" else argv for argv in commands
                if argv != ["kill", "%1"]]
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


def test_every_flight_of_the_quick_start_is_sped_up() -> None:
    # A flight at real time takes minutes (dolphin_uav_surface.xml: 2 min 16 s): each
    # --sim flight, the service's simulator and the simulator a --connect flight flies on
    # say how much faster.
    commands = _quick_start_commands()
    sims = [argv for argv in commands if argv[:2] == ["tml", "sim"]]
    assert sims and all("--speedup" in argv for argv in sims)
    base = 5760
    for argv in sims:
        if "--tcp-base-port" in argv:
            base = int(argv[argv.index("--tcp-base-port") + 1])
    flights = [argv for argv in commands if argv[:2] in (["tml", "run"], ["tml", "serve"])]
    assert len(flights) >= 7
    for argv in flights:
        if "--sim" in argv:
            assert "--speedup" in argv, argv
        else:  # on the simulator started above
            address = argv[argv.index("--connect") + 1]
            assert address == f"tcp:127.0.0.1:{base}", argv


def test_the_quick_start_says_the_simulator_and_the_service_need_a_terminal() -> None:
    after = README.split("## Quick start", 1)[1].split("```", 2)[2].split("\n## ", 1)[0]
    words = " ".join(after.split())
    assert "`tml sim` and `tml serve` run until stopped" in words
    assert "a terminal of its own" in words and "`kill %1` stops it" in words
