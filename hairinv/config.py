"""Typed settings: defaults, TOML presets and ``key=value`` overrides.

Settings are frozen dataclasses, one per stage, each field with its unit and
the reason for its default. They are resolved in this order, later wins:
defaults, the quality preset (``configs/quality/<name>.toml``), a user
``--config FILE.toml``, then ``--set section.key=value`` overrides. Unknown
sections or keys are rejected by name.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"
QUALITIES = ("draft", "default", "final")
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}


@dataclass(frozen=True)
class ImportSettings:
    """How a hairstyle file becomes strands in metres."""

    units: str = "auto"
    """File unit: m, cm, mm, in, or auto (guessed from the size of the body or the hair, and reported)."""
    scale: float = 0.0
    """Metres per file unit; overrides ``units`` when > 0 (for odd units such as 0.1 inch = 0.00254)."""
    up: str = "auto"
    """World up axis of the file: x, y, z, or auto (the format's own convention, reported). Gravity is along -up."""
    flip: str = ""
    """Axes negated on import, e.g. "z" for a left-handed (DirectX) export; applied before scaling."""
    merge_tolerance: float = 1e-7
    """m. Consecutive points closer than this are merged: repeated points carry no shape."""
    min_length: float = 1e-3
    """m. Strands shorter than this are dropped: they cannot carry a super-helix."""
    guides: int = 0
    """Keep only this many strands, a seeded random subset evenly spread over the scalp (0 keeps all)."""
    seed: int = 0
    """Seed of the guide selection, so the same command picks the same strands."""


@dataclass(frozen=True)
class BodySettings:
    """How the body mesh is brought into the hair's frame, when its file is in other units or axes.

    By default the body file is read in the hair's unit, axes and flip (one unit for both files). A groom
    in centimetres on a head in metres is common: then say the body's own unit here."""

    units: str = "hair"
    """Body file unit: m, cm, mm, in; auto (guessed from the body's size, reported); or hair (the hair's)."""
    scale: float = 0.0
    """Metres per body file unit; overrides ``units`` when > 0."""
    up: str = "hair"
    """The body file's up axis: x, y, z, or hair (the same axes as the hair). When it differs from the
    hair's up axis, the body is turned by the smallest rotation taking its up axis onto the hair's."""
    flip: str = "hair"
    """Axes of the body file negated on import, e.g. "z"; none for no flip; hair: the hair's --flip."""
    bind_time: str = "rest"
    """For an animated body, the pose the groom was made on: rest (the pose the file stores: a skinned mesh's
    bind pose, a point cache's or a sequence's first frame), or a time in seconds from the animation's start,
    e.g. 0 for its first frame. The roots are bound to the body in that pose."""
    rest_mesh: str = ""
    """A mesh file of the animated body in the pose the groom was made on (the same vertices, in the same order,
    and the same triangles), when that pose is neither the file's rest pose nor a time of its animation."""


@dataclass(frozen=True)
class FitSettings:
    """Curves to G1 piecewise super-helices."""

    tolerance: float = 2e-4
    """m. Target for the largest distance between an input vertex and the fitted curve at its arc length.
    0.2 mm is twice a hair's diameter; elements are added until it is met or max_elements is reached."""
    elements: int = 0
    """Fixed number of elements per strand; 0 chooses it adaptively from the tolerance."""
    min_elements: int = 4
    """Smallest element count tried by the adaptive fit (the paper uses 6 to 40)."""
    max_elements: int = 0
    """Largest element count; 0 (the default): as many as the tolerance needs, up to what the vertices
    determine: 3 n + 3 parameters for the 2 (M - 1) distances of M vertices, so n <= (2 M - 5) / 3 (a
    21-point strand carries at most 12). Elements are chosen along the strand, each as long as one helix
    fits its vertices at their arc lengths, so a tight curl gets the elements it needs and no element
    winds between vertices. A strand that misses the tolerance is reported, with why."""
    max_iterations: int = 40
    """Levenberg-Marquardt iterations per element count; near-zero-residual fits converge in under 10."""


#: The physical range of each material constant (SI), beyond which a value is a mistake (a unit slip,
#: a stray exponent) rather than a material: Young's and shear moduli from soft gels to beyond diamond
#: (1.2e12 Pa; a shear modulus down to E / 3), densities from aerogels to beyond osmium (22,590 kg/m^3),
#: fibre radii from 0.1 um to a 1 cm rope, gravity from 1e-3 m/s^2 (or none) to 100 g. Values outside are
#: refused where they are read (settings and /model), as hair far outside them makes the arithmetic
#: overflow or underflow.
MATERIAL_RANGE = {
    "youngs_modulus": (1e3, 1e14, "Pa"),
    "shear_modulus": (1e2, 1e14, "Pa"),  # E / 3 at the least, for the least E
    "density": (1.0, 1e5, "kg/m^3"),
    "radius": (1e-7, 1e-2, "m"),
    "gravity": (1e-3, 1e3, "m/s^2"),  # or 0: none
}


def material_range_error(key: str, value: float, setting: bool = True) -> str | None:
    """The sentence refusing ``value`` for the material constant ``key`` (out of :data:`MATERIAL_RANGE`,
    or not a finite number), or None where it is within range. A gravity of 0 is within range (no
    gravity), and so is a shear modulus of 0 where it is a ``setting`` (derived from E) rather than the
    modulus in use."""
    lo, hi, unit = MATERIAL_RANGE[key]
    if value == 0 and (key == "gravity" or (key == "shear_modulus" and setting)):
        return None
    try:
        inside = lo <= float(value) <= hi
    except (TypeError, ValueError):
        inside = False
    if inside:
        return None
    return f"{key} is {value!r}; it must be a number from {lo:g} to {hi:g} {unit}" + (
        " (or 0: from E and poisson_ratio)" if key == "shear_modulus" and setting else
        " (or 0: no gravity)" if key == "gravity" else "")


@dataclass(frozen=True)
class MaterialSettings:
    """The hair material: stiffness, mass and cross-section (paper, section 7)."""

    youngs_modulus: float = 4e9
    """Pa. Young's modulus E of hair keratin; the paper uses 4 GPa for every groom."""
    poisson_ratio: float = 0.48
    """Poisson ratio nu of hair; the shear modulus is G = E / (2 (1 + nu)) unless ``shear_modulus`` is set."""
    shear_modulus: float = 0.0
    """Pa. Shear modulus G for the twist stiffness GJ; 0 derives it from E and ``poisson_ratio``."""
    density: float = 1300.0
    """kg/m^3. Volumetric density of hair (paper: 1300)."""
    radius: float = 5e-5
    """m. Radius of the circular cross-section (a 0.1 mm thick hair); I = pi r^4 / 4, J = pi r^4 / 2."""
    gravity: float = 9.81
    """m/s^2. Gravity's magnitude; it points along minus the groom's up axis. 0: a scene without gravity
    (the input shape is then its own rest shape wherever no contact pushes on it)."""

    @property
    def shear(self) -> float:
        return self.shear_modulus if self.shear_modulus > 0 else self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True)
class ContactSettings:
    """Where contacts are declared (paper, section 5: bounding cylinders and spatial hashing)."""

    body: bool = True
    """Declare hair-body contacts (false: the body is ignored)."""
    hair_hair: bool = True
    """Declare hair-hair contacts."""
    body_distance: float = 4e-3
    """m. A strand point closer than this to the body surface touches it. Captured hair floats a few
    millimetres off the scalp, so this is larger than the hair-hair distance (the paper uses 1-10x)."""
    hair_distance: float = 1e-3
    """m. Two strands whose centerlines come closer than this touch (the width of the bounding cylinders)."""
    root_clearance: float = 5e-3
    """m. No body contact within this arc length of the root: the root is clamped there already."""
    max_hair_per_element: int = 8
    """Hair-hair contacts kept per element, the closest first (0: no limit). On ruby short (1,867 guides)
    8 keeps 20,684 of 25,526; dense grooms (follow hairs packed within millimetres) would otherwise
    declare one contact per element and neighbour, over 100 per strand."""
    mu_body: float = 0.3
    """Coulomb friction coefficient between hair and body (paper: 0.1-0.3)."""
    mu_hair: float = 0.3
    """Coulomb friction coefficient between two hairs."""
    samples_per_element: int = 8
    """Points per element at which the distance to the body and to other strands is measured (at least 2)."""
    layer: bool = True
    """Also declare body contacts where a strand runs along the body at a nearly constant gap beyond
    body_distance (the empty layer above the skin of combed grooms and captures; paper, section 4.1)."""
    layer_max_gap: float = 1e-2
    """m. The widest hair layer looked for: 10 times the hair-hair distance, the paper's widest cylinders
    (it widened near-body wisps 1 to 10 times by hand)."""
    layer_tolerance: float = 1.5e-3
    """m. How far above its run's gap (the median distance of the run's samples) a point may lie and still
    rest on the layer; farther, the strand is leaving the body there."""
    layer_min_length: float = 2e-2
    """m. Arc length over which a strand must stay within its gap + layer_tolerance of the body before it
    is taken as lying on a layer: a strand only passing by the body comes that close over a short stretch."""
    wisp: bool = True
    """Also declare hair-hair contacts where a strand rests on another one below it (against gravity)
    within their wisps' width, derived from the local strand spacing, beyond hair_distance."""
    hair_max_distance: float = 3e-3
    """m. The widest wisp contact: centre lines this far apart may still rest on each other when the
    strands around them are as far apart (sparse guide strands standing for wisps)."""


@dataclass(frozen=True)
class SolverSettings:
    """The inverse problem and its cone complementarity solver (paper, section 6)."""

    target: str = "actual"
    """Rest shape the inversion draws towards: actual (the input curvature, the paper's choice), zero,
    uniform (each strand's mean curvature), tip (the curvature at the free end), or gravity-only
    (no contacts: q0 = q - K^-1 F_g, the baseline)."""
    gamma: float = 1e-3
    """N^-2 m^-2. Weight of the contact forces in the objective (paper: 1e-3 for every groom)."""
    gamma_relative: float = 1e-4
    """Each contact's weight in the objective is at least this fraction of its own diagonal of ``W`` (what a
    force on that contact alone moves the rest shape by): it bounds the loops of opposed forces that the
    paper's ``gamma`` leaves free (docs/inverse.md, "Bounded forces"). 0: the paper's problem."""
    tolerance: float = 1e-4
    """The sweeps stop when the natural-map residual is below this fraction of the heaviest strand's weight,
    or when ``rest_tolerance`` is met, whichever comes first (docs/inverse.md; the equilibrium itself is exact
    whatever the residual, it measures optimality)."""
    max_sweeps: int = 2000
    """Largest number of Gauss-Seidel sweeps over all contacts."""
    method: str = "auto"
    """auto (the default: the interior-point method where its factorisation costs at most
    ``hairinv.inverse.method.AUTO_GFLOP`` a step, the sweeps otherwise), interior-point (a primal-dual interior-point
    method, one sparse Cholesky factorisation a step, stopped by ``rest_tolerance``: it reaches the optimum
    where the sweeps stall, at the cost of factoring a system as large as the groom's coordinates) or sweeps
    (block Gauss-Seidel over the contacts, stopped by ``rest_tolerance`` or ``tolerance``). docs/inverse.md,
    "The solver"."""
    rest_tolerance: float = 0.05
    """1/m. Both methods stop once a duality gap bounds the distance of the rest shape from the optimum
    (rms over elements) below this; the sweeps stop too at ``tolerance``."""
    max_iterations: int = 100
    """Largest number of interior-point steps."""
    check_every: int = 5
    """Sweeps between two residual evaluations (each costs one product with W)."""
    max_seconds: float = 0.0
    """s. Stop after this much solver time even before max_sweeps (status MAX_ITERS); 0: no limit.
    For batch jobs with a time budget; the model written is an exact equilibrium either way."""
    accelerate: bool = True
    """Nesterov momentum over the sweeps, dropped whenever a sweep would raise the objective.
    On the wavy sample it reaches in 200 sweeps the objective plain sweeps reach in 1,600."""
    warm_start: bool = True
    """Start from the forces of the input file's /model when it has one for the same contacts (a model
    written by an earlier invert), so that inverting a model again continues where that run stopped."""
    stabilize: str = "stiffen"
    """What to do with a strand whose inverted equilibrium is unstable even on its supports: stiffen
    (multiply its bending and twist stiffness by the smallest factor that makes it stable, times
    stiffen_margin, and invert it with that stiffness) or off (keep the material and only report it).
    A strand the contacts cannot hold would otherwise fall away as soon as a simulation starts."""
    check_stability: bool = True
    """Check every strand's stability after the inversion (an eigen-decomposition per strand, the
    ``/model/stability_margin``). false skips it: no margins, no unstable strands reported, and so no
    stiffening (it needs stabilize = off). For runs whose stability a later ``hairinv verify`` judges."""
    stable_under: str = "forces"
    """What the stability check (and so stabilize) holds: forces (the contact forces held fixed, every
    motion allowed: what a simulation at rest needs, since its contact solve answers only past its
    tolerance) or supports (the loaded contact points held in place, and strands leaning on each other
    checked together: the weaker condition, fewer strands stiffened, but a still simulation lets some
    of them grow from round-off; docs/dynamics.md, Stability)."""
    friction_reserve: float = 0.1
    """The part of each contact's friction the inversion leaves unused: its forces are found in the cones
    of ``mu (1 - friction_reserve)`` and so lie inside the declared cones by that margin. Friction used to
    the full is static friction at the point of sliding: a still simulation then slips it from round-off
    and the groom creeps (on a generated updo, 345 of 400 strands moved 2.4 mm within 0.2 s; with a tenth
    in reserve none moved). 0 uses the declared friction to the full (the problem as declared, e.g. to
    compare with another solver); must be in [0, 1)."""
    stiffen_margin: float = 1.2
    """The stiffening factor is this times the critical one (at which the strand's equilibrium is
    neutral): the smallest eigenvalue of the scaled Hessian is then 1 - 1/margin = 0.17 of the
    material's own, so round-off and the simulation's finite steps do not tip it over."""


@dataclass(frozen=True)
class DynamicsSettings:
    """Time stepping of ``simulate`` (docs/dynamics.md)."""

    time_step: float = 0.01
    """s. Step of the linearly implicit Euler integrator; four steps per 1/25 s frame. It is stable at any
    step (the stiffness enters implicitly); smaller steps resolve fast motion and contact better."""
    damping: float = 0.01
    """s. Internal viscous damping of the rod, proportional to its stiffness: D = damping * K. It damps
    the fast bending modes (period under 0.1 s) within a few oscillations and the slow swing barely."""
    air_damping: float = 1.0
    """1/s. Air drag per unit mass against the strand's velocity in the world: hair set swinging settles
    in a few seconds, as real hair does."""
    body_thickness: float = 2e-3
    """m. How close a strand may come to the body once a new contact appears there. Contacts of the
    inverted model keep the distance they had, so a still groom stays exactly where it was."""
    hair_thickness: float = 5e-4
    """m. The same for new hair-hair contacts: the closest two centerlines may come."""
    push_speed: float = 0.05
    """m/s. Largest speed at which a strand found closer than its thickness is pushed back out; near a root
    less, at most ``0.05 max_turn s / time_step`` at arc ``s`` from it, so that a push does not bend the root
    element past ``max_turn`` (docs/dynamics.md)."""
    tolerance: float = 1e-6
    """Contact solve stops when every contact's velocity error (the natural-map residual times the
    contact's own Delassus scale) is below this fraction of g h, the speed gravity adds in one step."""
    max_sweeps: int = 200
    """Largest number of Gauss-Seidel sweeps per step (warm started from the previous step). A solve that
    converges takes what it needs (32 guides landing from a jump: 60-130 sweeps a step); one that stalls stops
    on ``stall_rounds`` first. Capped at 40 instead, the landing's truncated solves threw 4x the reference's
    kinetic energy into the hair (one strand whipped 701 mm from its rest place, against 458 for a run at a
    quarter of the step with every sweep; docs/dynamics.md)."""
    stall_rounds: int = 1
    """A step's contact solve stops early, keeping its best iterate, once this many rounds in a row (a
    round: one convex problem of the Coulomb fixed point, at most a tenth of ``max_sweeps``) have not
    halved its residual; 0 never stops early. Dense moving hair-hair contact rarely meets the tolerance
    and stalls: ruby short moving stops after 45-65 sweeps a step at 1 (5.0 s a frame from 0.5 s into the
    ``motion`` scene, 0.13 / 0.67 mm from a 1,000-sweep reference; with a cap of 40 sweeps instead 3.7-4.0 s,
    0.13 / 0.60 mm), with no halved step from the scene's start (4.2 s a frame). At ``max_turn`` 0.05 one
    stalled round let ruby short cascade into halved steps from the start (62 s a frame against 10 at 3;
    docs/dynamics.md)."""
    quadrature: int = 4
    """Gauss-Legendre points per element for the mass matrix and the inertial forces."""
    inertia_radius: float = 5e-3
    """m. Radius of the disc whose rotational inertia the cross-sections get (with the hair's own linear
    density). A 50 um hair's own makes twist nearly massless (around 3e4 rad/s), which the step cannot
    follow: strands released from contact then gain energy and blow up. 5 mm, the size of the wisp a guide
    strand stands for, brings it near 200 rad/s; bending and swinging are unchanged (docs/dynamics.md)."""
    max_turn: float = 0.1
    """rad. A step is split in halves while any element would turn by more than this within it: the step
    is linearised at its start, and a strand springing towards a distant rest shape is far from linear.
    Every strand takes the halved steps, so one strand's tip halves a whole groom's step: 0.05 halved ruby
    short's steps three times as often for no gain from the start of a motion (docs/dynamics.md)."""
    max_substeps: int = 6
    """Largest number of halvings of one step (down to 1/64 of it)."""
    sleep_speed: float = 1e-6
    """m/s. Strands at rest are put to sleep, island by island (strands joined by hair-hair contact), and
    cost nothing until the body's motion changes, the body moves near them or a strand hits them: at rest
    means that no point of any strand of the island has moved faster than this for three steps in a row
    under an unchanged body motion (docs/dynamics.md, "Sleeping"). 0: nothing sleeps. ``verify`` never
    lets strands sleep: it checks that they stay still."""


@dataclass(frozen=True)
class Settings:
    """All settings of a run, one section per stage."""

    import_: ImportSettings = field(default_factory=ImportSettings)
    body: BodySettings = field(default_factory=BodySettings)
    fit: FitSettings = field(default_factory=FitSettings)
    material: MaterialSettings = field(default_factory=MaterialSettings)
    contacts: ContactSettings = field(default_factory=ContactSettings)
    solver: SolverSettings = field(default_factory=SolverSettings)
    dynamics: DynamicsSettings = field(default_factory=DynamicsSettings)

    def to_dict(self) -> dict:
        return {_section_name(f.name): dataclasses.asdict(getattr(self, f.name)) for f in dataclasses.fields(self)}


def _section_name(attr: str) -> str:
    return attr.rstrip("_")


_SECTIONS = {_section_name(f.name): f.name for f in dataclasses.fields(Settings)}


#: Units a length may be written in, metres per unit: ``0.2mm``, ``4 mm``, ``1e-4m``, ``100um``.
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "in": 0.0254}
_LENGTH = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d.+-][^\s]*)?\s*")


def parse_length(text: str, option: str = "length", bare_metres: bool = False, positive: bool = True) -> float:
    """Metres from a length written with its unit: ``0.1mm``, ``1e-4m``, ``0.01 cm``, ``100um``.

    One rule for every length hairinv reads: a unit may always be given. A bare number is metres where
    ``bare_metres`` (the settings, and options whose help says metres); elsewhere it is refused, since
    ``0.1`` could mean 0.1 m or 0.1 mm, and a check a thousand times too lax would pass silently. The
    length must be finite, and > 0 where ``positive`` (else a setting's own range judges its sign, and
    its refusal names the setting).

    Raises
    ------
    InputError
        One sentence starting with ``option``.
    """
    units = ", ".join(u for u in LENGTH_UNITS if u != "µm")
    match = _LENGTH.fullmatch(text)
    if match is None:
        raise InputError(f"{option}: {text!r} is not a length; give a number and a unit ({units}), e.g. 0.1mm")
    number, unit = match.groups()
    if unit is None and not bare_metres:
        raise InputError(f"{option}: {text!r} has no unit; give one ({units}), e.g. 0.1mm or 1e-4m")
    if unit is not None and unit not in LENGTH_UNITS:
        raise InputError(f"{option}: unknown unit {unit!r} in {text!r}; use one of {units}")
    value = float(number) * LENGTH_UNITS[unit or "m"]
    if not (math.isfinite(value) and (value > 0 or not positive)):
        raise InputError(f"{option}: {text!r} must be a length > 0" if positive else
                         f"{option}: {text!r} must be a finite length")
    return value


#: The documented range of every numeric setting, ``section.key -> (least, largest, unit)``, bounds
#: included; a value outside, or not finite, is refused where it is read (:func:`apply`), before any
#: size is derived from it. The bounds are far beyond any groom's (a unit slip, a stray exponent, an
#: allocation of terabytes), not advice; the stages refuse finer mistakes with their own reasons (e.g.
#: ``solver.gamma`` > 0). A unit ``m`` marks a length: it may be written with its unit (``0.2mm``), a
#: bare number is metres. Keys of :data:`ZERO_MEANS` also take 0.
SETTING_RANGE = {
    "import.scale": (1e-9, 1e3, "m per file unit"),
    "import.merge_tolerance": (0.0, 1.0, "m"),
    "import.min_length": (0.0, 10.0, "m"),
    "import.guides": (0, 10**9, "strands"),
    "import.seed": (0, 2**63 - 1, ""),
    "body.scale": (1e-9, 1e3, "m per file unit"),
    "fit.tolerance": (1e-9, 1.0, "m"),
    "fit.elements": (1, 1000, "elements"),
    "fit.min_elements": (1, 1000, "elements"),
    "fit.max_elements": (1, 1000, "elements"),
    "fit.max_iterations": (1, 10**6, "iterations"),
    **{f"material.{key}": value for key, value in MATERIAL_RANGE.items()},
    "material.poisson_ratio": (-0.99, 0.5, ""),
    "contacts.body_distance": (0.0, 1.0, "m"),
    "contacts.hair_distance": (0.0, 1.0, "m"),
    "contacts.root_clearance": (0.0, 10.0, "m"),
    "contacts.max_hair_per_element": (1, 10**6, "contacts"),
    "contacts.mu_body": (0.0, 1e3, ""),
    "contacts.mu_hair": (0.0, 1e3, ""),
    "contacts.samples_per_element": (0, 1000, "points"),
    "contacts.layer_max_gap": (0.0, 1.0, "m"),
    "contacts.layer_tolerance": (0.0, 1.0, "m"),
    "contacts.layer_min_length": (0.0, 10.0, "m"),
    "contacts.hair_max_distance": (0.0, 1.0, "m"),
    "solver.gamma": (0.0, 1e30, "N^-2 m^-2"),
    "solver.gamma_relative": (0.0, 1.0, ""),
    "solver.tolerance": (0.0, 1.0, ""),
    "solver.max_sweeps": (0, 10**9, "sweeps"),
    "solver.rest_tolerance": (0.0, 1e6, "1/m"),
    "solver.max_iterations": (0, 10**6, "steps"),
    "solver.check_every": (0, 10**6, "sweeps"),
    "solver.max_seconds": (0.0, 1e9, "s"),
    "solver.friction_reserve": (0.0, 1.0, ""),
    "solver.stiffen_margin": (1.0, 1e6, ""),
    "dynamics.time_step": (1e-7, 10.0, "s"),
    "dynamics.damping": (0.0, 1e3, "s"),
    "dynamics.air_damping": (0.0, 1e6, "1/s"),
    "dynamics.body_thickness": (0.0, 1.0, "m"),
    "dynamics.hair_thickness": (0.0, 1.0, "m"),
    "dynamics.push_speed": (0.0, 1e3, "m/s"),
    "dynamics.tolerance": (0.0, 1.0, ""),
    "dynamics.max_sweeps": (0, 10**6, "sweeps"),
    "dynamics.stall_rounds": (0, 10**6, "rounds"),
    "dynamics.quadrature": (0, 8, "points"),
    "dynamics.inertia_radius": (0.0, 1.0, "m"),
    "dynamics.max_turn": (0.0, 3.2, "rad"),
    "dynamics.max_substeps": (0, 12, "halvings"),
    "dynamics.sleep_speed": (0.0, 1.0, "m/s"),
}

#: Settings whose 0 means something of its own, outside their range.
ZERO_MEANS = {
    "import.scale": "0: from units",
    "body.scale": "0: from units",
    "fit.elements": "0: adaptive",
    "fit.max_elements": "0: as many as the tolerance needs",
    "material.gravity": "0: no gravity",
    "material.shear_modulus": "0: from E and poisson_ratio",
    "contacts.max_hair_per_element": "0: no limit",
}


def range_error(where: str, value) -> str | None:
    """The sentence refusing ``value`` for the setting ``where`` (``section.key``), out of
    :data:`SETTING_RANGE` or not finite; None where it is within range or the setting has no range."""
    if where not in SETTING_RANGE or (value == 0 and where in ZERO_MEANS):
        return None
    lo, hi, unit = SETTING_RANGE[where]
    if (isinstance(value, int) or math.isfinite(value)) and lo <= value <= hi:
        return None
    zero = f" (or {ZERO_MEANS[where]})" if where in ZERO_MEANS else ""
    # a quantity that cannot be zero or negative says so first: "> 0" is the rule a user remembers
    positive = "> 0, " if lo > 0 and isinstance(value, (int, float)) and value <= 0 else ""
    return (f"{where} is {value!r}; it must be {positive}a number from {lo:g} to {hi:g}{' ' + unit if unit else ''}"
            f"{zero}")


def _coerce(value, typ, where: str, source: str):
    if typ in (int, float) and isinstance(value, bool):
        raise InputError(f"{source}: setting {where} expects a number, got {value!r}")
    if typ is float and isinstance(value, str) and SETTING_RANGE.get(where, (0, 0, ""))[2] == "m":
        match = _LENGTH.fullmatch(value)
        if match is not None and match.group(2) is not None:  # a length with its unit; a bare number is metres
            number, unit = match.groups()
            if unit not in LENGTH_UNITS:
                raise InputError(f"{source}: setting {where}: unknown unit {unit!r} in {value!r}; use one of "
                                 f"{', '.join(u for u in LENGTH_UNITS if u != 'µm')}")
            return float(number) * LENGTH_UNITS[unit]
    try:
        if typ is bool:
            if isinstance(value, str):
                if value.lower() in ("1", "true", "yes", "on"):
                    return True
                if value.lower() in ("0", "false", "no", "off"):
                    return False
                raise ValueError(value)
            return bool(value)
        if typ is int:
            if isinstance(value, float) and not value.is_integer():
                raise ValueError(value)
            return int(value)
        if typ is float:
            return float(value)
        if typ is str:
            return str(value)
    except (TypeError, ValueError):
        article = "an" if typ.__name__[0] in "aeiou" else "a"
        raise InputError(f"{source}: setting {where} expects {article} {typ.__name__}, got {value!r}") from None
    raise InputError(f"{source}: setting {where} has an unsupported type")


def apply(settings: Settings, overrides: dict, source: str = "overrides") -> Settings:
    """Return ``settings`` with a nested ``{section: {key: value}}`` mapping applied.

    Raises
    ------
    InputError
        For an unknown section or key (named), or a value of the wrong type.
    """
    changes = {}
    for section, values in overrides.items():
        if section not in _SECTIONS:
            raise InputError(f"{source}: unknown settings section [{section}]; known: {', '.join(_SECTIONS)}")
        if not isinstance(values, dict):
            raise InputError(f"{source}: [{section}] must be a table of key = value")
        attr = _SECTIONS[section]
        current = getattr(settings, attr)
        hints = typing.get_type_hints(type(current))
        known = {f.name for f in dataclasses.fields(current)}
        updates = {}
        for key, value in values.items():
            if key not in known:
                raise InputError(
                    f"{source}: unknown setting {section}.{key}; known in [{section}]: {', '.join(sorted(known))}"
                )
            updates[key] = _coerce(value, hints[key], f"{section}.{key}", source)
            if hints[key] in (int, float):
                problem = range_error(f"{section}.{key}", updates[key])
                if problem is not None:
                    raise InputError(f"{source}: setting {problem}")
        changes[attr] = dataclasses.replace(current, **updates)
    return dataclasses.replace(settings, **changes)


def load_toml(path) -> dict:
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise InputError("no such settings file", path) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"is not valid TOML ({exc})", path) from None


def parse_set(items) -> dict:
    """Turn ``["fit.tolerance=1e-4", ...]`` into ``{"fit": {"tolerance": "1e-4"}}``."""
    out: dict = {}
    for item in items:
        if "=" not in item or "." not in item.split("=", 1)[0]:
            raise InputError(f"--set expects section.key=value, got {item!r}")
        key, value = item.split("=", 1)
        section, name = key.strip().split(".", 1)
        out.setdefault(section, {})[name] = value.strip()
    return out


def resolve(quality: str = "default", config_file=None, sets=(), extra: dict | None = None) -> Settings:
    """Settings from defaults, a quality preset, a TOML file, ``--set`` items and CLI options.

    ``extra`` holds values given as dedicated command-line options
    (``--units``, ``--tolerance`` ...); they win over everything else.
    """
    if quality not in QUALITIES:
        raise InputError(f"unknown quality {quality!r}; choose one of {', '.join(QUALITIES)}")
    settings = Settings()
    preset = CONFIG_DIR / "quality" / f"{quality}.toml"
    if preset.exists():
        settings = apply(settings, load_toml(preset), str(preset))
    if config_file is not None:
        settings = apply(settings, load_toml(config_file), str(config_file))
    if sets:
        settings = apply(settings, parse_set(sets), "--set")
    if extra:
        settings = apply(settings, {k: v for k, v in extra.items() if v}, "command line")
    return settings


@dataclass(frozen=True)
class Sources:
    """Where a command's settings come from, each over the one before: the defaults, the quality preset, a
    TOML file, ``--set`` items, then the command's own options (``--mu``, ``--body-units`` ...).

    The library takes these rather than resolved :class:`Settings` where it must know what the user gave
    explicitly: a simulation keeps the contacts its model declared unless the user changes them
    (:func:`simulation_settings`)."""

    quality: str = "default"
    """The preset, ``configs/quality/<name>.toml``: draft, default or final; default is the balance of speed
    and accuracy the defaults above are chosen for."""
    config_file: str | Path | None = None
    """A TOML settings file (``--config``), one table per section; None: none."""
    sets: tuple[str, ...] = ()
    """``section.key=value`` items (``--set``), applied after the file; none by default."""
    options: dict = field(default_factory=dict)
    """``{section: {key: value}}``: the values of the command's own options, which win over everything
    else and are said to come from the command line; none by default."""

    def settings(self) -> Settings:
        """The settings in effect (:func:`resolve`, then :attr:`options`)."""
        settings = resolve(self.quality, self.config_file, self.sets)
        return apply(settings, self.options, "command line") if self.options else settings

    def given(self, section: str) -> dict:
        """The values of ``section`` the user gave: the TOML file's, then the ``--set`` items', then the
        options' (the preset's are not the user's)."""
        values = {}
        if self.config_file is not None:
            values.update(load_toml(self.config_file).get(section, {}))
        values.update(parse_set(self.sets).get(section, {}))
        values.update(self.options.get(section, {}))
        return values


def simulation_settings(sources: Sources, stored_contacts: dict, where: str) -> Settings:
    """The settings of a simulation of an inverted model.

    The contacts are the ones the model declared (``stored_contacts``: the ``[contacts]`` table its
    ``/contacts`` group records, read as a settings source named ``where``), so that the first step meets
    the inverted contacts again; contact settings the user gave (:meth:`Sources.given`) still change
    them, the preset's do not. Every other section is ``sources``'s.

    Raises
    ------
    InputError
        For an unknown section or key, or a value of the wrong type, named with its source.
    """
    settings = sources.settings()
    contacts = apply(Settings(), {"contacts": stored_contacts}, where).contacts
    given = sources.given("contacts")
    if given:
        contacts = apply(dataclasses.replace(settings, contacts=contacts), {"contacts": given}, "settings").contacts
    return dataclasses.replace(settings, contacts=contacts)
