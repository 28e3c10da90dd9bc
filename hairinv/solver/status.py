"""One set of statuses for every method of the contact solver, and each method's map onto it.

Each method speaks its own dialect inside (the local kernels return small integer codes, the
interior point stops for reasons of its own); what leaves the solver is always a :class:`Status`,
as cvxpy maps every backend's status onto one set (its ``STATUS_MAP`` per solver interface).
A :class:`Status` is a ``str``: it compares equal to its name, and its name is what the stage
files record (``/model`` attribute ``status``), so stage files written before this enum read the
same.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["Status"]


class Status(StrEnum):
    """How a solve ended."""

    CONVERGED = "CONVERGED"
    """the stopping rule was met: the residual tolerance, or the rest-shape bound where one was asked"""
    MAX_ITERS = "MAX_ITERS"
    """the sweeps (or steps) allowed, or the time allowed to the sweeps, were spent first: the best iterate"""
    NUMERICAL_ERROR = "NUMERICAL_ERROR"
    """a non-finite value in the data or the iterates, or a contact with no positive definite ``W_ii``"""
    TIME = "TIME"
    """the interior point's time limit: its best iterate"""
    STALLED = "STALLED"
    """the interior point made no progress (or its factorisation broke down): its best iterate"""
    TOO_LARGE = "TOO_LARGE"
    """the interior point's factorisation would cost more than allowed: nothing solved, the forces zero"""
