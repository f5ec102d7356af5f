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
