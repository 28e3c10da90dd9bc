"""Command-line interface of hairinv (click)."""

from ._memory import keep_freed_memory

# first, before numpy, numba and their threads start (cli/_memory.py)
keep_freed_memory()
