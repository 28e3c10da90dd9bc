"""Simulate an inverted model, and check that it stays still: ``hairinv simulate`` and ``verify`` as calls.

:func:`load` reads a model's stage file, settles its settings (the contacts as the model declared them,
:func:`hairinv.config.simulation_settings`), its scene and its body, and refuses a model whose rest
shape does not hold its helices with its forces (:func:`check_equilibrium`). The :class:`Run` it
returns simulates the scene (:meth:`Run.simulate`), judges a still check (:meth:`Run.check_still`) and
writes the model's groups with ``/frames`` (:meth:`Run.write`). :func:`simulate` and :func:`verify` do
all of it in one call, as the commands do, for code that drives them without a subprocess.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import formats, stages
from .config import Settings, Sources, simulation_settings
from .errors import InputError, Interrupted, RunError
from .features import Features, simulate_features
from .model import Contacts, Helices, stiffening_from_group

if TYPE_CHECKING:  # the dynamics, for annotations only: imported once a model has been read and checked
    from .dynamics.run import Frames
    from .dynamics.scene import Scene
    from .dynamics.verify import Verdict

__all__ = ["Run", "load", "check_equilibrium", "simulate_record", "verify_record", "recorded_verdict", "simulate",
           "verify"]

#: m, the largest distance a strand point may move in a still check, as ``hairinv verify`` takes it by
#: default (``--tolerance 0.1mm``): a hair's diameter (material.radius is 50 um).
STILL_TOLERANCE = 1e-4
#: s, the longest pre-roll
MAX_PREROLL = 60.0
#: 1/s, the highest frame rate an animated body may be given
MAX_BODY_FPS = 10000.0


@dataclass
class Run:
    """A simulation of an inverted model: what :func:`load` read and settled, and once simulated its frames.

    Attributes
    ----------
    model_path : Path, the model's stage file
    stage : StageFile, its groups (``/curves``, ``/helices``, ``/model`` and ``/contacts`` if any)
    helices : Helices
    contacts : Contacts or None, the contacts the model was inverted with
    mesh : trimesh.Trimesh or None, the body in the groom's frame, m
    body : Path or None, the body file in use
    to_groom : (4, 4) float64 or None, the transform of the body file into the groom's frame
    scene : Scene
    settings : Settings
    init : str, the rest shape the strands start from (hairinv.dynamics.run.INITS)
    seconds : float, s, the simulated time
    fps : float, 1/s, frames per second
    record : dict or None, the command record written with the frames (hairinv.staleness)
    frames : Frames or None, once simulated
    """

    model_path: Path
    stage: stages.StageFile
    helices: Helices
    contacts: Contacts | None
    mesh: object
    body: Path | None
    to_groom: np.ndarray | None
    scene: Scene
    settings: Settings
    init: str
    seconds: float
    fps: float
    record: dict | None = None
    frames: Frames | None = None
    shot: object = None
    """:class:`hairinv.dynamics.skin.Shot` when the body file is animated, else None"""
    say: object = None
    body_fps: float | None = None
    """1/s, the animated body's frame rate as given (``--body-fps``), or None: its file's"""
    pose: dict = field(default_factory=dict)
    """the pose of the body the groom was made on (:func:`hairinv.groom.pose_setting`): {} for its rest pose"""

    @property
    def steps(self) -> int:
        """The time steps the run takes (each frame's, times the frames after the first, and the pre-roll's)."""
        per_frame = max(1, round(1.0 / (self.fps * self.settings.dynamics.time_step)))
        h = 1.0 / (self.fps * per_frame)
        preroll = int(np.ceil(self.shot.preroll / h - 1e-9)) if self.shot is not None else 0
        return per_frame * max(0, round(self.seconds * self.fps)) + preroll

    def features(self) -> Features:
        """What the simulation models and skips, and why."""
        model = self.stage[stages.MODEL]
        factor = stiffening_from_group(model, self.helices.n_strands)
        return simulate_features(self.settings.contacts, np.asarray(model.attrs["gravity"], dtype=np.float64),
                                 self.mesh is not None, self.scene, self.init,
                                 factor is not None and bool(np.any(factor > 1.0)),
                                 None if self.shot is None else f"{self.shot.body.n_frames} frames")

    def simulate(self, on_frame=None, on_step=None) -> Frames:
        """Run the scene (:func:`hairinv.dynamics.run.run_scene`); the frames, also kept in :attr:`frames`.

        ``on_frame(log)`` after every frame (returning True stops the run there), ``on_step()`` after
        every step.

        Raises
        ------
        RunError
            The simulation diverged: no output is written.
        Interrupted
            Ctrl-C once a frame was done: the frames done are in :attr:`frames` (``interrupted`` set), and
            :meth:`write` writes them.
        """
        from .dynamics.run import run_scene

        try:
            self.frames = run_scene(self.helices, self.stage[stages.MODEL], self.contacts, self.mesh, self.scene,
                                    self.settings, init=self.init, seconds=self.seconds, fps=self.fps,
                                    on_frame=on_frame, on_step=on_step, body_path=self.body, shot=self.shot,
                                    say=self.say)
        except Interrupted as stop:
            self.frames = stop.result
            raise
        except FloatingPointError as exc:
            raise RunError(f"the simulation diverged {exc}; no output was written; try a smaller "
                           "dynamics.time_step") from None
        return self.frames

    def check_still(self, tolerance: float = STILL_TOLERANCE, full: bool = False, on_step=None) -> Verdict:
        """Simulate and judge whether no strand point moves more than ``tolerance`` (m): the run stops at
        the first frame past it, unless ``full``. No strand sleeps (``dynamics.sleep_speed`` 0): a strand
        at rest for a few steps could still be drifting away from round-off, which is what is checked."""
        from .dynamics.verify import judge

        if self.settings.dynamics.sleep_speed:
            self.settings = dataclasses.replace(
                self.settings, dynamics=dataclasses.replace(self.settings.dynamics, sleep_speed=0.0))
        stop = None if full else (lambda log: log.displacement > tolerance)
        return judge(self.simulate(on_frame=stop, on_step=on_step), tolerance, self.seconds)

    def groups(self) -> list[stages.Group]:
        """The groups of the run's stage file: the model's, then ``/frames`` with the settings and inputs
        that made it."""
        groups = [self.stage[name] for name in (stages.CURVES, stages.HELICES, stages.CONTACTS, stages.MODEL)
                  if name in self.stage]
        inputs = [stages.file_record(self.model_path)]
        if self.body is not None:
            inputs.append({**stages.file_record(self.body), "to_groom": np.asarray(self.to_groom).tolist()})
            if self.pose:
                from .groom import pose_record

                inputs[-1]["pose"] = pose_record(self.pose)
        config = {"dynamics": dataclasses.asdict(self.settings.dynamics),
                  "contacts": dataclasses.asdict(self.settings.contacts), "scene": self.scene.name, "init": self.init}
        frames = self.frames.group(config, inputs)
        frames.attrs["features"] = self.features().attr()
        return groups + [frames]

    def write(self, output) -> None:
        """The model's groups and the run's ``/frames``, written atomically to ``output``."""
        stages.write_stage(output, self.groups(), "simulate", self.record)


def load(model, body=None, sources: Sources | None = None, scene: str = "still", init: str = "inverted",
         seconds: float | None = None, fps: float | None = None, output=None, say=None,
         preroll: float | None = None, body_fps: float | None = None, animate: bool = True) -> Run:
    """Read an inverted model for a simulation of ``scene``.

    Parameters
    ----------
    model : path of a stage file written by ``hairinv invert``
    body : path of the body mesh, or None for the one the model was inverted against, where it still is
    sources : Sources, the settings (default: the defaults); the contacts are the model's unless the user
        changes them (:func:`hairinv.config.simulation_settings`)
    scene : a scene preset's name or a scene file (hairinv.dynamics.scene)
    init : inverted, naive or gravity-only: the rest shape the strands start from
    seconds, fps : s and 1/s, or None for the scene's
    output : path the frames will be written to, checked here to be none of the inputs; or None
    say : callable(str), optional, gets the lines about the body
    preroll : s, for an animated body: the time taken from the groom's pose to the shot's first frame; None:
        :data:`hairinv.dynamics.skin.PREROLL` where the first frame is another pose, else 0
    body_fps : 1/s, an animated body's frame rate: a mesh sequence's (24 assumed otherwise), or overriding the
        rate its file states or its keys suggest; None: the file's
    animate : False: an animated body is held still in the groom's pose (its rest pose), as ``verify`` checks the
        still promise on it; True: its animation is played

    Raises
    ------
    InputError
        A missing file, a file that holds no inverted model, a bad setting or scene, an output that is an
        input; with ``init = "inverted"``, a model whose rest shape does not hold its helices with its
        forces (eq. 4), changed since it was inverted.
    """
    say = say or (lambda line: None)
    model = Path(model)
    body = None if body is None else Path(body)
    if not model.exists():
        raise InputError("no such file", model)
    if body is not None and not (body.exists() or "#" in body.name):
        raise InputError("no such file", body)
    if not stages.is_stage_file(model):
        raise InputError("is not a hairinv stage file: run `hairinv invert` on the hairstyle first", model)
    stage = stages.read_stage(model)  # checked whole before the numerical code is even imported
    for name in (stages.CURVES, stages.HELICES, stages.MODEL):
        if name not in stage:
            raise InputError(f"has no /{name} group: run `hairinv invert` on it first", model)

    from .dynamics.scene import Scene, check_run_length
    from .dynamics.simulate import validate_settings
    from .groom import (load_body, pose_words, posed_animation, posed_mesh, run_body_record, simulation_body,
                        simulation_pose)

    loaded = Scene.load(scene)
    animated = None
    if body_fps is not None and not (np.isfinite(body_fps) and 0.0 < body_fps <= MAX_BODY_FPS):
        raise InputError(f"--body-fps is {body_fps!r}; it must be a frame rate above 0 and at most {MAX_BODY_FPS:g}")
    if body is not None and formats.is_animated_body(body):
        if animate:
            animated = formats.read_animated_body(body, fps=body_fps)
            for note in animated.notes:
                say(f"body: {note}")
        else:
            say(f"body: {Path(body).name} is animated: held still in the groom's pose (its rest pose); "
                "`hairinv simulate` plays its animation")
    if animated is not None:
        seconds = animated.end - animated.start if seconds is None else seconds
        fps = (animated.fps or loaded.fps) if fps is None else fps
    if preroll is not None and not (np.isfinite(preroll) and 0.0 <= preroll <= MAX_PREROLL):
        raise InputError(f"--preroll is {preroll!r}; it must be a number of seconds from 0 to {MAX_PREROLL:g}")
    seconds = loaded.seconds if seconds is None else seconds
    fps = loaded.fps if fps is None else fps
    check_run_length(seconds, fps, None, "--seconds", "--fps")
    if output is not None:
        stages.check_output_path(output, inputs=[model, body])
    stored = stage[stages.CONTACTS].config.get("contacts", {}) if stages.CONTACTS in stage else {}
    settings = simulation_settings(sources or Sources(), stored, str(model))
    validate_settings(settings.dynamics)
    curves = stage[stages.CURVES]
    helices = Helices.from_group(stage[stages.HELICES])
    contacts = Contacts.from_group(stage[stages.CONTACTS]) if stages.CONTACTS in stage else None
    if init == "inverted":
        check_equilibrium(model, helices, contacts, stage[stages.MODEL])
    found = run_body_record(body, stage, model)  # the file's SHA-256 taken once
    body, to_groom, notes, read = simulation_body(settings.body, body, stage, model, curves, found)
    mesh = None
    shot = None
    pose = simulation_pose(settings.body, body, found[1], model)
    if body is not None:
        for line in notes:
            say(line)
        mesh = load_body(body, to_groom, posed_mesh(body, pose, read, animated))
        say(f"body: {body}")
        if pose:
            say(f"body: the groom's pose is {pose_words(pose)}")
        if animate and animated is None and formats.is_animated_body(body):  # the recorded body
            animated = formats.read_animated_body(body, fps=body_fps)
        if animated is not None:
            from .dynamics.skin import PREROLL, Shot

            moved = posed_animation(animated, pose, body).transformed(to_groom)
            if preroll is None:
                preroll = PREROLL if Shot.needs_preroll(moved) else 0.0
            shot = Shot(moved, float(preroll))
    elif loaded.body != "removed":
        say("no body: only hair-hair contacts")
    if body_fps is not None and animated is None:
        raise InputError(f"--body-fps is the frame rate of an animated body, and the body "
                         f"{'is not given' if body is None else 'is a still mesh'}", body)
    return Run(model, stage, helices, contacts, mesh, body, to_groom, loaded, settings, init, float(seconds),
               float(fps), shot=shot, say=say, body_fps=body_fps, pose=pose)


def check_equilibrium(path, helices: Helices, contacts: Contacts | None, model: stages.Group) -> None:
    """Refuse a model whose rest shape does not hold ``helices`` with its forces
    (:func:`hairinv.inverse.problem.model_mismatch`): an :class:`InputError` of ``path``."""
    from .inverse.problem import model_mismatch

    miss, element = model_mismatch(helices, contacts, model)
    if element >= 0:
        strand = int(np.searchsorted(helices.offsets, element, side="right") - 1)
        raise InputError(f"/model does not hold /helices in equilibrium with its forces: its rest shape is "
                         f"{miss:.3g} 1/m from the one its forces give at element {element} (strand {strand}), so "
                         "its helices, contacts, forces or material were changed after it was inverted (or it "
                         "was written by another version); invert it again", path)


def simulate_record(run: Run, scene: str) -> dict:
    """The command record of ``hairinv simulate`` of ``run`` (``scene`` as given: a scene file's contents
    count among the inputs)."""
    from .staleness import command_record

    scene_file = Path(scene) if Path(scene).suffix == ".toml" else None
    return command_record("simulate", [run.model_path, run.body, scene_file], run.settings,
                          ("body", "contacts", "dynamics"),
                          {"scene": scene, "init": run.init, "seconds": run.seconds, "fps": run.fps,
                           **({"preroll": run.shot.preroll} if run.shot is not None else {}),
                           **({"body_fps": run.body_fps} if run.body_fps is not None else {})})


def verify_record(run: Run, tolerance: float, full: bool) -> dict:
    """The command record of ``hairinv verify`` of ``run``, checking to ``tolerance`` (m)."""
    from .staleness import command_record

    return command_record("verify", [run.model_path, run.body], run.settings, ("body", "contacts", "dynamics"),
                          {"init": run.init, "seconds": run.seconds, "fps": run.fps, "tolerance_m": tolerance,
                           "full": full})


def recorded_verdict(path, tolerance: float, seconds: float) -> Verdict:
    """The verdict of a still check from the ``/frames`` group ``verify -o`` wrote (each frame's per-strand
    displacement)."""
    from .dynamics.verify import judge_displacements

    stage = stages.read_stage(path)
    if stages.FRAMES not in stage:
        raise InputError("holds no /frames group to read a verdict from; run verify without --if-stale", path)
    group = stage[stages.FRAMES]
    if "strand_displacement" not in group.datasets:
        raise InputError("holds no per-strand displacements (written by an older hairinv); run verify without "
                         "--if-stale", path)
    return judge_displacements(group.datasets["time"], group.datasets["strand_displacement"], tolerance, seconds,
                               bool(group.attrs.get("stopped", False)))


def simulate(model, body=None, sources: Sources | None = None, scene: str = "still", init: str = "inverted",
             seconds: float | None = None, fps: float | None = None, output=None, on_frame=None, on_step=None,
             say=None, preroll: float | None = None) -> Run:
    """``hairinv simulate``: :func:`load` the model, simulate ``scene``, and write the frames to ``output``
    (with the command's record) when it is given. The run, its frames in :attr:`Run.frames`. On Ctrl-C
    (:class:`~hairinv.errors.Interrupted`) the frames done are written to ``output``, marked interrupted,
    before the interrupt goes on."""
    run = load(model, body, sources, scene, init, seconds, fps, output, say, preroll)
    if output is not None:
        run.record = simulate_record(run, scene)
    try:
        run.simulate(on_frame=on_frame, on_step=on_step)
    except Interrupted:
        if output is not None:
            run.write(output)
        raise
    if output is not None:
        run.write(output)
    return run


def verify(model, body=None, sources: Sources | None = None, init: str = "inverted", seconds: float | None = None,
           fps: float | None = None, tolerance: float = STILL_TOLERANCE, full: bool = False, output=None,
           on_step=None, say=None) -> tuple[Verdict, Run]:
    """``hairinv verify``: the still scene from the model, judged to ``tolerance`` (m), stopped at the first
    frame past it unless ``full``; the frames written to ``output`` when it is given (on Ctrl-C, the frames
    done, marked interrupted, before the interrupt goes on).

    Returns
    -------
    (Verdict, Run)
    """
    run = load(model, body, sources, "still", init, seconds, fps, output, say)
    if output is not None:
        run.record = verify_record(run, tolerance, full)
    try:
        verdict = run.check_still(tolerance, full, on_step=on_step)
    except Interrupted:
        if output is not None:
            run.write(output)
        raise
    if output is not None:
        run.write(output)
    return verdict, run
