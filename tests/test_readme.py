"""Every command of the README, run as written, in order, from a folder laid out like a checkout.

The folder holds ``samples`` (the repository's) and, beside it, ``../shared`` (the real data, when this
machine has it: the commands that read it are skipped otherwise, with the reason). ``hairinv`` is the
installed command of this environment; ``make demo`` and ``make test`` are not run (they are how this
suite itself is run). Each command must exit as the README says: 0, except ``verify --init naive``, which
the README shows failing (exit 1: the naive model moves).

Runtime: a few minutes (the whole README: fits, inversions and the one-second simulations of the samples,
and the real grooms when present).
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ENV, REAL, ROOT

README = ROOT / "README.md"
# commands the README shows failing, with their exit code
EXPECTED_EXIT = {"hairinv verify curly.model.h5 --init naive": 1}


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


def test_every_readme_command_runs_as_written(tmp_path):
    work = tmp_path / "checkout"
    work.mkdir()
    (work / "samples").symlink_to(ROOT / "samples")
    shared = REAL.parent.parent if REAL.exists() else None
    if shared is not None:
        (tmp_path / "shared").symlink_to(shared)
    env = dict(ENV)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    skipped = []
    for command in readme_commands():
        if "../shared" in command and shared is None:
            skipped.append(command)
            continue
        run = subprocess.run(command, shell=True, cwd=work, env=env, capture_output=True, text=True, timeout=1200)
        expected = EXPECTED_EXIT.get(command, 0)
        assert run.returncode == expected, f"{command}: exit {run.returncode}\n{run.stdout[-2000:]}{run.stderr[-2000:]}"
        assert "Traceback" not in run.stderr, f"{command}:\n{run.stderr}"
    if skipped:
        pytest.skip(f"real data not found at {REAL}: {len(skipped)} README commands not run ({skipped[0]} ...)")
