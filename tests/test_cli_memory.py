"""The command keeps the memory it frees for its next arrays (cli/_memory.py), measured with glibc's own
account of its heap (mallinfo2), in fresh interpreters: one where the command runs, one where the library
and the command's module are only imported, and ones where the user chose malloc's settings."""

import ctypes
import os
import subprocess
import sys

import pytest

PROBE = """
import contextlib, ctypes, io, sys
import numpy as np
import hairinv.contacts.detect  # noqa: F401
from hairinv_cli.main import main
if sys.argv[1] == "command":  # the command runs: its group's callback, then a subcommand's help
    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
        main(["status", "--help"])

class Info(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Info
a = np.ones(2**23)  # 64 MiB
during = libc.mallinfo2()
del a
after = libc.mallinfo2()
print(during.hblkhd, after.fordblks)
"""
SIZE = 2**26


def _glibc_with_mallinfo2() -> bool:
    if not sys.platform.startswith("linux"):
        return False
    libc = ctypes.CDLL(None)
    return hasattr(libc, "gnu_get_libc_version") and hasattr(libc, "mallinfo2")


def _probe(mode: str, **env) -> tuple[int, int]:
    clean = {k: v for k, v in os.environ.items()
             if not k.startswith("MALLOC_") and k not in ("HAIRINV_SYSTEM_MALLOC", "GLIBC_TUNABLES")}
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env={**clean, **env}, capture_output=True, text=True,
                         check=True)
    mapped, free = (int(v) for v in out.stdout.split())
    return mapped, free


@pytest.mark.skipif(not _glibc_with_mallinfo2(), reason="glibc >= 2.33 (mallinfo2) only")
def test_the_command_keeps_freed_memory_in_its_heap():
    mapped, free = _probe("command")
    assert mapped < SIZE, "a 64 MiB array was given a mapping of its own"
    assert free >= SIZE, "the freed 64 MiB went back to the system"


@pytest.mark.skipif(not _glibc_with_mallinfo2(), reason="glibc >= 2.33 (mallinfo2) only")
@pytest.mark.parametrize("mode, env", [("library", {}), ("command", {"HAIRINV_SYSTEM_MALLOC": "1"}),
                                       ("command", {"HAIRINV_SYSTEM_MALLOC": ""}),
                                       ("command", {"MALLOC_ARENA_MAX": "4"}),
                                       ("command", {"MALLOC_PERTURB_": "0"}),
                                       ("command", {"GLIBC_TUNABLES": "glibc.malloc.tcache_count=7"})])
def test_malloc_is_left_alone_for_libraries_and_where_the_user_chose(mode, env):
    # the control: glibc's defaults map an array this large on its own and unmap it when freed
    mapped, free = _probe(mode, **env)
    assert mapped >= SIZE
    assert free < SIZE
