"""Every command of the README, run as written, in order, from a folder laid out like a fresh clone.

The folder holds ``samples`` (the repository's) and nothing else: the README's examples must run on a clone
of the repository alone, so no command may read a file outside it (``../``, an absolute path). ``hairinv`` is
the installed command of this environment; ``make demo`` and ``make test`` are not run (they are how this
suite itself is run). Each command must exit as the README says: 0, except ``verify --init naive``, which
the README shows failing (exit 1: the naive model moves).

Runtime: about four minutes (the whole README: fits, inversions, the still checks, one second of the motion
scene on the wavy sample, the exports and a batch of the three sample grooms).
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

from conftest import ENV, ROOT

README = ROOT / "README.md"
# commands the README shows failing, with their exit code
EXPECTED_EXIT = {"hairinv verify wavy.model.h5 --init naive": 1}


def readme_commands() -> list[str]:
    """The shell commands of the README's ``sh`` code blocks, in order (comments and make demo/test left out)."""
    text = README.read_text()
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            if not line or line.startswith("#") or line in ("make demo", "make test"):
                continue
            commands.append(line)
    return commands


def test_the_readme_has_commands_for_every_subcommand():
    commands = readme_commands()
    used = {shlex.split(c)[1] for c in commands if c.startswith("hairinv ")}
    from hairinv_cli.main import main

    assert set(main.commands) - used == set(), f"subcommands without a README example: {set(main.commands) - used}"


def test_the_readme_reads_nothing_outside_a_clone():
    """A first-time user has the repository and nothing beside it: every path a command names lies inside."""
    commands = readme_commands()
    assert commands
    for command in commands:
        for arg in shlex.split(command):
            assert not arg.startswith("/") and "../" not in arg and "~" not in arg, f"{command}: reads {arg}"
    # the files the README's commands read from the repository are all in it
    for command in commands:
        for arg in shlex.split(command):
            if arg.startswith("samples/"):
                assert (ROOT / arg).exists(), f"{command}: {arg} is not in the repository"


def test_every_readme_command_runs_as_written(tmp_path):
    work = tmp_path / "checkout"
    work.mkdir()
    (work / "samples").symlink_to(ROOT / "samples")
    env = dict(ENV)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    commands = readme_commands()
    assert EXPECTED_EXIT.keys() <= set(commands), "a command expected to fail is no longer in the README"
    for command in commands:
        run = subprocess.run(command, shell=True, cwd=work, env=env, capture_output=True, text=True, timeout=1200)
        expected = EXPECTED_EXIT.get(command, 0)
        assert run.returncode == expected, f"{command}: exit {run.returncode}\n{run.stdout[-2000:]}{run.stderr[-2000:]}"
        assert "Traceback" not in run.stderr, f"{command}:\n{run.stderr}"
