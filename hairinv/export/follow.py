"""The render groom of a simulation of guides, for ``hairinv export --follow`` / ``--render STYLE``.

:class:`FollowSource` is a stage file seen as its render groom: every strand of the hairstyle the guides
were picked from (or of the file ``--render`` names), carried frame by frame by the simulated guides
(:mod:`hairinv.follow`). Its ``input`` shape is the render groom as read, ``frame:N`` and ``rest`` the render
strands in the guides' frame N and rest shape; the writers take it as they take any stage file.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..follow import FAR_FROM_GUIDES, SAME_ROOT, Following, render_groom
from .source import ExportSource, Strands

__all__ = ["FollowSource", "follow_source"]


def follow_source(path, render=None, lines: list[str] | None = None) -> ExportSource:
    """The stage file ``path`` as its render groom (:class:`FollowSource`), or as itself when the render groom
    holds no strand that was not simulated (every strand a guide: nothing changes); ``lines`` gets what was
    done.

    Raises
    ------
    InputError
        The file has no simulation, or a trimmed one; its render groom cannot be found or read, or grows
        elsewhere than its guides; one sentence naming the file.
    """
    lines = [] if lines is None else lines
    plain = ExportSource(path)
    if plain.frames is None:
        raise InputError("has no /frames group, so it has no simulated guides for the render groom to follow; "
                         "run `hairinv simulate` on it first", plain.path)
    if plain.frames_trimmed:
        raise InputError("is a trimmed simulation: its guides were cut, and the render groom does not follow cut "
                         "guides", plain.path)
    groom, groom_path = render_groom(plain.curves, plain.path, render)
    guides = plain.helices
    from scipy.spatial import cKDTree

    nearest, which = cKDTree(guides.root).query(groom.points[groom.offsets[:-1]])
    is_guide = nearest <= SAME_ROOT
    if groom.n_strands == plain.n_strands and is_guide.all() and len(np.unique(which)) == plain.n_strands:
        lines.append(f"render groom {groom_path}: its {groom.n_strands} strands are the simulated ones; the frames "
                     "are written as they are")
        return plain
    if guides.n_strands > 1:
        spacing = float(np.median(cKDTree(guides.root).query(guides.root, 2)[0][:, 1]))
        median = float(np.median(nearest))
        if median > FAR_FROM_GUIDES * spacing:
            raise InputError(f"its roots lie {1e3 * median:.3g} mm from the nearest guide's (median), "
                             f"{median / spacing:.3g} times the guides' own spacing ({1e3 * spacing:.3g} mm): it is "
                             "not a groom of these guides, or it is in other units or axes", groom_path)
    return FollowSource(plain, groom, groom_path, is_guide, lines)


class FollowSource(ExportSource):
    """A simulation's render groom (module docstring), built by :func:`follow_source`."""

    def __init__(self, plain: ExportSource, groom, groom_path, is_guide: np.ndarray, lines: list[str]):
        self.__dict__.update(plain.__dict__)
        self.points = np.ascontiguousarray(groom.points, dtype=np.float64)
        self.offsets = np.ascontiguousarray(groom.offsets, dtype=np.int64)
        self.n_strands = groom.n_strands
        self.render_path = groom_path
        self.is_guide = is_guide
        self.following = Following(self.points, self.offsets, self.helices, self.frames)
        self.follow = self.following.follow
        lines.append(f"render groom {groom_path}: {groom.n_strands} strands ({int(is_guide.sum())} of them simulated "
                     f"guides), each following its {self.follow.guide.shape[1]} nearest of the "
                     f"{self.helices.n_strands} guides")

    def input_files(self):
        return [*super().input_files(), self.render_path]

    def input(self) -> Strands:
        return Strands(self.points, self.offsets, "render groom, input shape")

    def rest(self) -> Strands:
        h = self.helices
        return Strands(self.following.pose(h.root, h.frame0, self.rest_omega), self.offsets,
                       "render groom, rest shape (carried by the guides' rest shape)")

    def frame(self, k: int) -> Strands:
        label = f"render groom, frame {k} (t = {self.times[k]:g} s), following the {self.helices.n_strands} guides"
        return Strands(self.following.frame(k), self.offsets, label)

    # the guides' quantities are not the render strands'
    def strand_values(self):
        return {}

    def vertex_values(self):
        return {}

    def stable(self):
        return None

    def guide_flags(self) -> np.ndarray:
        return self.is_guide.astype(np.int32)
