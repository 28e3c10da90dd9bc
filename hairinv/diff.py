"""Two stage files compared quantity by quantity: what ``hairinv diff`` reports for regression checks
(docs/diff.md).

Each quantity is a :class:`Row`: the old and new value in a physical unit (mm for positions and fit
errors, 1/m for curvatures, N for forces), the difference, the tolerance it was held to, the verdict and
the strands concerned. Arrays are compared entry by entry (per vertex, element, contact or strand), each
entry against ``atol + rtol * |old entry|`` (for a position: ``rtol`` times the length of its strand,
since a position has no scale of its own); the row fails if any entry is beyond its tolerance.

Every quantity has a row whatever the files hold, under a stable key: a quantity that cannot be
compared is ``SKIPPED`` with the reason. A group present in one file only, or (for two files of the same
hairinv version) a dataset present in one only, is a difference; a dataset or attribute that one version
adds (docs/stage-files.md) and the other file's version does not write is skipped and said so.

Computing times (the ``seconds`` attributes, ``/frames/frame_seconds``) are never compared: they are
wall-clock figures, different on every run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import stages
from .errors import InputError
from .groom import strand_lengths
from .model import rest_from_group

__all__ = ["SCHEMA", "Tolerances", "Row", "Diff", "parse_tolerances", "diff_stages", "diff_files",
           "report_lines"]

#: Version of the JSON layout (:meth:`Diff.as_dict`): raised when a key is renamed, removed or changes
#: meaning; keys and quantities are only ever added within one version.
SCHEMA = 1

PASS, FAIL, SKIPPED = "PASS", "FAIL", "SKIPPED"
_MM = 1e3  # m -> mm
#: Frames whose largest distance the note of a failing ``frames.positions`` lists.
FRAMES_IN_NOTE = 12


@dataclass(frozen=True)
class Tolerances:
    """Absolute tolerances per kind of quantity, and one relative tolerance for all (docs/diff.md says why).

    The defaults pass two runs of the same command (the pipeline gives the same numbers on any thread
    count) and fail a changed setting: a solver.tolerance ten times tighter, a Young's modulus 5 % higher,
    a fit tolerance of 0.15 mm instead of 0.2 mm, 10 % more air damping or half the time step. Files from
    another machine or BLAS may differ by more than round-off where the contact solver's path took another
    turn; loosen ``curvature`` and ``force`` for those (docs/diff.md).
    """

    length: float = 1e-5
    """m. Point positions (input curves, frames), fit errors and the arc lengths that match contacts: a tenth of
    what `hairinv verify` calls moving (0.1 mm), a twentieth of the fit tolerance (0.2 mm). 10 % more air
    damping moves the wavy sample's moving frames by 3 um in the first frame and 88 um in the third."""
    curvature: float = 1e-4
    """1/m. Rest and fitted shapes, per element ``|d(kappa1, kappa2, tau)|``. This change on every element of a
    30 cm strand moves its tip by at most ``d L^2 / 2`` = 4.5 um, under ``length``. A ten times tighter
    solver.tolerance moves the wavy sample's rest shape by up to 0.011 1/m, a 5 % stiffer material by 7 1/m."""
    force: float = 1e-9
    """N. Contact forces (as world vectors) and the solver's residual: 3e-5 of the weight of a 30 cm hair
    (3.0e-5 N at the default material), a third of the residual the solver stops at on the wavy sample. A ten
    times tighter solver.tolerance moves forces by 1e-7 to 9e-7 N."""
    factor: float = 1e-6
    """Stiffening factors (no unit). Each is a closed form of its strand's smallest eigenvalue (round-off
    about 1e-12); a ten times tighter solver.tolerance moves them by 2e-4."""
    time: float = 1e-9
    """s. Frame times (``k / fps``, round-off about 1e-16 s)."""
    sweeps: int = 0
    """Contact solver sweeps: the same by default, the solve being deterministic."""
    rtol: float = 1e-6
    """Relative tolerance of every compared entry (its old magnitude; a position's strand length): far above
    float64 round-off amplified by the rods' stiffness conditioning, far below any physical change."""

    def as_dict(self) -> dict:
        return {"rtol": self.rtol, "atol": {"length_m": self.length, "curvature_1_per_m": self.curvature,
                                            "force_N": self.force, "factor": self.factor, "time_s": self.time,
                                            "sweeps": self.sweeps}}


#: ``--atol`` kinds and their units, as the options take them.
ATOL_KINDS = {"length": "a length with its unit, e.g. 0.01mm", "curvature": "1/m", "force": "N",
              "factor": "no unit", "time": "s", "sweeps": "a count"}


def parse_tolerances(rtol: float | None = None, atol: tuple[str, ...] | list[str] = ()) -> Tolerances:
    """The default :class:`Tolerances` with ``rtol`` and ``KIND=VALUE`` items (``--atol``) applied.

    ``length`` takes a unit (``0.01mm``, ``1e-5m``, ``10um``) as ``hairinv verify --tolerance`` does; the
    others are numbers in their SI unit (:data:`ATOL_KINDS`). One bare number is refused: the quantities
    are in m, 1/m, N and s, and no single number serves them all.

    Raises
    ------
    InputError
        One sentence naming the option and the value.
    """
    from .dynamics.verify import parse_length

    values = {}
    kinds = ", ".join(f"{k} ({u})" for k, u in ATOL_KINDS.items())
    if rtol is not None:
        if not (math.isfinite(rtol) and rtol >= 0):
            raise InputError(f"--rtol must be a finite number >= 0, got {rtol!r}")
        values["rtol"] = float(rtol)
    for item in atol:
        kind, sep, text = str(item).partition("=")
        kind, text = kind.strip().lower(), text.strip()
        if not sep:
            raise InputError(f"--atol takes KIND=VALUE, not {item!r}: the quantities compared are in different "
                             f"units, so each kind has its own, one of {kinds}")
        if kind not in ATOL_KINDS:
            raise InputError(f"--atol: unknown kind {kind!r} in {item!r}; use one of {kinds}")
        if kind == "length":
            values[kind] = parse_length(text, f"--atol {kind}")
            continue
        try:
            value = int(text) if kind == "sweeps" else float(text)
        except ValueError:
            raise InputError(f"--atol {kind}: {text!r} is not a {'whole ' if kind == 'sweeps' else ''}number") from None
        if not (math.isfinite(value) and value >= 0):
            raise InputError(f"--atol {kind}: {text!r} must be a finite number >= 0")
        values[kind] = value
    return replace(Tolerances(), **values)


@dataclass
class Row:
    """One compared quantity. Values are in ``unit``; ``difference`` and ``tolerance`` are those of the entry
    furthest beyond (or nearest to) its tolerance, which is the largest difference unless ``rtol`` weighs
    in. ``strands`` lists the strands with an entry beyond tolerance, largest difference first, each as
    ``(strand, difference in unit)``."""

    key: str
    label: str
    unit: str
    old: float | int | str | None = None
    new: float | int | str | None = None
    difference: float | int | None = None
    tolerance: float | int | None = None
    verdict: str = PASS
    note: str = ""
    strands: list[tuple[int, float]] = field(default_factory=list)
    per_frame: list[dict] | None = None

    @property
    def group(self) -> str:
        return self.key.split(".")[0]

    def as_dict(self) -> dict:
        return {"label": self.label, "group": self.group, "unit": self.unit, "old": self.old, "new": self.new,
                "difference": self.difference, "tolerance": self.tolerance, "verdict": self.verdict,
                "note": self.note, "strands": [{"strand": k, "difference": d} for k, d in self.strands],
                "per_frame": self.per_frame}


@dataclass
class Diff:
    """The comparison of two stage files: every quantity's :class:`Row`, in report order."""

    old: stages.StageFile
    new: stages.StageFile
    tolerances: Tolerances
    rows: list[Row]
    settings_changed: list[dict]

    @property
    def failed(self) -> list[Row]:
        return [r for r in self.rows if r.verdict == FAIL]

    @property
    def passed(self) -> bool:
        return not self.failed

    def as_dict(self) -> dict:
        """JSON-ready; docs/diff.md gives the schema."""

        def side(stage):
            return {"file": str(stage.path), "producer": stage.producer, "stages": ",".join(stage.groups)}

        return {"schema": SCHEMA, "verdict": PASS if self.passed else FAIL, "old": side(self.old),
                "new": side(self.new), "tolerances": self.tolerances.as_dict(),
                "quantities": {r.key: r.as_dict() for r in self.rows},
                "failed": [r.key for r in self.failed],
                "skipped": [{"quantity": r.key, "reason": r.note} for r in self.rows if r.verdict == SKIPPED],
                "settings_changed": self.settings_changed}


# --------------------------------------------------------------------------- helpers


def _version(stage: stages.StageFile) -> str | None:
    """``0.1.0`` of the producer ``hairinv 0.1.0 invert``, or None."""
    parts = str(stage.producer).split()
    return parts[1] if len(parts) >= 2 and parts[0] == "hairinv" else None


def _owner(offsets: np.ndarray) -> np.ndarray:
    """(n,) int64: the strand of each row of a CSR array."""
    return np.repeat(np.arange(len(offsets) - 1, dtype=np.int64), np.diff(offsets))


def _flatten(config: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in config.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _largest(values) -> float | None:
    values = np.asarray(values, dtype=np.float64)
    return float(values.max()) if values.size else None


def _rms(values) -> float | None:
    values = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(values ** 2))) if values.size else None


def _scaled(value, scale: float):
    return None if value is None else float(value) * scale


class _Comparison:
    """Builds the rows of :func:`diff_stages`; one method per group."""

    def __init__(self, old: stages.StageFile, new: stages.StageFile, tol: Tolerances):
        self.old, self.new, self.tol = old, new, tol
        self.rows: list[Row] = []
        self.same_version = _version(old) is not None and _version(old) == _version(new)

    # ------------------------------------------------------------------ row builders

    def add(self, row: Row) -> Row:
        self.rows.append(row)
        return row

    def skip(self, key: str, label: str, unit: str, note: str, verdict: str = SKIPPED) -> Row:
        return self.add(Row(key, label, unit, verdict=verdict, note=note))

    def exact(self, key: str, label: str, unit: str, old, new, note: str = "") -> Row:
        """Counts, names and settings: the same or not."""
        same = old == new
        difference = (new - old) if isinstance(old, (int, float)) and isinstance(new, (int, float)) else None
        return self.add(Row(key, label, unit, old, new, difference, 0 if difference is not None else None,
                            PASS if same else FAIL, note))

    def scalar(self, key: str, label: str, unit: str, scale: float, old: float, new: float, tol: float) -> Row:
        """One number held to ``tol`` (SI)."""
        diff = abs(new - old)
        return self.add(Row(key, label, unit, old * scale, new * scale, diff * scale, tol * scale,
                            PASS if diff <= tol else FAIL))

    def entries(self, key: str, label: str, unit: str, scale: float, diff, tol, owners, old=None, new=None,
                note: str = "", per_frame=None) -> Row:
        """Entry-wise differences ``diff`` (n,) against ``tol`` (n,), SI; ``owners`` the strands of each entry,
        a (n,) array or a list of them (-1: none, the body)."""
        diff = np.asarray(diff, dtype=np.float64).reshape(-1)
        tol = np.broadcast_to(np.asarray(tol, dtype=np.float64), diff.shape)
        owners = [np.asarray(o, dtype=np.int64).reshape(-1) for o in (owners if isinstance(owners, list) else [owners])]
        if diff.size == 0:
            return self.add(Row(key, label, unit, old, new, 0.0, None, PASS, note, per_frame=per_frame))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(tol > 0, diff / np.where(tol > 0, tol, 1.0), np.where(diff > 0, np.inf, 0.0))
        worst = int(np.argmax(ratio))
        beyond = diff > tol
        strands = []
        if beyond.any():  # each strand's largest difference beyond tolerance, largest first (ties: lower index)
            k = np.concatenate([owner[beyond] for owner in owners])
            d = np.tile(diff[beyond], len(owners))
            k, d = k[k >= 0], d[k >= 0]
            if k.size:
                largest = np.full(int(k.max()) + 1, -1.0)
                np.maximum.at(largest, k, d)
                named = np.flatnonzero(largest >= 0)
                order = np.lexsort((named, -largest[named]))
                strands = [(int(named[i]), float(largest[named[i]]) * scale) for i in order]
        return self.add(Row(key, label, unit, old, new, float(diff[worst]) * scale, float(tol[worst]) * scale,
                            FAIL if beyond.any() else PASS, note, strands, per_frame))

    # ------------------------------------------------------------------ presence

    def groups_of(self, name: str) -> tuple[stages.Group, stages.Group] | str:
        """Both files' group ``name``, or the reason a quantity of it is not compared."""
        if name in self.old and name in self.new:
            return self.old[name], self.new[name]
        if name not in self.old and name not in self.new:
            return f"/{name} is in neither file"
        holder = self.old if name in self.old else self.new
        return f"/{name} is only in {holder.path.name}"

    def optional(self, name: str, item: str, attr: bool = False) -> tuple[str, str] | None:
        """None if both files' ``/name`` hold ``item`` (a dataset, or an attribute); else the verdict and note
        of a quantity that needs it."""
        go, gn = self.old[name], self.new[name]
        have_old = item in (go.attrs if attr else go.datasets)
        have_new = item in (gn.attrs if attr else gn.datasets)
        if have_old and have_new:
            return None
        what = f"/{name} {'attribute' if attr else 'dataset'} {item}"
        if not have_old and not have_new:
            return SKIPPED, f"{what} is in neither file"
        holder, other = (self.old, self.new) if have_old else (self.new, self.old)
        if self.same_version:
            return FAIL, (f"{what} is only in {holder.path.name}; both files were written by hairinv "
                          f"{_version(holder)}, so the settings changed what was written")
        return SKIPPED, (f"{what} is only in {holder.path.name} ({holder.producer}); {other.path.name} was "
                         f"written by {other.producer or 'an unknown producer'}, which may not write it")

    # ------------------------------------------------------------------ the file

    def file(self) -> None:
        old, new = list(self.old.groups), list(self.new.groups)
        only = [f"/{g} only in {self.old.path.name}" for g in old if g not in new]
        only += [f"/{g} only in {self.new.path.name}" for g in new if g not in old]
        self.add(Row("file.groups", "groups", "", ",".join(old), ",".join(new), None, None,
                     FAIL if only else PASS, "; ".join(only)))

    # ------------------------------------------------------------------ /curves

    def curves(self) -> None:
        keys = [("curves.strands", "strands", "strands"), ("curves.points", "input points", "points"),
                ("curves.positions", "input positions, largest distance", "mm")]
        both = self.groups_of(stages.CURVES)
        if isinstance(both, str):
            for key, label, unit in keys:
                self.skip(key, label, unit, both)
            return
        go, gn = both
        off_o, off_n = go["offsets"], gn["offsets"]
        self.exact("curves.strands", "strands", "strands", len(off_o) - 1, len(off_n) - 1)
        same = np.array_equal(off_o, off_n)
        row = self.exact("curves.points", "input points", "points", int(off_o[-1]), int(off_n[-1]))
        if not same and row.verdict == PASS:
            row.verdict, row.note = FAIL, "the same count, spread differently over the strands"
        if not same:
            self.skip(*keys[2], "the strands have different vertices")
            return
        length = strand_lengths(go["points"], off_o)
        owner = _owner(off_o)
        diff = np.linalg.norm(gn["points"] - go["points"], axis=1)
        self.entries(*keys[2], _MM, diff, self.tol.length + self.tol.rtol * length[owner], owner)

    # ------------------------------------------------------------------ /helices

    def helices(self) -> None:
        keys = [("helices.elements", "elements", "elements"),
                ("helices.fit_error_mean", "fit error, mean per strand", "mm"),
                ("helices.fit_error_max", "fit error, largest per strand", "mm"),
                ("helices.shape", "fitted shape, largest difference", "1/m")]
        both = self.groups_of(stages.HELICES)
        if isinstance(both, str):
            for key in keys:
                self.skip(*key, both)
            return
        go, gn = both
        off_o, off_n = go["offsets"], gn["offsets"]
        same = np.array_equal(off_o, off_n)
        row = self.exact(*keys[0], int(off_o[-1]), int(off_n[-1]))
        if not same and row.verdict == PASS:
            row.verdict, row.note = FAIL, "the same count, spread differently over the strands"
        if len(off_o) != len(off_n):
            for key in keys[1:3]:
                self.skip(*key, "the files have different strand counts")
        else:
            for i, key in ((0, keys[1]), (1, keys[2])):
                eo, en = go["fit_error"][:, i], gn["fit_error"][:, i]
                summary = np.mean if i == 0 else np.max
                self.entries(*key, _MM, np.abs(en - eo), self.tol.length + self.tol.rtol * np.abs(eo),
                             np.arange(len(eo)), _scaled(summary(eo), _MM) if len(eo) else None,
                             _scaled(summary(en), _MM) if len(en) else None)
        if not same:
            self.skip(*keys[3], "the strands have different elements")
            return
        self.curvature_rows(keys[3], None, go["omega"], gn["omega"], off_o)

    def curvature_rows(self, largest_key, rms_key, omega_old, omega_new, offsets) -> None:
        """Per element ``|d omega|`` (1/m): the largest, and (with ``rms_key``) the rms over the elements."""
        norm_old = np.linalg.norm(omega_old, axis=1)
        norm_new = np.linalg.norm(omega_new, axis=1)
        diff = np.linalg.norm(omega_new - omega_old, axis=1)
        if rms_key is not None:
            rms = _rms(diff) or 0.0
            tol = self.tol.curvature + self.tol.rtol * (_rms(norm_old) or 0.0)
            self.add(Row(*rms_key, _rms(norm_old), _rms(norm_new), rms, tol, PASS if rms <= tol else FAIL))
        self.entries(*largest_key, 1.0, diff, self.tol.curvature + self.tol.rtol * norm_old, _owner(offsets),
                     _largest(norm_old), _largest(norm_new))

    # ------------------------------------------------------------------ /contacts

    def contacts(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The rows; returns the matching (old index, new index) when the contact sets match."""
        keys = [("contacts.hair_body", "hair-body contacts", "contacts"),
                ("contacts.hair_hair", "hair-hair contacts", "contacts"),
                ("contacts.set", "contacts (difference: unmatched)", "contacts")]
        both = self.groups_of(stages.CONTACTS)
        if isinstance(both, str):
            for key in keys:
                self.skip(*key, both)
            return None
        go, gn = both
        so, sn = go["strand"].reshape(-1, 2), gn["strand"].reshape(-1, 2)
        self.exact(*keys[0], int(np.count_nonzero(so[:, 1] < 0)), int(np.count_nonzero(sn[:, 1] < 0)))
        self.exact(*keys[1], int(np.count_nonzero(so[:, 1] >= 0)), int(np.count_nonzero(sn[:, 1] >= 0)))
        pairs, lost, found = _match_contacts(so, go["s"].reshape(-1, 2), sn, gn["s"].reshape(-1, 2),
                                             self.tol.length, self.tol.rtol)
        unmatched = len(lost) + len(found)
        strands: dict[int, float] = {}
        for side, idx in ((so, lost), (sn, found)):
            for c in idx:
                for k in side[c]:
                    if k >= 0:
                        strands[int(k)] = strands.get(int(k), 0) + 1
        note = ("" if not unmatched else
                f"{len(lost)} of {len(so)} contacts of {self.old.path.name} and {len(found)} of {len(sn)} of "
                f"{self.new.path.name} have no contact on the same strands within {_MM * self.tol.length:g} mm "
                "of arc length in the other file")
        self.add(Row(*keys[2], len(so), len(sn), unmatched, 0, FAIL if unmatched else PASS, note,
                     [(k, float(n)) for k, n in sorted(strands.items(), key=lambda kv: (-kv[1], kv[0]))]))
        return None if unmatched else pairs

    # ------------------------------------------------------------------ /model

    def model(self, pairs) -> None:
        material = [("model.target", "target", "", None), ("model.youngs_modulus", "Young's modulus", "GPa", 1e-9),
                    ("model.shear_modulus", "shear modulus", "GPa", 1e-9),
                    ("model.density", "density", "kg/m^3", 1.0), ("model.radius", "radius", "mm", _MM),
                    ("model.gamma", "gamma (weight of the forces)", "1/(N^2 m^2)", 1.0)]
        solver = [("model.status", "solver status", ""), ("model.sweeps", "solver sweeps", "sweeps"),
                  ("model.residual", "solver residual", "N"),
                  ("model.objective", "objective", "1/m^2"),
                  ("model.carrying_threshold", "normal force counted as carrying", "N"),
                  ("model.unstable", "strands unstable at rest", "strands")]
        shapes = [("model.force", "contact forces, largest difference", "N"),
                  ("model.rest_rms", "rest shape, rms difference", "1/m"),
                  ("model.rest_max", "rest shape, largest difference", "1/m"),
                  ("model.rest_stiffened_rms", "stiffened rest shape, rms difference", "1/m"),
                  ("model.rest_stiffened_max", "stiffened rest shape, largest difference", "1/m"),
                  ("model.stiffening", "stiffening factors, largest difference", "")]
        both = self.groups_of(stages.MODEL)
        if isinstance(both, str):
            for key, label, unit, *_ in material + solver + shapes:
                self.skip(key, label, unit, both)
            return
        go, gn = both
        for key, label, unit, scale in material:
            name = key.split(".")[1]
            missing = self.optional(stages.MODEL, name, attr=True)
            if missing:
                self.skip(key, label, unit, missing[1], missing[0])
                continue
            vo, vn = go.attrs[name], gn.attrs[name]
            if scale is None:
                self.exact(key, label, unit, str(vo), str(vn))
            else:
                self.exact(key, label, unit, float(vo) * scale, float(vn) * scale)
        # the solver's outcome
        missing = self.optional(stages.MODEL, "status", attr=True)
        if missing:
            self.skip(*solver[0], missing[1], missing[0])
        else:
            self.exact(*solver[0], str(go.attrs["status"]), str(gn.attrs["status"]))
        missing = self.optional(stages.MODEL, "iterations", attr=True)
        if missing:
            self.skip(*solver[1], missing[1], missing[0])
        else:
            so, sn = int(go.attrs["iterations"]), int(gn.attrs["iterations"])
            self.add(Row(*solver[1], so, sn, sn - so, self.tol.sweeps,
                         PASS if abs(sn - so) <= self.tol.sweeps else FAIL))
        missing = self.optional(stages.MODEL, "residual", attr=True)
        if missing:
            self.skip(*solver[2], missing[1], missing[0])
        else:
            ro, rn = float(go.attrs["residual"]), float(gn.attrs["residual"])
            self.scalar(*solver[2], 1.0, ro, rn, self.tol.force + self.tol.rtol * abs(ro))
        helices_o = self.old.groups.get(stages.HELICES)
        helices_n = self.new.groups.get(stages.HELICES)
        self.objective(solver[3], go, gn)
        missing = self.optional(stages.MODEL, "carrying_threshold", attr=True)
        if missing:
            self.skip(*solver[4], missing[1], missing[0])
        else:
            to, tn = float(go.attrs["carrying_threshold"]), float(gn.attrs["carrying_threshold"])
            self.scalar(*solver[4], 1.0, to, tn, self.tol.force + self.tol.rtol * abs(to))
        missing = self.optional(stages.MODEL, "stability_margin")
        if missing:
            self.skip(*solver[5], missing[1], missing[0])
        else:
            from .model import UNSTABLE_MARGIN

            uo, un = (np.flatnonzero(np.asarray(g["stability_margin"]) < UNSTABLE_MARGIN) for g in (go, gn))
            changed = np.setxor1d(uo, un)
            self.add(Row(*solver[5], len(uo), len(un), len(un) - len(uo), 0, FAIL if len(changed) else PASS,
                         "", [(int(k), 1.0) for k in changed]))
        # contact forces, where the contact sets match
        contacts = self.groups_of(stages.CONTACTS)
        if isinstance(contacts, str):
            self.skip(*shapes[0], contacts)
        elif pairs is None:
            self.skip(*shapes[0], "the contact sets differ (contacts.set)")
        elif len(go["force"]) != len(contacts[0]["strand"]) or len(gn["force"]) != len(contacts[1]["strand"]):
            self.skip(*shapes[0], "/model/force does not hold one row per contact")
        else:
            co, cn = contacts
            i, j = pairs
            world_o = np.einsum("cji,cj->ci", co["frame"][i], go["force"][i])  # frame.T @ r
            world_n = np.einsum("cji,cj->ci", cn["frame"][j], gn["force"][j])
            strand = co["strand"].reshape(-1, 2)[i]
            size = np.linalg.norm(world_o, axis=1)
            self.entries(*shapes[0], 1.0, np.linalg.norm(world_n - world_o, axis=1),
                         self.tol.force + self.tol.rtol * size, [strand[:, 0], strand[:, 1]], _largest(size),
                         _largest(np.linalg.norm(world_n, axis=1)))
        # rest shapes and stiffening, per element and per strand
        same_elements = (helices_o is not None and helices_n is not None
                         and np.array_equal(helices_o["offsets"], helices_n["offsets"]))
        layout = None if same_elements else (
            "the strands have different elements" if helices_o is not None and helices_n is not None
            else "a file has no /helices")
        for name, (rms_key, max_key) in (("omega_rest", (shapes[1], shapes[2])),
                                         ("omega_rest_stiffened", (shapes[3], shapes[4]))):
            missing = self.optional(stages.MODEL, name)
            if missing or layout:
                verdict, note = missing or (SKIPPED, layout)
                self.skip(*rms_key, note, verdict)
                self.skip(*max_key, note, verdict)
                continue
            if len(go[name]) != int(helices_o["offsets"][-1]) or len(gn[name]) != int(helices_n["offsets"][-1]):
                self.skip(*rms_key, f"/model/{name} does not hold one row per element")
                self.skip(*max_key, f"/model/{name} does not hold one row per element")
                continue
            self.curvature_rows(max_key, rms_key, go[name], gn[name], helices_o["offsets"])
        missing = self.optional(stages.MODEL, "stiffening")
        if missing:
            self.skip(*shapes[5], missing[1], missing[0])
        elif len(go["stiffening"]) != len(gn["stiffening"]):
            self.skip(*shapes[5], "the files have different strand counts")
        else:
            fo, fn = go["stiffening"], gn["stiffening"]
            self.entries(*shapes[5], 1.0, np.abs(fn - fo), self.tol.factor + self.tol.rtol * np.abs(fo),
                         np.arange(len(fo)), _largest(fo), _largest(fn))

    def objective(self, key, go: stages.Group, gn: stages.Group) -> None:
        """``1/2 sum_e w_e |q0_e - q0target_e|^2 + 1/2 sum_c gamma_c |r_c|^2`` (docs/stage-files.md; ``gamma_c`` is
        ``/model/contact_gamma`` where the file has it, else ``gamma``), with the rest shape a
        simulation uses (the stiffened strands' own) when both files hold it, else ``omega_rest``. It may move
        by what its terms may move by, to first order: ``sum_e w_e |q0_e - q0target_e| tol_e + gamma sum_c
        |r_c| tol_c``, plus rtol of itself."""
        both_stiffened = "omega_rest_stiffened" in go.datasets and "omega_rest_stiffened" in gn.datasets

        def value(g):
            rest = rest_from_group(g) if both_stiffened else np.asarray(g["omega_rest"], dtype=np.float64)
            target, weight = g["omega_target"], g["target_weight"]
            if rest.shape != target.shape or len(weight) != len(rest):
                return None, None
            drift = np.linalg.norm(rest - target, axis=1)
            force = np.linalg.norm(g["force"].reshape(-1, 3), axis=1)
            gamma = float(g.attrs.get("gamma", 0.0))
            if "contact_gamma" in g.datasets and len(g["contact_gamma"]) == len(force):
                gamma = np.asarray(g["contact_gamma"], dtype=np.float64)  # each contact's own weight
            objective = 0.5 * float(np.sum(weight * drift ** 2)) + 0.5 * float(np.sum(gamma * force ** 2))
            rtol = self.tol.rtol
            spread = (float(np.sum(weight * drift * (self.tol.curvature + rtol * np.linalg.norm(rest, axis=1))))
                      + float(np.sum(gamma * force * (self.tol.force + rtol * force))) + rtol * abs(objective))
            return objective, spread

        oo, tol = value(go)
        on, _ = value(gn)
        if oo is None or on is None:
            self.skip(*key, "the rest shape, target and weights of /model do not match in size")
            return
        self.scalar(*key, 1.0, oo, on, tol)

    # ------------------------------------------------------------------ /frames

    def frames(self) -> None:
        keys = [("frames.count", "frames", "frames"), ("frames.time", "frame times, largest difference", "s"),
                ("frames.positions", "frame positions, largest distance", "mm")]
        both = self.groups_of(stages.FRAMES)
        if isinstance(both, str):
            for key in keys:
                self.skip(*key, both)
            return
        go, gn = both
        to, tn = go["time"], gn["time"]
        common = min(len(to), len(tn))
        self.exact(*keys[0], len(to), len(tn),
                   "" if len(to) == len(tn) else f"the first {common} frames compared")
        self.entries(*keys[1], 1.0, np.abs(tn[:common] - to[:common]),
                     self.tol.time + self.tol.rtol * np.abs(to[:common]), np.full(common, -1),
                     float(to[-1]) if len(to) else None, float(tn[-1]) if len(tn) else None)
        self.positions(keys[2], common)

    def positions(self, key, common: int) -> None:
        """The frames' centerlines at the input's vertices, as ``hairinv export`` writes them (its
        :class:`~hairinv.export.source.ExportSource` evaluates them), point by point."""
        from .export.source import ExportSource

        try:
            src_o, src_n = ExportSource(self.old.path), ExportSource(self.new.path)
        except InputError as exc:
            self.skip(*key, f"the frames cannot be evaluated: {exc}")
            return
        e_off, length, v_off, _ = src_o.frame_layout()
        if not np.array_equal(v_off, src_n.frame_layout()[2]):
            counts_differ = any(r.verdict == FAIL for r in self.rows
                                if r.key in ("curves.strands", "curves.points", "helices.elements"))
            self.skip(*key, "the frames' strands have different vertices (strands or cuts differ)",
                      SKIPPED if counts_differ else FAIL)
            return
        owner = _owner(v_off)
        strand_length = np.bincount(_owner(e_off), weights=length, minlength=len(v_off) - 1)
        tol = self.tol.length + self.tol.rtol * strand_length[owner]
        worst = np.zeros(len(owner))
        per_frame = []
        for k in range(common):
            d = np.linalg.norm(src_n.frame(k).points - src_o.frame(k).points, axis=1)
            worst = np.maximum(worst, d)
            i = int(np.argmax(d)) if len(d) else -1
            beyond = d > tol
            per_frame.append({"frame": k, "time_s": float(src_o.times[k]),
                              "largest_mm": _MM * float(d[i]) if i >= 0 else 0.0,
                              "strand": int(owner[i]) if i >= 0 else None,
                              "strands_beyond": int(len(np.unique(owner[beyond])))})
        row = self.entries(*key, _MM, worst, tol, owner, note="" if common else "no frame to compare",
                           per_frame=per_frame)
        moved = [f for f in per_frame if f["strands_beyond"]]
        if moved:
            first = moved[0]
            row.note = (f"beyond tolerance in {len(moved)} of {common} frames, first frame {first['frame']} "
                        f"(t = {first['time_s']:.4g} s); largest distance per frame, mm: "
                        + ", ".join(f"{f['largest_mm']:.3g}" for f in per_frame[:FRAMES_IN_NOTE])
                        + (" ..." if common > FRAMES_IN_NOTE else ""))

    # ------------------------------------------------------------------ settings

    def settings(self) -> list[dict]:
        """The effective settings (each group's ``config``) that differ: information, not a verdict."""
        out = []
        for name in stages.PIPELINE:
            if name not in self.old or name not in self.new:
                continue
            co, cn = _flatten(self.old[name].config), _flatten(self.new[name].config)
            for key in sorted(set(co) | set(cn)):
                if co.get(key) != cn.get(key):
                    out.append({"group": name, "key": key, "old": co.get(key), "new": cn.get(key)})
        return out


def _match_contacts(strand_o, s_o, strand_n, s_n, atol: float, rtol: float):
    """Pair the contacts of two files: the same strands (A, B) and arc lengths within ``atol + rtol |s|``.

    Returns ``((old index, new index) arrays of the pairs, unmatched old indices, unmatched new indices)``.
    Contacts are detected strand by strand in a fixed order, so two runs list them alike; otherwise each
    strand pair's contacts are walked in order of their arc length along A.
    """
    def close(i, j):
        return np.all(np.abs(s_n[j] - s_o[i]) <= atol + rtol * np.abs(s_o[i]))

    if len(strand_o) == len(strand_n) and np.array_equal(strand_o, strand_n):
        ok = np.all(np.abs(s_n - s_o) <= atol + rtol * np.abs(s_o), axis=1)
        if ok.all():
            idx = np.arange(len(strand_o))
            return (idx, idx), [], []
    groups_o: dict[tuple[int, int], list[int]] = {}
    groups_n: dict[tuple[int, int], list[int]] = {}
    for groups, strand in ((groups_o, strand_o), (groups_n, strand_n)):
        for c, (a, b) in enumerate(strand.tolist()):
            groups.setdefault((a, b), []).append(c)
    pairs_o, pairs_n, lost, found = [], [], [], []
    for pair in sorted(set(groups_o) | set(groups_n)):
        lo = sorted(groups_o.get(pair, []), key=lambda c: (s_o[c, 0], s_o[c, 1]))
        ln = sorted(groups_n.get(pair, []), key=lambda c: (s_n[c, 0], s_n[c, 1]))
        i = j = 0
        while i < len(lo) and j < len(ln):
            if close(lo[i], ln[j]):
                pairs_o.append(lo[i])
                pairs_n.append(ln[j])
                i += 1
                j += 1
            elif s_o[lo[i], 0] <= s_n[ln[j], 0]:
                lost.append(lo[i])
                i += 1
            else:
                found.append(ln[j])
                j += 1
        lost += lo[i:]
        found += ln[j:]
    return (np.asarray(pairs_o, dtype=np.int64), np.asarray(pairs_n, dtype=np.int64)), lost, found


def diff_stages(old: stages.StageFile, new: stages.StageFile, tolerances: Tolerances | None = None) -> Diff:
    """Compare two stage files read with :func:`hairinv.stages.read_stage`.

    The frames are evaluated from the files on disk (``old.path``, ``new.path``) by the export code.
    """
    tol = tolerances or Tolerances()
    c = _Comparison(old, new, tol)
    c.file()
    c.curves()
    c.helices()
    pairs = c.contacts()
    c.model(pairs)
    c.frames()
    return Diff(old, new, tol, c.rows, c.settings())


def diff_files(old, new, tolerances: Tolerances | None = None) -> Diff:
    """Read and compare two stage files; :class:`InputError` (naming the file) if one is missing or unreadable."""
    read = []
    for path in (Path(old), Path(new)):
        if not path.exists():
            raise InputError("no such file", path)
        if path.is_dir():
            raise InputError("is a folder, not a stage file", path)
        read.append(stages.read_stage(path))
    return diff_stages(read[0], read[1], tolerances)


# --------------------------------------------------------------------------- text


#: Strands named per failing row in the text table.
TEXT_STRANDS = 3
#: Widest old or new value in the text table (the full values are in the JSON and the header lines).
TEXT_WIDTH = 24


def _text(value, width: int | None = None) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return "0" if value == 0 else f"{value:.4g}"
    text = str(value)
    return text if width is None or len(text) <= width else text[:width - 3] + "..."


def report_lines(diff: Diff, every_row: bool = False) -> list[str]:
    """The comparison as a table for a terminal or a CI log: a header, one line per quantity (the quantities
    of groups neither file holds left out unless ``every_row``), the notes (what was skipped and why, what
    differs, the settings that differ), and the verdict last."""
    lines = [f"{name}: {stage.path} ({stage.producer or 'unknown producer'}; {','.join(stage.groups)})"
             for name, stage in (("old", diff.old), ("new", diff.new))]
    t = diff.tolerances
    lines.append(f"tolerances: length {_MM * t.length:g} mm, curvature {t.curvature:g} 1/m, force {t.force:g} N, "
                 f"factor {t.factor:g}, time {t.time:g} s, sweeps {t.sweeps}; plus rtol {t.rtol:g} of each old value")
    shown = [r for r in diff.rows if every_row or r.note != f"/{r.group} is in neither file"]
    header = ("quantity", "unit", "old", "new", "difference", "tolerance", "verdict", "strands")
    table = []
    for r in shown:
        strands = ""
        if r.strands:
            strands = ", ".join(f"{k} ({_text(d)})" for k, d in r.strands[:TEXT_STRANDS])
            if len(r.strands) > TEXT_STRANDS:
                strands += f" +{len(r.strands) - TEXT_STRANDS} more"
        table.append((f"/{r.group} {r.label}", r.unit, _text(r.old, TEXT_WIDTH), _text(r.new, TEXT_WIDTH),
                      _text(r.difference),
                      _text(r.tolerance), r.verdict, strands))
    widths = [max(len(row[i]) for row in [header, *table]) for i in range(len(header) - 1)]
    for row in [header, *table]:
        lines.append(("  ".join(cell.ljust(w) for cell, w in zip(row, widths)) + "  " + row[-1]).rstrip())
    notes = [f"{r.key}: {r.note}" for r in shown if r.note]
    notes += [f"setting /{s['group']} {s['key']}: {s['old']!r} -> {s['new']!r}" for s in diff.settings_changed]
    if notes:
        lines.append("notes (why a quantity was skipped, what differs, the settings that differ):")
        lines += [f"  {note}" for note in notes]
    failed = diff.failed
    compared = [r for r in diff.rows if r.verdict != SKIPPED]
    if failed:
        lines.append(f"diff: FAIL, {len(failed)} of {len(compared)} quantities compared differ beyond their "
                     "tolerance: " + ", ".join(r.key for r in failed))
    else:
        lines.append(f"diff: PASS, all {len(compared)} quantities compared are within their tolerance")
    return lines
