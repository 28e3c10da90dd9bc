"""The command's own memory: what it frees is kept for its next arrays, not handed back to the system.

A stage on a full head allocates and frees many gigabytes, in arrays of tens to hundreds of megabytes.
glibc's malloc gives each array that large a mapping of its own and unmaps it when it is freed, so the
next array's pages are faulted in afresh. On a bare machine that costs a few hundredths of a second a
gigabyte; on a virtual machine whose guest hands freed memory back to its host it costs seconds a gigabyte
(this machine: 5-6 s a gigabyte once the memory the guest used recently is spent). So the command asks
glibc (``mallopt``) to serve even the largest allocations from its heap, with no mapping of their own, and
to keep what is freed there for reuse (it hands back only what exceeds 2 GiB at the heap's top).

Measured on this machine (two-core virtual machine), detecting the contacts of 100,000 strands
(docs/benchmarks.md, "A full head"): 184 s with glibc's defaults, 153 and 161 s with these settings
(peak 8.1-8.3 GiB instead of 7.3). The worker threads allocate from arenas of their own, where glibc still maps
anything over 64 MiB; one arena for every thread (``M_ARENA_MAX`` 1) would keep those too (142 s), but
the threads then wait on each other's small allocations: fitting 30,000 strands took 8.2-8.5 s instead
of 6.6-6.8 s, so it is not set.

A library user's process is left as it is: this runs only when the ``hairinv`` command itself runs (its
group's callback, before any subcommand), not on import. The command leaves malloc alone where it is not
glibc's, where the user tuned it already (any ``MALLOC_*`` variable set, or ``GLIBC_TUNABLES`` naming a
``glibc.malloc.`` tunable), or where ``HAIRINV_SYSTEM_MALLOC`` is set, to anything.

Freed memory kept in the heap is reused as is: an array asked for zeroed (``np.zeros``) on reused memory is
written with zeros, where a fresh mapping would have come zeroed for free, so the peak of resident memory can
be higher than with glibc's defaults (the figures above).
"""

from __future__ import annotations

import ctypes
import os
import sys

# glibc's mallopt parameters (malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_MAX = -4
# the free memory at the heap's top that is handed back (mallopt takes an int): 2 GiB
TRIM_THRESHOLD = 2**31 - 1


def _user_chose() -> bool:
    """Whether the environment tunes malloc already, or asks for the system's malloc as it is."""
    return ("HAIRINV_SYSTEM_MALLOC" in os.environ or any(name.startswith("MALLOC_") for name in os.environ)
            or "glibc.malloc." in os.environ.get("GLIBC_TUNABLES", ""))


def keep_freed_memory() -> bool:
    """Ask glibc's malloc to keep freed memory for reuse (module docstring); True if it took every setting."""
    if not sys.platform.startswith("linux") or _user_chose():
        return False
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # glibc's own symbol: other C libraries' mallopt differ or are absent
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    settings = ((M_MMAP_MAX, 0), (M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return all(mallopt(parameter, value) == 1 for parameter, value in settings)
