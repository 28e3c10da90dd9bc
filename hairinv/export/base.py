"""The registry of export writers, one module per output kind, chosen by the output's suffix.

A module registers its writer with :func:`register_exporter`; adding a format touches only that module
(and the import list of :mod:`hairinv.export`). A writer gets the stage file as an
:class:`~hairinv.export.source.ExportSource`, the output path and the shape asked for, writes through the
atomic writer (:mod:`hairinv.atomic`, through the format's own writer in :mod:`hairinv.formats` or
:func:`hairinv.formats.usd.save_stage`) and says what it wrote in the :class:`ExportReport`.

A kind that can also compare several stage files (runs of one groom side by side) registers that writer
with :func:`register_comparison`, under the same suffixes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError

__all__ = ["COMPARISONS", "EXPORTERS", "ExportReport", "Exporter", "check_export_path", "exporter_for",
           "register_comparison", "register_exporter"]


@dataclass
class ExportReport:
    """What an export did: ``lines`` for stdout, ``warnings`` for stderr (things left out, and why)."""

    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Exporter:
    """One output kind.

    Attributes
    ----------
    name : str, e.g. ``"USD"``
    suffixes : tuple of str, lower case with the dot
    write : callable(source, path, shape, report)
    default_shape : str, the ``--shape`` used when none is given; None: the output takes no ``--shape`` (a
        summary or a picture of the whole file)
    several_shapes : bool, whether one file carries several shapes (``--shape all``)
    options : tuple of str, the further options the writer takes as keywords (``color``)
    owns : callable(path) -> bool, or None
        Whether an existing file at the output path is one this writer wrote (or of its kind), so that it
        may be replaced; None: a hairstyle file hairinv reads.
    """

    name: str
    suffixes: tuple[str, ...]
    write: Callable
    default_shape: str | None
    several_shapes: bool = False
    options: tuple[str, ...] = ()
    owns: Callable | None = None


EXPORTERS: dict[str, Exporter] = {}


def register_exporter(*suffixes: str, name: str, default_shape: str | None = "input", several_shapes: bool = False,
                      options: tuple[str, ...] = (), owns: Callable | None = None):
    """Register ``fn(source, path, shape, report, **options)`` as the writer of files with these suffixes."""

    def decorate(fn):
        exporter = Exporter(name, tuple(s.lower() for s in suffixes), fn, default_shape, several_shapes, options,
                            owns)
        for suffix in exporter.suffixes:
            EXPORTERS[suffix] = exporter
        return fn

    return decorate


# Suffix -> writer ``fn(sources, path, report)`` of several stage files compared side by side.
COMPARISONS: dict[str, Callable] = {}


def register_comparison(*suffixes: str):
    """Register ``fn(sources, path, report)`` as the writer of a comparison of several stage files (a list of
    :class:`~hairinv.export.source.ExportSource`, checked to be runs of one groom) to files with these
    suffixes."""

    def decorate(fn):
        for suffix in suffixes:
            COMPARISONS[suffix.lower()] = fn
        return fn

    return decorate


def exporter_for(path) -> Exporter:
    """The exporter of ``path``'s suffix, or an :class:`InputError` naming the suffixes supported."""
    path = Path(path)
    exporter = EXPORTERS.get(path.suffix.lower())
    if exporter is None:
        known = ", ".join(sorted(EXPORTERS))
        if not path.suffix:
            raise InputError(f"has no suffix to choose the format by; hairinv export writes {known}", path)
        raise InputError(f"hairinv export cannot write {path.suffix!r} files; it writes {known}", path)
    return exporter


def check_export_path(out, inputs=(), exporter: Exporter | None = None) -> Path:
    """Refuse an output path that would destroy something the user gave us.

    Refused: a folder, a missing folder, one of ``inputs`` (the stage file and the files it was made from),
    and an existing file that is not of the output's kind: for the groom formats one that hairinv does not
    read as a hairstyle (a body mesh, a USD scene without curves, a file of another kind under that
    suffix), for the others one that the exporter's ``owns`` does not recognise. An existing file of the
    output's kind is replaced (atomically, when the export succeeds), as a Makefile rerun expects.
    """
    from .. import formats

    out = Path(out)
    resolved = out.resolve()
    for src in inputs:
        if src is not None and Path(src).resolve() == resolved:
            raise InputError("the output file would overwrite an input of the export; choose another -o", out)
    if out.is_dir():
        raise InputError("the output path is a folder", out)
    if not out.parent.exists():
        raise InputError("the output folder does not exist", out.parent)
    if out.exists() and exporter is not None and exporter.owns is not None:
        if not exporter.owns(out):
            raise InputError(f"exists and is not a {exporter.name} file hairinv wrote; refusing to overwrite it "
                             "(remove it or choose another -o)", out)
    elif out.exists():
        try:
            formats.read_curves(out)
        except InputError:
            raise InputError("exists and is not a hairstyle file hairinv reads; refusing to overwrite it "
                             "(remove it or choose another -o)", out) from None
    return out
