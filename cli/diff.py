"""``hairinv diff OLD NEW``: two stage files compared quantity by quantity, for regression checks in CI
(docs/diff.md). Exit 0 when every quantity is within its tolerance, 1 when some moved beyond it, 2 for a
file that is missing, unreadable or not a stage file.

The command is registered on the ``hairinv`` group by one import at the end of cli/main.py.
"""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import click


def _cli():
    """The module that holds the ``hairinv`` group: ``hairinv_cli.main``, or ``__main__`` while that module
    runs as ``python -m hairinv_cli.main`` (importing it by name then would build a second group, which the
    command line never sees)."""
    running = sys.modules.get("__main__")
    spec = getattr(running, "__spec__", None)
    if spec is not None and spec.name == "hairinv_cli.main":
        return running
    return importlib.import_module("hairinv_cli.main")


_main = _cli()


@_main.main.command()
@click.argument("old", type=click.Path(path_type=Path))
@click.argument("new", type=click.Path(path_type=Path))
@click.option("--rtol", type=float, default=None, metavar="R",
              help="Relative tolerance of every compared entry, of its old magnitude (a position: of its "
                   "strand's length) [default: 1e-6].")
@click.option("--atol", "atols", multiple=True, metavar="KIND=VALUE",
              help="Absolute tolerance of one kind of quantity (repeatable): length=0.01mm (positions, fit "
                   "errors; with its unit), curvature=1e-4 (1/m, rest and fitted shapes), force=1e-9 (N), "
                   "factor=1e-6 (stiffening), time=1e-9 (s), sweeps=0. The defaults shown; docs/diff.md "
                   "says why.")
@click.option("--json", "as_json", is_flag=True, help="Print the comparison as JSON (docs/diff.md gives the schema).")
@click.option("--all", "every_row", is_flag=True,
              help="Also list the quantities of groups neither file holds (always in the JSON).")
@click.pass_obj
@_main.handle_errors
def diff(obj, old, new, rtol, atols, as_json, every_row):
    """Compare the stage files OLD and NEW group by group: counts, fit error, contacts, the solver's
    outcome, rest shape, stiffening, frame positions. Exit 0 when everything is within tolerance, 1 when
    something moved beyond it (the table says what, by how much, and on which strands), 2 for unreadable
    input.

    Positions are in mm, curvatures in 1/m, forces in N. Contact forces are compared where the two files
    declare the same contacts; frames as the centerlines `hairinv export` writes. A group in one file
    only is a difference; a dataset that one hairinv version adds and the other's does not write is
    skipped, and the report says so.
    """
    from hairinv.diff import diff_files, parse_tolerances, report_lines

    tolerances = parse_tolerances(rtol, atols)
    result = diff_files(old, new, tolerances)
    if as_json:
        _main._say({**obj, "quiet": False}, json.dumps(result.as_dict(), indent=2))
    else:
        for line in report_lines(result, every_row=every_row):
            _main._say(obj, line)
    if not result.passed:
        sys.exit(_main.FAILED)
