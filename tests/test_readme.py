"""The README tells the truth: its sample output is the first command's,
line for line, and the examples it names run."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from cdpm.cli import main

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _setup_commands() -> list[str]:
    section = README.split("## Set up", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```bash\n(.*?)\n```", section, re.S)


def test_the_two_setup_commands_are_there_and_ci_runs_the_second():
    first, second = _setup_commands()
    assert first.endswith("cdpm analyze models/two_link_planar/two_link_planar.yaml --pose nominal")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert second.strip().replace(" -e ", " -q -e ") in ci  # CI installs quietly


def test_the_sample_output_is_printed_line_for_line(capsys):
    first = _setup_commands()[0]
    argv = shlex.split(first.split("&& .venv/bin/cdpm ", 1)[1])
    assert main(argv) == 0
    printed = capsys.readouterr().out.splitlines()
    section = README.split("## Set up", 1)[1].split("\n## ", 1)[0]
    sample = re.findall(r"among its lines:\n\n```\n(.*?)\n```", section, re.S)
    assert sample, "the README shows no sample output of the first command"
    for line in sample[0].splitlines():
        assert line in printed, f"README line not printed by the first command: {line!r}"


@pytest.mark.parametrize(
    "command",
    [
        line.split("#")[0].strip()
        for line in README.splitlines()
        if line.startswith("cdpm analyze models/") and "BMArm" not in line  # BMArm: imported
    ],
)
def test_the_analyze_examples_with_models_run(command, capsys):
    assert main(shlex.split(command)[1:]) == 0
    assert "cdpm report:" in capsys.readouterr().out
