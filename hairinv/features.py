"""What a run models, and what it skips and why (docs/scenes.md, "What a scene models").

A scene says what exists: gravity, a body, hair-hair contact, friction, a body motion, a trim,
stiffening. What is absent costs nothing: no hair-hair detection when it is off, no body queries
without a body, frictionless contacts solved for their normal force alone, no stability check when
asked not to. :func:`detect_features`, :func:`invert_features` and :func:`simulate_features` say which
of these a stage models from the settings, the scene and the inputs; the stages print
:meth:`Features.line` and store :meth:`Features.attr` as the ``features`` attribute of the group they
write (docs/stage-files.md).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from .config import ContactSettings, SolverSettings

__all__ = ["FEATURES", "Features", "detect_features", "invert_features", "simulate_features"]

#: every feature a scene may declare, by its stable key, with the words the report uses
FEATURES = {
    "gravity": "gravity",
    "body_contact": "hair-body contact",
    "hair_hair_contact": "hair-hair contact",
    "friction": "friction",
    "body_motion": "body motion",
    "trim": "trim",
    "stability_check": "stability check",
    "stiffening": "stiffening",
}


@dataclass
class Features:
    """The features a stage modelled (keys of :data:`FEATURES`, with a detail each) and those it skipped,
    each with why (declared off in the settings or the scene, or an input that is absent)."""

    modelled: dict[str, str] = field(default_factory=dict)
    """key -> detail (may be empty), in the order of :data:`FEATURES`"""
    skipped: dict[str, str] = field(default_factory=dict)
    """key -> why"""

    def model(self, key: str, detail: str = "") -> None:
        self.modelled[key] = detail

    def skip(self, key: str, why: str) -> None:
        self.skipped[key] = why

    def line(self) -> str:
        """``modelled: gravity (9.81 m/s^2), hair-body contact; skipped: hair-hair contact (declared off:
        contacts.hair_hair = false)``."""
        order = list(FEATURES)
        done = [FEATURES[k] + (f" ({d})" if d else "") for k, d in sorted(self.modelled.items(),
                                                                          key=lambda kv: order.index(kv[0]))]
        left = [f"{FEATURES[k]} ({why})" for k, why in sorted(self.skipped.items(), key=lambda kv: order.index(kv[0]))]
        return f"modelled: {', '.join(done) or 'nothing'}; skipped: {', '.join(left) or 'nothing'}"

    def attr(self) -> str:
        """The ``features`` attribute: JSON ``{"modelled": [key, ...], "skipped": {key: why}}``."""
        return json.dumps({"modelled": list(self.modelled), "skipped": dict(self.skipped)})

    @classmethod
    def from_attr(cls, text) -> "Features | None":
        """The features a stage file's ``features`` attribute records (details are not stored), None if it
        records none or not in :meth:`attr`'s form."""
        try:
            data = json.loads(text)
            modelled = {str(k): "" for k in data["modelled"] if k in FEATURES}
            skipped = {str(k): str(why) for k, why in data["skipped"].items() if k in FEATURES}
        except (TypeError, ValueError, KeyError, AttributeError):
            return None
        return cls(modelled, skipped)


def _contact_features(out: Features, settings: ContactSettings, body: bool, body_why: str = "") -> None:
    """Hair-body and hair-hair contact, as detection declares them."""
    if not settings.body:
        out.skip("body_contact", "declared off: contacts.body = false")
    elif not body:
        out.skip("body_contact", body_why or "no body mesh given")
    else:
        out.model("body_contact")
    if settings.hair_hair:
        out.model("hair_hair_contact")
    else:
        out.skip("hair_hair_contact", "declared off: contacts.hair_hair = false")


def _friction(out: Features, settings: ContactSettings) -> None:
    """Friction where some modelled contact kind has mu > 0; frictionless contacts are solved for their
    normal force alone."""
    kinds = [(name, mu) for key, name, mu in (("body_contact", "body", settings.mu_body),
                                              ("hair_hair_contact", "hair", settings.mu_hair))
             if key in out.modelled]
    if not kinds:
        out.skip("friction", "no contacts")
        return
    rough = [f"mu_{name} {mu:g}" for name, mu in kinds if mu > 0]
    smooth = [f"contacts.mu_{name} = 0" for name, mu in kinds if not mu > 0]
    if not rough:
        out.skip("friction", f"{' and '.join(smooth)}: frictionless, normal forces only")
    else:
        out.model("friction", ", ".join(rough) + (f"; frictionless where {' and '.join(smooth)}" if smooth else ""))


def _gravity(out: Features, gravity) -> None:
    g = float(np.linalg.norm(np.asarray(gravity, dtype=np.float64)))
    if g > 0.0:
        out.model("gravity", f"{g:g} m/s^2")
    else:
        out.skip("gravity", "material.gravity = 0")


def detect_features(settings: ContactSettings, body: bool) -> Features:
    """What ``detect`` declares: hair-body contact (``settings.body`` and a body mesh) and hair-hair
    contact (``settings.hair_hair``)."""
    out = Features()
    _contact_features(out, settings, body)
    return out


def invert_features(contacts: ContactSettings, solver: SolverSettings, gravity, body: bool) -> Features:
    """What ``invert`` models: gravity, the contacts declared (or reused), friction, the stability check
    and stiffening. A contact kind declared but never found is still modelled (its detection ran)."""
    out = Features()
    _gravity(out, gravity)
    if solver.target == "gravity-only":
        why = "the gravity-only target declares no contacts"
        out.skip("body_contact", why)
        out.skip("hair_hair_contact", why)
    else:
        _contact_features(out, contacts, body)
    _friction(out, contacts)
    if not solver.check_stability:
        out.skip("stability_check", "declared off: solver.check_stability = false")
    else:
        out.model("stability_check", f"under the {solver.stable_under} held fixed"
                  if solver.stable_under == "forces" else "with the loaded contact points held")
    if solver.target == "gravity-only":
        out.skip("stiffening", "the gravity-only inversion keeps the material")
    elif solver.stabilize != "stiffen":
        out.skip("stiffening", "declared off: solver.stabilize = off")
    else:
        out.model("stiffening", "where a strand is unstable")
    return out


def simulate_features(contacts: ContactSettings, gravity, body: bool, scene, init: str,
                      stiffened: bool, animated: str | None = None) -> Features:
    """What ``simulate`` (and ``verify``) models: gravity (the model's), the contacts (as the model
    declared them, unless the scene removes the body), friction, the scene's body motion and trim, and the
    model's stiffening (``stiffened``: its file holds factors above 1 and the run starts from them)."""
    out = Features()
    _gravity(out, gravity)
    if scene.body == "removed":
        _contact_features(out, contacts, False, "the scene removes the body")
    else:
        _contact_features(out, contacts, body)
    _friction(out, contacts)
    if animated:
        out.model("body_motion", f"animated ({animated}): each root follows the triangle it sits on")
    elif scene.moving:
        out.model("body_motion", f"{len(scene.keyframes)} keyframes")
    elif scene.body == "removed":
        out.skip("body_motion", "the scene removes the body")
    else:
        out.skip("body_motion", "the scene's body is fixed: contacts are detected again only where strands move")
    if scene.trim is not None:
        out.model("trim", f"at {scene.trim.length:g} m" if scene.trim.length else f"at {scene.trim.fraction:g} "
                  "of each strand's length")
    else:
        out.skip("trim", "the scene has no [trim]")
    if init != "inverted":
        out.skip("stiffening", f"--init {init} keeps the material")
    elif stiffened:
        out.model("stiffening", "the model's factors")
    else:
        out.skip("stiffening", "the model has no stiffened strand")
    return out
