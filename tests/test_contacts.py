"""Contact detection against geometry known in closed form, a brute-force reference and real data.

Strands are built directly as super-helices (straight lines, circular arcs,
tight helices) so the expected contact arc lengths, points and normals are
known analytically; bodies are planes, boxes and icospheres from trimesh.
Runtime: about 4 s with a warm numba cache (the sintel fit and trimesh's closest points are most of it).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from conftest import SAMPLES, real_path
from hairinv import stages
from hairinv.config import ContactSettings, FitSettings, ImportSettings
from hairinv.contacts import BodyMesh, DetectReport, detect_contacts
from hairinv.contacts.hair import hair_pairs
from hairinv.errors import InputError
from hairinv.fit import fit_groom
from hairinv.groom import hair_unit_transform, load_body, load_groom
from hairinv.model import BODY, Contacts, Helices
from hairinv.rod.helix import frames_at, points_at

# Refined contact positions: golden-section / Gauss-Newton on float64 geometry of size ~0.1 m;
# the arc length at a quadratic minimum is resolved to about sqrt(eps) of the distance scale.
POSITION = 1e-7
# Distances and normals of exact geometry (planes, box faces, straight lines): round-off.
EXACT = 1e-12
# Frames: orthonormality and handedness to round-off.
FRAME = 1e-12
# An icosphere of 4 subdivisions (5120 faces) departs from its sphere by < 0.1 % of the radius, and its facet
# normals from the radial direction by < 3 degrees.
FACET_COS = np.cos(np.radians(3.0))

SETTINGS = ContactSettings()
# hair-hair geometry tests: no root clearance and no cap per element, so every element pair within reach counts
HAIR_ONLY = dataclasses.replace(SETTINGS, body=False, root_clearance=0.0, max_hair_per_element=0)
# the fixed-radius rules alone (the layer rule is tested on its own below)
BODY_ONLY = dataclasses.replace(SETTINGS, hair_hair=False, root_clearance=0.0, layer=False)


def frame_with_tangent(t, n2=None) -> np.ndarray:
    """Rows (t, n1, n2), right-handed; ``n2`` as given (made orthogonal) or any."""
    t = np.asarray(t, float) / np.linalg.norm(t)
    if n2 is None:
        a = np.eye(3)[np.argmin(np.abs(t))]
        n2 = a - a.dot(t) * t
    n2 = np.asarray(n2, float) - np.dot(n2, t) * t
    n2 /= np.linalg.norm(n2)
    n1 = np.cross(n2, t)
    return np.array([t, n1, n2])


def helices(strands) -> Helices:
    """``strands``: list of (root, frame0, omega (N, 3), length (N,))."""
    root = np.array([s[0] for s in strands], float)
    frame0 = np.array([s[1] for s in strands], float)
    omega = np.concatenate([np.asarray(s[2], float).reshape(-1, 3) for s in strands])
    length = np.concatenate([np.asarray(s[3], float).ravel() for s in strands])
    offsets = np.concatenate([[0], np.cumsum([len(np.ravel(s[3])) for s in strands])]).astype(np.int64)
    return Helices(root, frame0, offsets, length, omega, np.zeros((len(strands), 2)))


def straight(root, direction, length, elements):
    return (np.asarray(root, float), frame_with_tangent(direction), np.zeros((elements, 3)),
            np.full(elements, length / elements))


def plane(height=0.0, size=1.0) -> trimesh.Trimesh:
    """The open square y = height, |x|, |z| < size, normal +y (two triangles)."""
    v = np.array([[-size, height, -size], [size, height, -size], [size, height, size], [-size, height, size]])
    return trimesh.Trimesh(v, [[0, 2, 1], [0, 3, 2]], process=False)


def assert_frames(contacts: Contacts):
    f = contacts.frame
    np.testing.assert_allclose(np.einsum("cij,ckj->cik", f, f), np.broadcast_to(np.eye(3), f.shape), atol=FRAME)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=FRAME)


def points_on(h: Helices, strand: int, s) -> np.ndarray:
    """Centerline points of a strand at arc lengths ``s``, by the rod module (independently of detection)."""
    a, b = h.offsets[strand], h.offsets[strand + 1]
    s = np.atleast_1d(np.asarray(s, float))
    out = np.empty((len(s), 3))
    points_at(h.root[strand], h.frame0[strand], h.omega[a:b], h.length[a:b], s, out)
    return out


# --- hair-body ---------------------------------------------------------------------------------------------------

def arc_over_plane(h_low: float, radius=0.05, theta0=0.6, elements=3):
    """A circular arc in the x-y plane whose lowest point (0, h_low, 0) is at arc length radius * theta0."""
    center = np.array([0.0, radius + h_low, 0.0])
    root = center + radius * np.array([-np.sin(theta0), -np.cos(theta0), 0.0])
    t0 = np.array([np.cos(theta0), -np.sin(theta0), 0.0])
    # omega = (kappa, 0, 0) bends the tangent towards -n2: n2 points away from the centre
    F = frame_with_tangent(t0, n2=root - center)
    total = 2 * radius * theta0
    return (root, F, np.tile([1.0 / radius, 0.0, 0.0], (elements, 1)), np.full(elements, total / elements)), center


def test_arc_above_a_plane_touches_at_its_lowest_point():
    radius, theta0, h_low = 0.05, 0.6, 0.002
    strand, center = arc_over_plane(h_low, radius, theta0)
    h = helices([strand])
    contacts, report = detect_contacts(h, plane(), BODY_ONLY)
    # element 1 holds the lowest point; element 0 is closest at its end, the joint with element 1, which is not
    # element 0's to declare; element 2 is closest at its start (phi = 0.2 rad), 3 mm above the plane
    assert contacts.n_contacts == 2 and contacts.n_body == 2 and contacts.n_hair == 0
    np.testing.assert_array_equal(contacts.strand, [[0, BODY], [0, BODY]])
    s_low = radius * theta0
    s_start2 = 2 * radius * theta0 * 2 / 3
    np.testing.assert_allclose(contacts.s[:, 0], [s_low, s_start2], rtol=0, atol=POSITION)
    np.testing.assert_array_equal(contacts.s[:, 1], 0.0)
    phi = s_start2 / radius - theta0
    expected = [[0.0, h_low, 0.0], [radius * np.sin(phi), radius + h_low - radius * np.cos(phi), 0.0]]
    np.testing.assert_allclose(contacts.point, expected, rtol=0, atol=POSITION)
    np.testing.assert_allclose(contacts.frame[:, 0], [[0, 1, 0], [0, 1, 0]], rtol=0, atol=EXACT)
    np.testing.assert_array_equal(contacts.mu, SETTINGS.mu_body)
    assert_frames(contacts)
    assert report.points_inside_body == 0 and report.strands_touching_body == 1


@pytest.mark.parametrize("iterations", [4, 12])
def test_fewer_refinement_steps_place_the_contact_within_their_bracket(iterations):
    """The golden-section steps shrink the bracket between two samples by 0.618 each: the lowest point of
    the arc is found within that bracket, and its distance is off by its square over twice the radius."""
    radius, theta0, h_low = 0.05, 0.6, 0.002
    strand, _ = arc_over_plane(h_low, radius, theta0)
    contacts, _ = detect_contacts(helices([strand]), plane(), BODY_ONLY, refine_iterations=iterations)
    spacing = strand[3][1] / (SETTINGS.samples_per_element - 1)
    bracket = 2 * spacing * 0.6180339887498949 ** iterations
    s_low = radius * theta0
    assert abs(contacts.s[0, 0] - s_low) <= bracket
    assert h_low <= contacts.gap[0] <= h_low + bracket ** 2 / (2 * radius) + 1e-12
    finer, _ = detect_contacts(helices([strand]), plane(), BODY_ONLY)  # the default's 24 steps
    assert abs(finer.s[0, 0] - s_low) <= 2 * spacing * 0.6180339887498949 ** 24
    assert finer.s[0, 0] != contacts.s[0, 0]  # the steps asked for are the steps taken


def test_arc_beyond_the_body_distance_gives_nothing():
    strand, _ = arc_over_plane(SETTINGS.body_distance * 1.01)
    contacts, report = detect_contacts(helices([strand]), plane(), BODY_ONLY)
    assert contacts.n_contacts == 0 and report.n_body == 0


def test_strand_passing_a_box_edge_gets_the_edge_normal():
    """Closest to the edge x = y = 0.1 of a cube: the normal is the edge's bisector, not a face normal."""
    d = 0.001
    direction = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    closest = np.array([0.1, 0.1, 0.02]) + d * np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    strand = straight(closest - 0.03 * direction, direction, 0.06, 3)
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    contacts, _ = detect_contacts(helices([strand]), box, BODY_ONLY)
    assert contacts.n_contacts == 1
    assert contacts.s[0, 0] == pytest.approx(0.03, abs=POSITION)
    np.testing.assert_allclose(contacts.point[0], closest, rtol=0, atol=POSITION)
    # the normal turns by (error in s) / d along the strand
    np.testing.assert_allclose(contacts.frame[0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0.0], rtol=0, atol=POSITION / d)


def test_one_body_contact_per_element_and_none_within_the_root_clearance():
    """A straight strand 1 mm above a plane, all along: every element touches, once, beyond the clearance."""
    elements = 6
    strand = straight([-0.1, 0.001, 0.0], [1.0, 0.0, 0.0], 0.12, elements)
    settings = dataclasses.replace(SETTINGS, hair_hair=False, root_clearance=0.025)
    contacts, _ = detect_contacts(helices([strand]), plane(), settings)
    element = np.floor(contacts.s[:, 0] / 0.02 + 1e-9).astype(int)
    # element 0 (0-2 cm) lies within the 2.5 cm clearance; element 1 starts within it
    np.testing.assert_array_equal(element, [1, 2, 3, 4, 5])
    assert np.all(contacts.s[:, 0] >= settings.root_clearance)
    np.testing.assert_allclose(contacts.point[:, 1], 0.001, rtol=0, atol=EXACT)
    np.testing.assert_allclose(contacts.frame[:, 0], np.tile([0.0, 1.0, 0.0], (5, 1)), rtol=0, atol=EXACT)


def test_strand_half_inside_a_sphere_is_counted_and_pushed_outwards():
    """A chord 5 cm under the top of a sphere of 10 cm: the depth grows monotonically to the middle, so the
    elements before the middle are deepest at their ends (not theirs to declare) and the contacts are the
    middle (x = 0, start of element 4) and the start of element 5 (x = 5 cm)."""
    radius = 0.1
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    elements, n = 8, SETTINGS.samples_per_element
    strand = straight([-0.2, 0.05, 0.0], [1.0, 0.0, 0.0], 0.4, elements)
    h = helices([strand])
    contacts, report = detect_contacts(h, sphere, BODY_ONLY)
    # the samples an element owns: all but its last, which is the next element's first; the tip
    s = np.linspace(0.0, 0.4, elements * (n - 1) + 1)
    inside = sphere.contains(points_on(h, 0, s))  # ray test on the closed icosphere: independent of ours
    assert inside.sum() > 10
    assert report.points_inside_body == inside.sum()
    assert report.strands_inside_body == 1
    assert any("inside the body" in line for line in report.lines())
    # the deepest point of a chord of the faceted sphere is within a facet (~7 mm) of the sphere's
    np.testing.assert_allclose(contacts.s[:, 0], [0.2, 0.25], rtol=0, atol=1e-3)
    np.testing.assert_allclose(contacts.point, [[0.0, 0.05, 0.0], [0.05, 0.05, 0.0]], rtol=0, atol=1e-3)
    assert np.all(sphere.contains(contacts.point))
    # outward: the radial direction, up to the facets' tilt
    radial = contacts.point / np.linalg.norm(contacts.point, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", contacts.frame[:, 0], radial) > FACET_COS)
    assert report.deepest_inside == pytest.approx(0.05, rel=2e-3)
    # pushing along the normal by the depth reaches the surface
    depth = radius - np.linalg.norm(contacts.point, axis=1)
    pushed = contacts.point + depth[:, None] * contacts.frame[:, 0]
    np.testing.assert_allclose(np.linalg.norm(pushed, axis=1), radius, rtol=2e-3)
    assert_frames(contacts)


@pytest.mark.parametrize("offset", [0.0, 0.07, 0.102, 0.1035])
def test_long_strands_far_from_the_body_find_exactly_the_elements_the_samples_say(offset):
    """Strands of 50 elements passing a sphere of 10 cm at ``offset`` from its centre, from 40 cm away
    (detection skips samples it can prove are far, by the distance of earlier ones): the elements declared,
    and the samples counted inside, are those trimesh's own signed distances of the samples give."""
    radius = 0.1
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    elements, n = 50, SETTINGS.samples_per_element
    direction = np.array([1.0, 0.3, -0.2]) / np.linalg.norm([1.0, 0.3, -0.2])
    side = np.cross(direction, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    h = helices([straight(offset * side - 0.45 * direction, direction, 1.0, elements)])
    contacts, report = detect_contacts(h, sphere, BODY_ONLY)
    s = np.linspace(0.0, 1.0, elements * (n - 1) + 1)
    sd = -trimesh.proximity.signed_distance(sphere, points_on(h, 0, s))  # trimesh: positive inside
    per_element = np.stack([sd[e * (n - 1):e * (n - 1) + n] for e in range(elements)])
    least = per_element.argmin(axis=1)
    last = np.arange(elements) == elements - 1
    expected = (per_element.min(axis=1) < SETTINGS.body_distance) & ((least < n - 1) | last)
    assert expected.any()
    np.testing.assert_array_equal(np.sort(contacts.element[:, 0]), np.flatnonzero(expected))
    assert report.points_inside_body == np.count_nonzero(sd < 0.0)


def test_past_an_open_boundary_nothing_is_inside():
    """A box open at the bottom (a bust cut at the chest): below the hole is outside; inside, the walls push out."""
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    open_box = trimesh.Trimesh(box.vertices, box.faces[box.face_normals[:, 1] > -0.5], process=False)
    assert not open_box.is_watertight  # trimesh's contains cannot answer here
    below = straight([-0.05, -0.12, 0.0], [1.0, 0.0, 0.0], 0.1, 2)  # under the hole, 2 cm below the rim
    through = straight([-0.03, 0.07, -0.153], [0.0, 0.0, 1.0], 0.3, 6)  # through the box, 3 cm under its top
    h = helices([below, through])
    contacts, report = detect_contacts(h, open_box, BODY_ONLY)
    assert set(contacts.strand[:, 0]) == {1}
    assert report.strands_inside_body == 1
    # inside, samples with |z| < 7 cm are 3 cm deep (nearest the top) and |z| < 10 cm are inside
    s = np.linspace(0.0, 0.3, 6 * 7 + 1)
    assert report.points_inside_body == np.count_nonzero(np.abs(s - 0.153) < 0.1)
    assert report.deepest_inside == pytest.approx(0.03, abs=EXACT)
    plateau = np.abs(contacts.point[:, 2]) < 0.07
    assert plateau.sum() == 4  # elements 1-4, at their first sample on the plateau
    np.testing.assert_allclose(contacts.frame[plateau, 0], np.tile([0.0, 1.0, 0.0], (4, 1)), atol=EXACT)
    # element 5 starts 3 mm inside the wall z = 0.1 and leaves through it: pushed out through that wall
    np.testing.assert_allclose(contacts.point[~plateau], [[-0.03, 0.07, 0.097]], atol=EXACT)
    np.testing.assert_allclose(contacts.frame[~plateau, 0], [[0.0, 0.0, 1.0]], atol=EXACT)


def test_several_pieces_a_non_manifold_fin_and_an_inside_out_piece():
    """Two cubes apart (one inside out) and a fin on an edge of the first: each gets its analytic contact."""
    a = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    b = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    b.apply_translation([0.5, 0.0, 0.0])
    b.invert()
    # the fin shares the cube's edge y = z = 0.05 (three faces on one edge: non-manifold) and sticks out along +z
    fin_v = np.array([[-0.05, 0.05, 0.05], [0.05, 0.05, 0.05], [0.0, 0.05, 0.15]])
    vertices = np.concatenate([a.vertices, b.vertices, fin_v])
    faces = np.concatenate([a.faces, b.faces + 8, [[16, 17, 18]]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    prepared = BodyMesh.from_mesh(mesh)
    assert any("inward" in note for note in prepared.notes)
    over_a = straight([-0.02, 0.052, -0.03], [0.0, 0.0, -1.0], 0.02, 1)  # 2 mm over the top of cube a
    inside_b = straight([0.48, 0.03, -0.01], [0.0, 0.0, 1.0], 0.02, 1)  # in cube b, 2 cm under its top
    h = helices([over_a, inside_b])
    contacts, report = detect_contacts(h, prepared, BODY_ONLY)
    assert list(contacts.strand[:, 0]) == [0, 1]
    np.testing.assert_allclose(contacts.frame[0, 0], [0.0, 1.0, 0.0], atol=EXACT)
    np.testing.assert_allclose(contacts.frame[1, 0], [0.0, 1.0, 0.0], atol=EXACT)
    assert report.strands_inside_body == 1 and report.points_inside_body == SETTINGS.samples_per_element


# --- hair-hair ---------------------------------------------------------------------------------------------------

def crossing(offset):
    """Strand 0 along y at x = 0.013, z = offset; strand 1 along x at z = 0; they cross over (0.013, 0, 0)."""
    s0 = straight([0.013, -0.041, offset], [0.0, 1.0, 0.0], 0.1, 4)
    s1 = straight([-0.05, 0.0, 0.0], [1.0, 0.0, 0.0], 0.1, 4)
    return helices([s0, s1])


def test_crossing_strands_touch_once_at_the_analytic_closest_points():
    offset = 0.0005
    contacts, report = detect_contacts(crossing(offset), None, HAIR_ONLY)
    assert contacts.n_contacts == 1 and contacts.n_hair == 1 and report.n_hair == 1
    np.testing.assert_array_equal(contacts.strand, [[0, 1]])
    np.testing.assert_allclose(contacts.s, [[0.041, 0.063]], rtol=0, atol=EXACT)
    np.testing.assert_allclose(contacts.point, [[0.013, 0.0, offset]], rtol=0, atol=EXACT)
    np.testing.assert_allclose(contacts.frame[0, 0], [0.0, 0.0, 1.0], rtol=0, atol=EXACT)  # from B (z = 0) to A
    np.testing.assert_array_equal(contacts.mu, SETTINGS.mu_hair)
    assert_frames(contacts)


def test_a_stray_strand_far_away_changes_nothing():
    """A strand 10,000 km off (a units mistake) makes the grid too fine to key: it is coarsened, not wrong."""
    h = crossing(0.0005)
    far = helices([(h.root[i], h.frame0[i], h.omega[4 * i:4 * i + 4], h.length[4 * i:4 * i + 4]) for i in range(2)]
                  + [straight([1e7, 1e7, 1e7], [0.0, 1.0, 0.0], 0.1, 4)])
    near, _ = detect_contacts(h, None, HAIR_ONLY)
    both, _ = detect_contacts(far, None, HAIR_ONLY)
    for name in ("strand", "s", "point", "frame"):
        np.testing.assert_array_equal(getattr(both, name), getattr(near, name))


def test_crossing_strands_beyond_the_distance_do_not_touch():
    contacts, _ = detect_contacts(crossing(SETTINGS.hair_distance * 1.01), None, HAIR_ONLY)
    assert contacts.n_contacts == 0


def test_intersecting_strands_take_the_normal_from_their_tangents():
    contacts, _ = detect_contacts(crossing(0.0), None, HAIR_ONLY)
    assert contacts.n_contacts == 1
    # t_A x t_B = y x x = -z, oriented so that its largest component is positive
    np.testing.assert_allclose(contacts.frame[0, 0], [0.0, 0.0, 1.0], rtol=0, atol=EXACT)
    assert_frames(contacts)


@pytest.mark.parametrize("shift", [0.0, 0.0125, 0.004])
def test_parallel_strands_touch_at_most_once_per_element_pair(shift):
    gap = 0.0005
    a = straight([0.0, 0.0, 0.0], [0.0, -1.0, 0.0], 0.1, 4)
    b = straight([gap, -shift, 0.0], [0.0, -1.0, 0.0], 0.1, 4)
    h = helices([a, b])
    contacts, _ = detect_contacts(h, None, HAIR_ONLY)
    elements = np.minimum(np.floor(contacts.s / 0.025 + 1e-9).astype(int), 3)
    pairs = {tuple(e) for e in elements}
    assert len(pairs) == contacts.n_contacts
    overlapping = {(i, j) for i in range(4) for j in range(4)
                   if max(0.025 * i, 0.025 * j + shift) <= min(0.025 * (i + 1), 0.025 * (j + 1) + shift)}
    assert pairs <= overlapping
    if shift == 0.0:
        assert pairs == {(0, 0), (1, 1), (2, 2), (3, 3)}  # the joints belong to the next pair
    xb = np.concatenate([points_on(h, 1, s) for s in contacts.s[:, 1]])
    np.testing.assert_allclose(np.linalg.norm(contacts.point - xb, axis=1), gap, rtol=0, atol=EXACT)
    np.testing.assert_allclose(contacts.frame[:, 0], np.tile([-1.0, 0.0, 0.0], (len(xb), 1)), atol=EXACT)


def tight_helix(turns_radius=0.002, pitch=0.0006):
    """(kappa, tau) of a helix of the given radius and pitch: consecutive turns ``pitch`` apart."""
    k = 1.0 / (turns_radius**2 + (pitch / (2 * np.pi)) ** 2)
    return turns_radius * k, pitch * k / (2 * np.pi)


def test_a_strand_never_contacts_itself():
    kappa, tau = tight_helix()
    omega = np.tile([kappa, 0.0, tau], (6, 1))
    length = np.full(6, 0.01)
    whole = helices([(np.zeros(3), np.eye(3), omega, length)])
    contacts, _ = detect_contacts(whole, None, HAIR_ONLY)
    assert contacts.n_contacts == 0
    # the same curve cut in two strands (2 mm of it left out between them): its turns 0.6 mm apart now touch
    x = np.empty((1, 3))
    F = np.empty((1, 3, 3))
    frames_at(np.zeros(3), np.eye(3), omega, length, np.array([0.032]), x, F)
    halves = helices([(np.zeros(3), np.eye(3), omega[:3], length[:3]), (x[0], F[0], omega[3:], [0.008, 0.01, 0.01])])
    contacts, _ = detect_contacts(halves, None, HAIR_ONLY)
    assert contacts.n_hair > 0
    np.testing.assert_array_equal(contacts.strand, np.tile([0, 1], (contacts.n_contacts, 1)))
    xb = np.concatenate([points_on(halves, 1, s) for s in contacts.s[:, 1]])
    distance = np.linalg.norm(contacts.point - xb, axis=1)
    assert np.all(distance < SETTINGS.hair_distance)
    np.testing.assert_allclose(distance, 0.0006, rtol=0.02)  # the pitch, up to the helix's slant


def segment_distances(p1, q1, p2, q2):
    """Closest points of segment pairs, vectorised (Ericson 5.1.9): (d, u, v)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("...i,...i", d1, d1)
    e = np.einsum("...i,...i", d2, d2)
    f = np.einsum("...i,...i", d2, r)
    c = np.einsum("...i,...i", d1, r)
    b = np.einsum("...i,...i", d1, d2)
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(denom > 1e-14 * a * e, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        v = (b * u + f) / e
        u = np.where(v < 0, np.clip(-c / a, 0, 1), np.where(v > 1, np.clip((b - c) / a, 0, 1), u))
    v = np.clip(v, 0.0, 1.0)
    d = np.linalg.norm(p1 + u[..., None] * d1 - p2 - v[..., None] * d2, axis=-1)
    return d, u, v


def test_hashed_hair_pairs_agree_with_brute_force(rng):
    """Every pair of elements on different strands, by brute force on 24 segments per element."""
    strands = []
    for _ in range(20):
        root = rng.uniform(-0.003, 0.003, 3)
        t = np.array([0.0, -1.0, 0.0]) + rng.normal(scale=0.3, size=3)
        strands.append((root, frame_with_tangent(t), rng.normal(scale=40.0, size=(5, 3)), np.full(5, 0.01)))
    h = helices(strands)
    contacts, _ = detect_contacts(h, None, HAIR_ONLY)
    m, hd = 24, SETTINGS.hair_distance
    elems = [(i, e) for i in range(h.n_strands) for e in range(5)]
    fine = {(i, e): points_on(h, i, 0.01 * e + np.linspace(0.0, 0.01, m + 1)) for i, e in elems}
    fine = {k: np.vstack([v[:-1], points_on(h, k[0], [0.01 * (k[1] + 1)])]) for k, v in fine.items()}
    close, ambiguous = set(), set()
    for i, ea in elems:
        for j, eb in elems:
            if j <= i:
                continue
            A, B = fine[(i, ea)], fine[(j, eb)]
            if np.min(np.linalg.norm(A[:, None] - B[None], axis=2)) > hd + 0.01 / m:
                continue
            d, u, v = segment_distances(A[:-1, None], A[1:, None], B[None, :-1], B[None, 1:])
            ka, kb = np.unravel_index(np.argmin(d), d.shape)
            end_a = ka == m - 1 and u[ka, kb] == 1.0 and ea < 4
            end_b = kb == m - 1 and v[ka, kb] == 1.0 and eb < 4
            if abs(d[ka, kb] - hd) < 2e-5 or (ka >= m - 2 and ea < 4) or (kb >= m - 2 and eb < 4):
                ambiguous.add((i, ea, j, eb))
            elif d[ka, kb] < hd and not end_a and not end_b:
                close.add((i, ea, j, eb))
    found = {(a, int(min(sa // 0.01 + 1e-9, 4)), b, int(min(sb // 0.01 + 1e-9, 4)))
             for (a, b), (sa, sb) in zip(contacts.strand, contacts.s)}
    assert len(close) > 30
    assert found - ambiguous == close



@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hair_pairs_find_every_close_polyline_pair(seed):
    """The hashed, swept search against every pair of segments: dense strands packed in a few millimetres (cells
    crowded, boxes spanning several cells), a per-element reach and a searched subset."""
    rng = np.random.default_rng(seed)
    strands, elements, n = 40, 3, 6
    E = strands * elements
    steps = rng.normal(scale=4e-4, size=(strands, elements * (n - 1), 3)) + np.array([0.0, -6e-4, 0.0])
    roots = rng.uniform(0.0, 3e-3, size=(strands, 1, 3))
    line = np.concatenate([roots, roots + np.cumsum(steps, axis=1)], axis=1)
    samples = np.stack([line[s, e * (n - 1):(e + 1) * (n - 1) + 1] for s in range(strands) for e in range(elements)])
    omega = np.zeros((E, 3))  # straight elements: the polyline is the centre line, no sag
    length = np.full(E, 1e-3)  # arc lengths are reported as (segment + parameter) * length / (n - 1)
    strand_of = np.repeat(np.arange(strands), elements)
    reach = rng.uniform(0.5e-3, 1.5e-3, E)
    wide = rng.random(E) < 0.4
    ea, eb, sa, sb, gap, close = hair_pairs(samples, omega, length, strand_of, reach, wide)
    found = {(a, b): (x, y) for a, b, x, y in zip(ea, eb, sa, sb)}
    assert len(found) == len(ea)
    expected, ambiguous, segment_pairs = {}, set(), 0
    h = 1e-3 / (n - 1)
    for a in range(E):
        for b in range(E):
            if strand_of[a] >= strand_of[b] or not (wide[a] or wide[b]):
                continue
            d, u, v = segment_distances(samples[a, :-1, None], samples[a, 1:, None], samples[b, None, :-1],
                                        samples[b, None, 1:])
            limit = 0.5 * (reach[a] + reach[b])
            segment_pairs += int(np.count_nonzero(d < limit))
            if d.min() >= limit:
                continue
            if abs(d.min() - limit) < 1e-12:
                ambiguous.add((a, b))
            ka, kb = np.unravel_index(np.argmin(d), d.shape)
            expected[(a, b)] = ((ka + u[ka, kb]) * h, (kb + v[ka, kb]) * h, d.min())
    assert len(expected) > 200
    assert set(found) - ambiguous == set(expected) - ambiguous
    assert close == segment_pairs
    for key, (x, y, dmin) in expected.items():
        if key in found:
            # the closest points may differ only where two segment pairs are equally close
            fx, fy = found[key]
            assert gap[np.flatnonzero((ea == key[0]) & (eb == key[1]))[0]] == pytest.approx(dmin, abs=1e-12)
            got = np.linalg.norm(_polyline_point(samples[key[0]], fx / h) - _polyline_point(samples[key[1]], fy / h))
            assert got == pytest.approx(dmin, abs=1e-12)
    assert np.all(np.diff(ea * E + eb) > 0)


def _polyline_point(points, t):
    k = min(int(t), len(points) - 2)
    return points[k] + (t - k) * (points[k + 1] - points[k])

# --- the whole pipeline on samples and real data ------------------------------------------------------------------

@pytest.fixture(scope="module")
def wavy():
    groom, _ = load_groom(SAMPLES / "wavy.h5", ImportSettings(guides=40, seed=3))
    h, _ = fit_groom(groom, FitSettings())
    return h, load_body(SAMPLES / "body.obj", hair_unit_transform(1.0))


def check_geometry(h: Helices, body, contacts: Contacts, settings: ContactSettings, report: DetectReport):
    """Independent checks of declared contacts: distances by trimesh and by the rod module, normals, frames."""
    assert_frames(contacts)
    body_rows = contacts.strand[:, 1] == BODY
    assert np.all(contacts.s[body_rows, 0] >= settings.root_clearance)
    if body_rows.any():
        closest, distance, _ = trimesh.proximity.closest_point(body, contacts.point[body_rows])
        reach = max(settings.body_distance, report.deepest_inside)
        # trimesh's closest point is off by up to 1e-5 m at times; the layer rule's contacts lie beyond
        # body_distance, as many as it reports, and within the widest layer
        beyond = distance > reach + 1e-5
        assert abs(int(beyond.sum()) - report.body_layer) <= max(2, 0.01 * report.body_layer)
        assert np.all(distance <= max(reach, settings.layer_max_gap if settings.layer else 0.0) + 1e-5)
        # the normal leads to a closest surface point (towards it inside, away from it outside; which of
        # several equally close points, as inside a crease, is not compared)
        apart = distance > 1e-4
        p, n, d = contacts.point[body_rows][apart], contacts.frame[body_rows, 0][apart], distance[apart, None]
        _, back_out, _ = trimesh.proximity.closest_point(body, p - d * n)
        _, back_in, _ = trimesh.proximity.closest_point(body, p + d * n)
        assert np.all(np.minimum(back_out, back_in) < 2e-5)
    hair = ~body_rows
    assert np.all(contacts.strand[hair, 0] < contacts.strand[hair, 1])
    xb = np.array([points_on(h, b, s)[0] for b, s in zip(contacts.strand[hair, 1], contacts.s[hair, 1])]).reshape(-1, 3)
    xa = np.array([points_on(h, a, s)[0] for a, s in zip(contacts.strand[hair, 0], contacts.s[hair, 0])]).reshape(-1, 3)
    np.testing.assert_allclose(xa, contacts.point[hair], rtol=0, atol=1e-12)
    gap = np.linalg.norm(xa - xb, axis=1)
    assert np.all(gap < settings.hair_distance)
    apart = gap > 1e-6
    np.testing.assert_allclose(contacts.frame[hair, 0][apart], (xa - xb)[apart] / gap[apart, None], atol=1e-9)
    # the documented order: body first by (strand, s), then hair by (A, B, s_A)
    assert np.all(np.diff(body_rows.astype(int)) <= 0)
    keys = np.lexsort((contacts.s[body_rows, 0], contacts.strand[body_rows, 0]))
    np.testing.assert_array_equal(keys, np.arange(body_rows.sum()))
    keys = np.lexsort((contacts.s[hair, 0], contacts.strand[hair, 1], contacts.strand[hair, 0]))
    np.testing.assert_array_equal(keys, np.arange(hair.sum()))


def test_sample_groom_geometry_and_determinism(wavy, monkeypatch):
    h, body = wavy
    contacts, report = detect_contacts(h, body, SETTINGS)
    assert report.n_body > 0 and report.n_hair > 0
    assert (report.n_body, report.n_hair) == (contacts.n_body, contacts.n_hair)
    check_geometry(h, body, contacts, SETTINGS, report)
    monkeypatch.setenv("HAIRINV_THREADS", "1")
    again, _ = detect_contacts(h, body, SETTINGS)
    for name in ("strand", "s", "point", "frame", "mu"):
        np.testing.assert_array_equal(getattr(again, name), getattr(contacts, name))


def test_switches_and_missing_body(wavy):
    h, body = wavy
    none, report = detect_contacts(h, None, SETTINGS)
    assert none.n_body == 0 and none.n_hair > 0
    assert any("no body mesh" in line for line in report.lines())
    off, report = detect_contacts(h, body, dataclasses.replace(SETTINGS, body=False))
    assert off.n_body == 0 and any("ignored" in line for line in report.lines())
    done = []
    no_hair, _ = detect_contacts(h, body, dataclasses.replace(SETTINGS, hair_hair=False), progress=done.append)
    assert no_hair.n_hair == 0 and no_hair.n_body > 0
    assert sum(done) == h.n_strands


def test_group_round_trip(wavy, tmp_path):
    h, body = wavy
    contacts, _ = detect_contacts(h, body, SETTINGS)
    inputs = [{"name": "x.h5", "sha256": "0" * 64}]
    for c, name in ((contacts, "full.h5"), (Contacts.empty(), "empty.h5")):
        path = stages.write_stage(tmp_path / name, [c.group(SETTINGS, inputs)], "detect")
        read = stages.read_stage(path)
        group = read[stages.CONTACTS]
        assert group.config == {"contacts": dataclasses.asdict(SETTINGS)}
        assert group.inputs == inputs
        back = Contacts.from_group(group)
        for field in ("strand", "s", "point", "frame", "mu"):
            np.testing.assert_array_equal(getattr(back, field), getattr(c, field))
            assert getattr(back, field).dtype == getattr(c, field).dtype
    half = contacts.subset(contacts.strand[:, 1] == BODY)
    assert half.n_contacts == contacts.n_body and half.n_hair == 0


@pytest.mark.parametrize("change", [
    {"body_distance": 0.0}, {"hair_distance": -1e-3}, {"hair_distance": float("nan")}, {"samples_per_element": 1},
    {"mu_hair": -0.1}, {"mu_body": float("inf")}, {"root_clearance": -1.0},
])
def test_invalid_settings_are_refused(change):
    with pytest.raises(InputError, match=f"contacts.{next(iter(change))}"):
        detect_contacts(crossing(0.0), None, dataclasses.replace(SETTINGS, **change))


def test_real_sintel_with_its_body():
    hair = real_path("sintel", "GEO-sintel_hair_emit.001-sintel_hair.tfx")
    scale = 0.008  # ≈0.8 cm per unit (shared/data/real/README.md)
    groom, _ = load_groom(hair, ImportSettings(scale=scale))
    h, _ = fit_groom(groom, FitSettings(tolerance=5e-4))
    body = load_body(real_path("sintel", "sintel.obj"), hair_unit_transform(scale))
    contacts, report = detect_contacts(h, body, SETTINGS)
    print("\n".join(report.lines()))
    assert report.n_body > 50 and report.n_hair > 20
    assert 0 < report.strands_inside_body < 0.1 * h.n_strands  # README: 2 % of strands have a vertex inside
    check_geometry(h, body, contacts, SETTINGS, report)


def test_no_hair_hair_contact_between_two_roots():
    """Neighbouring roots 0.5 mm apart, strands diverging: their only close
    points lie within root_clearance of both (clamped) roots, so no contact;
    with a zero clearance the same pair is declared."""
    a = straight((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.06, 3)
    b = straight((0.0, 0.0005, 0.0), (1.0, 1.0, 0.0), 0.06, 3)
    settings = ContactSettings(body=False, hair_distance=1e-3, root_clearance=5e-3)
    contacts, report = detect_contacts(helices([a, b]), None, settings)
    assert contacts.n_hair == 0
    assert any("root_clearance" in note for note in report.notes)
    loose, _ = detect_contacts(helices([a, b]), None, dataclasses.replace(settings, root_clearance=0.0))
    assert loose.n_hair == 1 and np.all(loose.s[0] < 1e-3)


def test_hair_contacts_per_element_are_capped_closest_first():
    """Nine parallel strands 0.2 mm apart: without a limit each element touches
    every neighbour within reach; with a cap of 2 each element keeps its two
    closest (the adjacent strands)."""
    strands = [straight((0.0, 0.0, 2e-4 * k), (1.0, 0.0, 0.0), 0.04, 2) for k in range(9)]
    h = helices(strands)
    free, _ = detect_contacts(h, None, dataclasses.replace(HAIR_ONLY, max_hair_per_element=0))
    capped, report = detect_contacts(h, None, dataclasses.replace(HAIR_ONLY, max_hair_per_element=2))
    per_element = lambda c: np.bincount(  # noqa: E731
        np.concatenate([2 * c.strand[:, 0] + (c.s[:, 0] >= 0.02), 2 * c.strand[:, 1] + (c.s[:, 1] >= 0.02)]),
        minlength=18)
    assert per_element(free).max() > 2
    assert per_element(capped).max() <= 2
    assert capped.n_hair < free.n_hair
    gap = np.abs(capped.strand[:, 0] - capped.strand[:, 1])
    assert np.all(gap == 1)  # the closest neighbours, 0.2 mm away
    assert any("max_hair_per_element" in note for note in report.notes)


# --- the hair layer and wisps ------------------------------------------------------------------------------------

LAYERED = dataclasses.replace(SETTINGS, hair_hair=False)


def draped_over_sphere(radius, gap, arc_angle=1.2, arc_elements=8, tail=0.1, tail_elements=4):
    """From the top of a sphere, a strand following it at ``gap`` (a circle of radius ``radius + gap``
    about its centre) for ``arc_angle`` radians, then leaving it along its tangent for ``tail`` m."""
    R = radius + gap
    root = np.array([0.0, R, 0.0])
    F = frame_with_tangent([1.0, 0.0, 0.0], n2=[0.0, 1.0, 0.0])  # n2 away from the centre: it bends towards it
    omega = np.concatenate([np.tile([1.0 / R, 0.0, 0.0], (arc_elements, 1)), np.zeros((tail_elements, 3))])
    length = np.concatenate([np.full(arc_elements, R * arc_angle / arc_elements),
                             np.full(tail_elements, tail / tail_elements)])
    return (root, F, omega, length), R * arc_angle


@pytest.mark.parametrize("gap", [0.005, 0.007])
def test_a_strand_lying_on_a_sphere_at_a_gap_gets_layer_contacts_and_none_where_it_leaves(gap):
    """Beyond body_distance (4 mm) the fixed radius declares nothing; the layer rule declares the arc's
    elements at their gap, and nothing along the tail, whose distance grows as it leaves the sphere."""
    radius = 0.1
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    strand, arc = draped_over_sphere(radius, gap)
    h = helices([strand])
    fixed, _ = detect_contacts(h, sphere, dataclasses.replace(LAYERED, layer=False))
    assert fixed.n_contacts == 0
    contacts, report = detect_contacts(h, sphere, LAYERED)
    # every arc element past the root clearance declares one, at the gap (the facets lie within 0.1 mm)
    arc_starts = np.cumsum(np.r_[0.0, h.length[:7]])
    expected = int(np.count_nonzero(arc_starts + h.length[:8] > SETTINGS.root_clearance))
    assert contacts.n_body == report.body_layer == expected
    np.testing.assert_allclose(contacts.gap, gap, atol=1.5e-4)
    assert contacts.s[:, 0].max() <= arc + 1e-9
    # the tail's distances: it leaves the sphere (independently, from trimesh)
    tail = points_on(h, 0, np.linspace(arc + 0.03, arc + 0.1, 8))
    assert np.all(-trimesh.proximity.signed_distance(sphere, tail) > gap + SETTINGS.layer_tolerance)
    assert report.layer_strands == 1 and report.layer_gaps == pytest.approx([gap], abs=1.5e-4)
    assert any("hair layer" in line for line in report.lines())
    # normals point away from the centre, up to the facets' tilt
    radial = contacts.point / np.linalg.norm(contacts.point, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", contacts.frame[:, 0], radial) > FACET_COS)


def test_a_strand_only_passing_the_body_gets_no_layer_contact():
    """A straight strand passing 7 mm over the edge of a box: it comes that near over about a centimetre
    only (the distance to an edge grows linearly), so it is not lying on the body. Along the box's face at
    the same distance it is."""
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    out = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    across = np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)
    passing = straight(np.array([0.1, 0.1, 0.0]) + 0.007 * out - 0.2 * across, across, 0.4, 20)
    contacts, report = detect_contacts(helices([passing]), box, LAYERED)
    assert contacts.n_body == 0 and report.body_layer == 0
    lying = straight([0.107, 0.09, -0.15], [0.0, 0.0, 1.0], 0.3, 15)
    contacts, report = detect_contacts(helices([lying]), box, LAYERED)
    assert contacts.n_body == report.body_layer > 10
    np.testing.assert_allclose(contacts.gap, 0.007, atol=1e-9)


def stacked_pair(gap, side_by_side=False):
    """Two straight horizontal strands along +x, 2 mm above a floor and ``gap`` above (or beside) it."""
    low = straight([0.0, 0.002, 0.0], [1.0, 0.0, 0.0], 0.1, 5)
    offset = [0.0, 0.0, gap] if side_by_side else [0.0, gap, 0.0]
    high = straight(np.array([0.0, 0.002, 0.0]) + offset, [1.0, 0.0, 0.0], 0.1, 5)
    return helices([low, high])


def test_a_strand_resting_on_another_beyond_the_fixed_radius_is_supported():
    """Two strands stacked 2 mm apart (twice hair_distance, the groom's own spacing): the wisp rule
    declares their contacts, normals vertical; side by side at the same spacing they get none (nothing
    to hold against gravity), nor without the up axis or with the rule off. Inverted on a floor the
    upper strand does rest on the lower one: its contacts carry its weight."""
    from hairinv.config import SolverSettings
    from hairinv.invert import invert
    from hairinv.config import MaterialSettings
    from hairinv.model import Material

    up = np.array([0.0, 1.0, 0.0])
    settings = dataclasses.replace(SETTINGS, body_distance=0.0025, root_clearance=0.005, layer=False)
    h = stacked_pair(0.002)
    contacts, report = detect_contacts(h, plane(), settings, up=up)
    hair = contacts.strand[:, 1] >= 0
    assert hair.sum() == report.hair_wisp > 0
    np.testing.assert_allclose(contacts.gap[hair], 0.002, atol=1e-9)
    assert np.all(np.abs(contacts.frame[hair, 0] @ up) == pytest.approx(1.0))
    assert np.all(contacts.strand[~hair, 0] == 0)  # only the lower strand reaches the floor
    assert report.wisp_radius == pytest.approx([1.25 * 0.002] * 2)
    for other in (detect_contacts(stacked_pair(0.002, side_by_side=True), plane(), settings, up=up)[0],
                  detect_contacts(h, plane(), settings)[0],
                  detect_contacts(h, plane(), dataclasses.replace(settings, wisp=False), up=up)[0]):
        assert not np.any(other.strand[:, 1] >= 0)
    model, _ = invert(h, contacts, Material.from_settings(MaterialSettings(), up), SolverSettings(tolerance=1e-8))
    weight = Material.from_settings(MaterialSettings(), up).linear_density * 9.81 * 0.1
    assert model.force[hair, 0].sum() > 0.3 * weight


# --- dense grooms: the hair-hair search and the layer rule at full-head sizes -----------------------------------

def bundle_and_guides(seed=0):
    """Bent horizontal strands along +x over the floor y = 0: a dense bundle (20 strands, 0.5 mm apart, as the
    follow hairs of one guide) and, 3 cm to the side, sparse guides stacked 2-2.8 mm apart (wisps), plus one
    strand between the two kinds at 1.5-3 mm from the bundle, so every pairing of dense and sparse occurs."""
    rng = np.random.default_rng(seed)
    strands = []
    for i in range(5):
        for j in range(4):
            y, z = 0.004 + 0.0005 * j, 0.0005 * i + 0.0001 * rng.uniform()
            strands.append(((0.0, y, z), frame_with_tangent([1.0, 0.0, 0.0], n2=[0.0, 1.0, 0.0]),
                            np.tile([rng.uniform(0.5, 1.0), 0.0, 0.0], (6, 1)), np.full(6, 0.02)))
    y = 0.004
    for k in range(5):
        strands.append(((0.0, y, 0.03), frame_with_tangent([1.0, 0.0, 0.0], n2=[0.0, 1.0, 0.0]),
                        np.tile([rng.uniform(0.5, 1.0), 0.0, 0.0], (6, 1)), np.full(6, 0.02)))
        y += rng.uniform(0.002, 0.0028)
    strands.append(((0.0, 0.0055 + 0.0015, 0.0025), frame_with_tangent([1.0, 0.0, 0.0], n2=[0.0, 1.0, 0.0]),
                    np.tile([0.7, 0.0, 0.0], (6, 1)), np.full(6, 0.02)))
    return helices(strands)


def assert_same_detection(a: Contacts, report_a: DetectReport, b: Contacts, report_b: DetectReport):
    """Every field of the contacts and the wisp radii, bit for bit."""
    for key in ("strand", "s", "point", "frame", "mu", "gap", "element"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    np.testing.assert_array_equal(report_a.wisp_radius, report_b.wisp_radius)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_two_pass_hair_search_declares_what_one_wide_search_does(monkeypatch, seed):
    """The first search (within hair_distance) finds the strands whose wisp radius is hair_distance; the
    second searches only the pairs with a sparse strand to hair_max_distance. Contacts and wisp radii are
    those of one search of every pair to hair_max_distance, bit for bit, on a groom with both kinds."""
    import functools

    from hairinv.contacts import detect as detect_module

    up = np.array([0.0, 1.0, 0.0])
    settings = dataclasses.replace(SETTINGS, root_clearance=0.0, layer=False)
    h = bundle_and_guides(seed)
    two, report = detect_contacts(h, plane(), settings, up=up)
    monkeypatch.setattr(detect_module, "_hair_candidates",
                        functools.partial(detect_module._hair_candidates, two_pass=False))
    one, report_one = detect_contacts(h, plane(), settings, up=up)
    assert_same_detection(two, report, one, report_one)
    # both kinds are there: the bundle at hair_distance, the guides wider, and wisp contacts between guides
    assert np.all(report.wisp_radius[:20] == settings.hair_distance)
    assert np.all(report.wisp_radius[20:25] > settings.hair_distance)
    assert report.hair_wisp > 0 and two.n_hair > report.hair_wisp


def dense_head(seed, guides=12, follow=10, spread=0.001):
    """Guides hanging from a row of roots over the floor, each with follow hairs within ``spread`` of it (the
    same curvatures, roots moved across the guide): elements with tens of neighbours within hair_distance."""
    rng = np.random.default_rng(seed)
    strands = []
    for g in range(guides):
        omega = np.column_stack([rng.normal(0.0, 20.0, 5), rng.normal(0.0, 20.0, 5), rng.normal(0.0, 5.0, 5)])
        base = np.array([0.004 * g, 0.05, 0.0])
        for f in range(follow + 1):
            offset = np.zeros(3) if f == 0 else np.array([rng.uniform(-spread, spread), 0.0,
                                                          rng.uniform(-spread, spread)])
            strands.append((base + offset, frame_with_tangent([0.0, -1.0, 0.05], n2=[1.0, 0.0, 0.0]),
                            omega + rng.normal(0.0, 0.3, omega.shape), np.full(5, 0.012)))
    return helices(strands)


def straight_grid(side=6, spacing=0.0005):
    """Straight strands along +x over the floor on a square lattice ``spacing`` apart: every distance ties
    with several others (4 neighbours at the spacing, 4 on the diagonals), so the greedy's ties decide."""
    return helices([((0.0, 0.004 + spacing * j, spacing * i), frame_with_tangent([1.0, 0.0, 0.0], n2=[0.0, 1.0, 0.0]),
                     np.zeros((5, 3)), np.full(5, 0.012)) for i in range(side) for j in range(side)])


@pytest.mark.parametrize("seed, cap, groom", [(0, 8, "dense"), (1, 2, "dense"), (2, 1, "dense"), (3, 8, "mixed"),
                                              (4, 2, "mixed"), (0, 1, "grid"), (0, 3, "grid")])
def test_pairs_refined_only_where_needed_give_the_same_contacts(monkeypatch, seed, cap, groom):
    """With the per-element cap, pairs of two dense strands are refined only when their distance matters (to
    find the dense strands, near the roots, and in the greedy cap while both elements still hold fewer than
    the cap). Contacts, wisp radii and the root note are those of refining every pair, bit for bit, and on a
    dense head most pairs are never refined."""
    import functools

    from hairinv.contacts import detect as detect_module

    up = np.array([0.0, 1.0, 0.0])
    settings = dataclasses.replace(SETTINGS, layer=False, max_hair_per_element=cap, root_clearance=0.004)
    h = {"dense": dense_head, "mixed": bundle_and_guides, "grid": lambda seed: straight_grid()}[groom](seed)
    refined = []
    real_cap = detect_module._cap_pairs

    def spy(*args):
        out = real_cap(*args)
        refined.append((int(args[5].sum()), len(args[5])))  # pairs.refined after the greedy
        return out

    monkeypatch.setattr(detect_module, "_cap_pairs", spy)
    candidates = detect_module._hair_candidates
    lazy, report = detect_contacts(h, plane(), settings, up=up, narrow=False)
    monkeypatch.setattr(detect_module, "_hair_candidates", functools.partial(candidates, lazy=False))
    eager, report_eager = detect_contacts(h, plane(), settings, up=up)
    assert_same_detection(lazy, report, eager, report_eager)
    roots = [n for n in report.notes if "root_clearance" in n]
    assert roots == [n for n in report_eager.notes if "root_clearance" in n]
    assert lazy.n_hair > 0
    (some, total), (every, total_eager) = refined
    assert every == total_eager == total
    if groom == "dense":
        counts = np.bincount(lazy.element[lazy.strand[:, 1] >= 0].ravel(), minlength=h.n_elements)
        assert counts.max() == cap  # the cap binds on a dense head, and most pairs are never measured
        assert any("not measured" in n for n in report.notes)
        if cap <= 2:
            assert some < 0.6 * total, (some, total)


def sampled(h, n=8):
    """What detection works on: ``(xs, Fs, s0, samples, omega, length, strand_of, is_last)`` of every element."""
    from hairinv.contacts._curve import element_starts, sample_elements

    offsets = np.asarray(h.offsets)
    E = h.n_elements
    xs, Fs, s0, samples = np.empty((E, 3)), np.empty((E, 3, 3)), np.empty(E), np.empty((E, n, 3))
    omega, length = np.ascontiguousarray(h.omega), np.ascontiguousarray(h.length)
    element_starts(np.ascontiguousarray(h.root), np.ascontiguousarray(h.frame0), offsets, omega, length, 0,
                   h.n_strands, xs, Fs, s0)
    sample_elements(xs, Fs, omega, length, 0, E, samples)
    strand_of = np.repeat(np.arange(h.n_strands), np.diff(offsets))
    is_last = np.zeros(E, np.int8)
    is_last[offsets[1:] - 1] = 1
    return xs, Fs, s0, samples, omega, length, strand_of, is_last


def near_both_roots(h, within, clearance):
    """Pairs of elements of two strands closer than ``within`` whose closest points both lie within ``clearance``
    of their roots (and are not an element's end that starts the next): every pair refined, no cap."""
    from hairinv.contacts import detect as detect_module

    xs, Fs, s0, samples, omega, length, strand_of, is_last = sampled(h)
    p = detect_module._found_pairs(samples, omega, length, strand_of, 2.0 * within)  # a search well past within
    detect_module._refine(p, np.ones(len(p.ea), bool), xs, Fs, omega, length)
    kept = detect_module._kept(p.ea, p.eb, p.sa, p.sb, p.dist, within, length, is_last)
    return int(np.count_nonzero(kept & (s0[p.ea] + p.sa < clearance) & (s0[p.eb] + p.sb < clearance)))


def tilted_lattice(seed, spacing, side=4, elements=1):
    """Straight strands on a square lattice ``spacing`` apart, turned and moved at random away from the axes and
    the origin: neighbours' distances round to a few ulps either side of the spacing."""
    rng = np.random.default_rng(seed)
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    origin = rng.uniform(-0.2, 0.2, 3)
    return helices([(origin + turn @ (0.0, spacing * j, spacing * i), frame_with_tangent(turn[:, 0]),
                     np.zeros((elements, 3)), np.full(elements, 0.01 / elements))
                    for i in range(side) for j in range(side)])


@pytest.mark.parametrize("seed, cap, groom, clearance", [(5, 8, "packed", 0.004), (6, 2, "dense", 0.0),
                                                         (7, 1, "dense", 0.02), (8, 4, "mixed", 0.004), (9, 2, "packed", 0.01),
                                                         (0, 2, "grid", 0.004), (0, 2, "tilted", 0.0),
                                                         (15, 1, "tilted", 0.0), (17, 2, "tilted", 0.004)])
def test_elements_holding_the_cap_close_by_are_searched_no_farther(monkeypatch, seed, cap, groom, clearance):
    """The pairs are first searched to a fraction of hair_distance; an element the greedy cap fills there is
    searched no farther. Contacts and wisp radii are those of searching every pair to hair_distance, bit for
    bit (the greedy could keep none of the pairs left out), with and without the wisp rule; on a dense head it
    does leave elements out, and where it leaves out one near the roots, the note on pairs near both roots
    counts those closer than the narrow reach (by their definition, every pair refined)."""
    import functools

    from hairinv.contacts import detect as detect_module

    h = {"dense": dense_head, "mixed": bundle_and_guides, "grid": lambda seed: straight_grid(),
         "packed": lambda seed: dense_head(seed, guides=6, follow=20, spread=0.0004),
         # neighbours at the narrow search's reach itself
         "tilted": lambda seed: tilted_lattice(seed, detect_module.NARROW * SETTINGS.hair_distance,
                                               elements=1 + seed % 2)}[groom](seed)
    candidates = detect_module._hair_candidates
    for up in (np.array([0.0, 1.0, 0.0]), None):
        settings = dataclasses.replace(SETTINGS, layer=False, max_hair_per_element=cap, root_clearance=clearance)
        monkeypatch.setattr(detect_module, "_hair_candidates", candidates)
        narrow, report = detect_contacts(h, plane(), settings, up=up)
        every, report_every = detect_contacts(h, plane(), settings, up=up, narrow=False)
        assert_same_detection(narrow, report, every, report_every)
        assert narrow.n_hair > 0
        if groom in ("dense", "packed", "tilted"):
            assert any("not searched farther" in n for n in report.notes), report.notes
        assert not any("not searched farther" in n for n in report_every.notes)
        roots = [n for n in report.notes if "root_clearance" in n]
        if not any("closer than" in n for n in roots):
            assert roots == [n for n in report_every.notes if "root_clearance" in n]
        else:
            # an element starting within root_clearance was settled: the note counts the pairs closer than the
            # narrow search's reach, all of which it found
            closer = detect_module.NARROW * settings.hair_distance
            assert roots == [f"hair-hair: {near_both_roots(h, closer, clearance)} contacts between two strands closer "
                             f"than {1e3 * closer:g} mm within root_clearance ({1e3 * clearance:g} mm) of both roots "
                             f"were not declared; nor were farther ones there, not all of which were searched or counted"]


@pytest.mark.parametrize("seed", [0, 1])
def test_hair_pairs_touching_given_strands_are_those_of_the_whole_search(seed):
    """``touching``: without the per-element cap, the hair-hair contacts with a strand among the given ones are
    exactly those of detecting every pair, and no others; with the cap, every contact touches them and no
    element holds more than the cap (it counts only those pairs)."""
    h = dense_head(seed, guides=6, follow=6)
    rng = np.random.default_rng(seed)
    touching = rng.random(h.n_strands) < 0.3
    for cap in (0, 2):
        settings = dataclasses.replace(SETTINGS, layer=False, wisp=False, max_hair_per_element=cap)
        some, _ = detect_contacts(h, plane(), settings, touching=touching)
        every, _ = detect_contacts(h, plane(), settings)
        hair = some.strand[:, 1] >= 0
        assert np.array_equal(some.subset(~hair).s, every.subset(every.strand[:, 1] < 0).s)  # body as before
        assert touching[some.strand[hair]].any(axis=1).all() and hair.sum() > 10
        if cap == 0:
            mine = every.subset((every.strand[:, 1] >= 0) & touching[np.maximum(every.strand, 0)].any(axis=1))
            for name in ("strand", "s", "gap", "element", "point"):
                np.testing.assert_array_equal(getattr(some.subset(hair), name), getattr(mine, name))
        else:
            held = np.bincount(some.element[hair].ravel(), minlength=h.n_elements)
            assert held.max() <= cap
    with pytest.raises(ValueError, match="wisp"):
        detect_contacts(h, plane(), SETTINGS, up=np.array([0.0, 1.0, 0.0]), touching=touching)

@pytest.mark.parametrize("seed", [0, 1])
def test_hair_pairs_searched_farther_per_strand_are_those_within_the_sum_of_their_strands_reaches(seed):
    """``farther``: a pair of strands a, b is declared within ``hair_distance + farther[a] + farther[b]``.
    Without the cap, the contacts are those of one search of every pair to the farthest reach, filtered pair by
    pair; with the cap, those the greedy keeps of them, closest first (its definition); with one value for all,
    those of a search at that reach (no per-strand code)."""
    h = dense_head(seed, guides=6, follow=6)
    rng = np.random.default_rng(seed)
    hd = SETTINGS.hair_distance
    farther = np.where(rng.random(h.n_strands) < 0.3, rng.uniform(0.5, 3.0, h.n_strands) * hd, 0.0)
    touching = farther > 0
    for cap in (0, 2):
        settings = dataclasses.replace(SETTINGS, layer=False, wisp=False, max_hair_per_element=cap)
        some, _ = detect_contacts(h, plane(), settings, touching=touching, farther=farther)
        wide = dataclasses.replace(settings, max_hair_per_element=0, hair_distance=hd + 2 * farther.max())
        every, _ = detect_contacts(h, plane(), wide, touching=touching)
        hair = some.strand[:, 1] >= 0
        assert np.array_equal(some.subset(~hair).s, every.subset(every.strand[:, 1] < 0).s)  # body as before
        pairs = every.strand[:, 1] >= 0
        within = pairs & (every.gap < hd + farther[every.strand[:, 0]] + farther[np.maximum(every.strand[:, 1], 0)])
        expected = every.subset(within)
        assert 10 < expected.n_contacts < np.count_nonzero(pairs)
        if cap:  # the greedy, closest first, while both elements hold fewer than the cap
            held, keep = np.zeros(h.n_elements, int), np.zeros(expected.n_contacts, bool)
            for k in np.argsort(expected.gap, kind="stable"):
                a, b = expected.element[k]
                if held[a] < cap and held[b] < cap:
                    held[a] += 1
                    held[b] += 1
                    keep[k] = True
            assert not keep.all()
            expected = expected.subset(keep)
        for name in ("strand", "element", "s", "gap", "point"):
            np.testing.assert_allclose(getattr(some.subset(hair), name), getattr(expected, name), rtol=0, atol=1e-12)
        same = np.full(h.n_strands, 0.7 * hd)
        one, _ = detect_contacts(h, plane(), settings, farther=same)
        at, _ = detect_contacts(h, plane(), dataclasses.replace(settings, hair_distance=hd + 2 * 0.7 * hd))
        for name in ("strand", "element", "s", "gap", "point"):
            np.testing.assert_allclose(getattr(one, name), getattr(at, name), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="wisp"):
        detect_contacts(h, plane(), SETTINGS, up=np.array([0.0, 1.0, 0.0]), farther=farther)


def test_a_strand_searched_thousands_of_times_farther_than_the_others_coarsens_the_grid():
    """One strand's pairs searched 0.5 m farther (a strand whipped through a step), the others' at 1 mm: its boxes
    would enter millions of cells of a grid sized for the others' (``CELL_ENTRIES``). The grid is coarsened
    instead, and the pairs are those of a search of every pair to that reach, filtered pair by pair."""
    h = dense_head(2, guides=6, follow=6)
    hd = SETTINGS.hair_distance
    farther = np.zeros(h.n_strands)
    farther[3] = 0.5
    settings = dataclasses.replace(SETTINGS, layer=False, wisp=False, max_hair_per_element=0)
    some, _ = detect_contacts(h, plane(), settings, farther=farther)
    every, _ = detect_contacts(h, plane(), dataclasses.replace(settings, hair_distance=hd + 1.0))
    pairs = every.strand[:, 1] >= 0
    expected = every.subset(pairs & (every.gap < hd + farther[every.strand[:, 0]]
                                     + farther[np.maximum(every.strand[:, 1], 0)]))
    partners = set(expected.strand[np.any(expected.strand == 3, axis=1)].ravel().tolist()) - {3}
    assert partners == set(range(h.n_strands)) - {3}  # strand 3 meets every other strand within 0.5 m
    hair = some.strand[:, 1] >= 0
    for name in ("strand", "element", "s", "gap"):
        np.testing.assert_allclose(getattr(some.subset(hair), name), getattr(expected, name), rtol=0, atol=1e-12)


@pytest.mark.parametrize("cap", [1, 8, 40])
def test_a_simulation_searches_narrowly_first_where_half_the_elements_held_the_cap(cap):
    """A simulation's detection (``ContactTracker.detect``) takes the narrow first search where at least half
    the elements held ``max_hair_per_element`` hair-hair contacts at its last detection, counted here from the
    contacts themselves; either way the contacts are the same (the test above)."""
    from conftest import material

    from hairinv.config import DynamicsSettings
    from hairinv.dynamics.simulate import Simulation

    h = dense_head(3)
    settings = dataclasses.replace(SETTINGS, layer=False, wisp=False, max_hair_per_element=cap)
    found, _ = detect_contacts(h, None, settings)
    held = np.zeros(h.n_elements, dtype=np.int64)
    for pair in found.element[found.strand[:, 1] >= 0]:
        held[pair] += 1
    share = np.mean(held >= cap)
    sim = Simulation(h, h.omega.copy(), material(), None, settings, DynamicsSettings(), initial=found)
    assert sim.tracker.last_found is not None  # the starting contacts are its last detection
    assert sim.tracker._narrow_pays() == (share >= 0.5)
    if cap == 1:
        assert share >= 0.5  # (both answers are met in these cases)
    if cap == 40:
        assert share < 0.5

def nearly_parallel(offset):
    """Three strands where segment_closest's parallel shortcut overstates a polyline gap: A, one 7 cm element
    nearly straight, ends beside a straight strand B tilted 0.9e-7 rad towards A's end (the polylines' gap
    is taken at A's last chord's start, 1e-9 m above the centre lines' own distance at A's end, just below
    the narrow reach); C crosses A a little farther out than A's end lies from B."""
    from hairinv.contacts import detect as detect_module
    from hairinv.contacts._curve import point_tangent

    kappa, L, theta, h = 1e-5, 0.07, 0.9e-7, 0.01
    r = detect_module.NARROW * SETTINGS.hair_distance
    A = (np.asarray(offset, float), frame_with_tangent([1.0, 0, 0], n2=[0, 0, 1.0]), [[kappa, 0, 0]], [L])
    xs, Fs, _, sA = (a[0] for a in sampled(helices([A]))[:4])
    scratch = [np.empty((3, 3)), np.empty(3), np.empty(3)]

    def at(s):
        x, t = np.empty(3), np.empty(3)
        point_tangent(xs, Fs, np.array([kappa, 0, 0.0]), s, *scratch, x, t)
        return x, t

    chord = (sA[7] - sA[6]) / np.linalg.norm(sA[7] - sA[6])
    z = np.cross(at(0.0)[1], at(L)[1])
    z /= np.linalg.norm(z)
    away = np.cross(z, chord)
    away *= -np.sign(np.dot(away, at(L)[1] - at(0.0)[1]))  # B on the convex side
    rounding = 64 * np.finfo(float).eps * (np.abs(sA).max() + 1.0) + 1e-12 * r
    apart = r + kappa * h * h / 8 + rounding + h * theta / 8
    along_b = np.cos(theta) * chord - np.sin(theta) * away
    root_b = sA[6] + apart * away + 0.5 * h * along_b - 0.245 * along_b
    x, t = at(5.5 * h)
    inward = -np.cross(z, t) * np.sign(np.dot(np.cross(z, t), away))
    return helices([A, (root_b, frame_with_tangent(along_b), [[0, 0, 0.0]], [0.7]),
                    (x + (r - 2e-10) * inward - 0.005 * z, frame_with_tangent(z), [[0, 0, 0.0]], [0.01])])


@pytest.mark.parametrize("offset", [(0.0, 0.1, 0.0), (100.0, 100.0, 100.0)])
def test_nearly_parallel_segments_hide_no_pair(monkeypatch, offset):
    """Where the polyline gap of nearly parallel segments overstates the distance, the search still finds the
    pair and its lower bound still holds: the narrow search and the lazy cap keep what searching and
    refining every pair keeps (A's contact with B, the closer, not with C)."""
    import functools

    from hairinv.contacts import detect as detect_module

    h = nearly_parallel(offset)
    candidates = detect_module._hair_candidates
    out = []
    for clearance in (0.05, 0.0):
        settings = dataclasses.replace(SETTINGS, layer=False, body=False, max_hair_per_element=1,
                                       root_clearance=clearance)
        for variant in ({}, {"narrow": False}, {"lazy": False}):
            lazy = {k: v for k, v in variant.items() if k != "narrow"}
            monkeypatch.setattr(detect_module, "_hair_candidates", functools.partial(candidates, **lazy))
            out.append(detect_contacts(h, None, settings, narrow=variant.get("narrow", True)))
        for contacts, report in out[-2:]:
            assert_same_detection(*out[-3], contacts, report)
        assert out[-1][0].element.tolist() == [[0, 1]]


@pytest.mark.parametrize("seed, cap, window", [(0, 1, None), (1, 2, None), (2, 4, None), (0, 1, 7), (2, 4, 64)])
def test_the_lazy_cap_is_the_greedy_by_distance_for_any_valid_lower_bounds(seed, cap, window, monkeypatch):
    """The greedy of the cap against its definition (pairs by distance, ties to the lower index, kept while both
    elements hold fewer than the cap), with a random part of the pairs refined beforehand and random lower bounds
    (anything at most the distance) for the others: the order of refinement must not matter. With a small window
    of pending pairs refined ahead, the greedy stops and resumes many times: the same answer."""
    from hairinv.contacts import detect as detect_module

    if window is not None:
        monkeypatch.setattr(detect_module, "_CAP_WINDOW", window)
    h = dense_head(seed)
    rng = np.random.default_rng(seed)
    E = h.n_elements
    xs, Fs, s0, samples, omega, length, strand_of, is_last = sampled(h)
    hd = 1e-3
    fresh = detect_module._found_pairs(samples, omega, length, strand_of, hd)
    full = fresh.copy()
    detect_module._refine(full, np.ones(len(full.ea), bool), xs, Fs, omega, length)
    candidate = detect_module._kept(full.ea, full.eb, full.sa, full.sb, full.dist, hd, length, is_last)
    # the definition
    expected = np.zeros(len(full.ea), bool)
    held = np.zeros(E, int)
    for k in sorted(np.flatnonzero(candidate), key=lambda k: (full.dist[k], k)):
        if held[full.ea[k]] < cap and held[full.eb[k]] < cap:
            held[full.ea[k]] += 1
            held[full.eb[k]] += 1
            expected[k] = True
    assert 0 < expected.sum() < candidate.sum()
    for trial in range(4):
        pairs = fresh.copy()
        detect_module._refine(pairs, rng.random(len(pairs.ea)) < 0.3 * trial, xs, Fs, omega, length)
        pairs.low = full.dist * rng.uniform(0.0, 1.0, len(full.ea)) ** (trial + 1)
        if trial == 3:  # bounds equal to the distances: a refined pair and a pending one at the same distance
            pairs.low = np.where(rng.random(len(full.ea)) < 0.5, full.dist, pairs.low)
        known = np.flatnonzero(pairs.refined & candidate)
        known = known[np.argsort(pairs.dist[known], kind="stable")]
        pending = np.flatnonzero(~pairs.refined)
        pending = pending[np.argsort(pairs.low[pending])]
        out = np.zeros(len(pairs.ea), bool)
        dropped, unmeasured = detect_module._cap_pairs(
            pairs.ea, pairs.eb, pairs.sa, pairs.sb, pairs.dist, pairs.refined, known, pending, pairs.low, cap, E, hd,
            s0, length, is_last, 0.0, xs, Fs, omega, out)
        np.testing.assert_array_equal(out, expected)
        done = pairs.refined
        assert unmeasured == np.count_nonzero(~done) > 0
        assert dropped == np.count_nonzero(candidate & done & ~expected)
        np.testing.assert_array_equal(pairs.dist[done], full.dist[done])


def test_a_groom_of_dense_strands_is_searched_only_to_hair_distance(monkeypatch):
    """No second search to hair_max_distance: every strand is dense. (The first search may go to a fraction of
    hair_distance before it, for the cap.)"""
    from hairinv.contacts import detect as detect_module

    reaches = []
    real = detect_module.hair_pairs

    def spy(samples, omega, length, strand_of, reach, wide=None):
        reaches.append(reach)
        return real(samples, omega, length, strand_of, reach, wide)

    monkeypatch.setattr(detect_module, "hair_pairs", spy)
    h = bundle_and_guides()
    dense = helices([(h.root[i], h.frame0[i], h.omega[6 * i:6 * i + 6], h.length[6 * i:6 * i + 6]) for i in range(20)])
    _, report = detect_contacts(dense, plane(), dataclasses.replace(SETTINGS, layer=False), up=np.array([0, 1.0, 0]))
    # each search goes a margin past its reach (rounding, nearly parallel segments: under 1e-5 of it here)
    hd = SETTINGS.hair_distance
    assert len(reaches) in (1, 2)
    assert np.all(hd <= reaches[-1]) and np.all(reaches[-1] <= hd * (1 + 1e-5))
    if len(reaches) == 2:
        narrow = detect_module.NARROW * hd
        assert np.all(narrow <= reaches[0]) and np.all(reaches[0] <= narrow + 1e-5 * hd)
    assert np.all(report.wisp_radius == SETTINGS.hair_distance)


def _median_by_strand(nearest, strand_of, count, settings):
    """The wisp radii by their definition: numpy's median of each strand's finite nearest distances."""
    radius = np.full(count, settings.hair_distance)
    for k in range(count):
        values = nearest[(strand_of == k) & np.isfinite(nearest)]
        if len(values):
            radius[k] = np.median(values)
    return np.clip(1.25 * radius, settings.hair_distance, settings.hair_max_distance)


def test_wisp_radius_is_the_median_of_each_strands_nearest_distances():
    from hairinv.contacts.detect import _wisp_radius

    rng = np.random.default_rng(3)
    strand_of = np.repeat(np.arange(40), rng.integers(1, 9, 40))
    E = len(strand_of)
    ea = rng.integers(0, E, 300)
    eb = rng.integers(0, E, 300)
    dist = rng.uniform(0.0, 0.003, 300)
    nearest = np.full(E, np.inf)
    np.minimum.at(nearest, ea, dist)
    np.minimum.at(nearest, eb, dist)
    np.testing.assert_array_equal(_wisp_radius(ea, eb, dist, strand_of, 41, SETTINGS),
                                  _median_by_strand(nearest, strand_of, 41, SETTINGS))


def _layer_by_the_rule(has, sd, sigma, least, samples, s0, length, offsets, mesh, settings):
    """The layer rule read directly (docs of ``_layer_elements``), strand by strand and run by run with numpy."""
    E, n = samples.shape[0], samples.shape[1]
    has = has.astype(bool)
    out = np.zeros(E, dtype=bool)
    gaps = []
    near = np.flatnonzero(np.minimum(np.where(has, sd, np.inf), least) <= settings.layer_max_gap)
    if not len(near):
        return out, np.zeros(0)
    dist = mesh.closest(np.ascontiguousarray(samples[near].reshape(-1, 3)))[0].reshape(-1, n)
    arc = s0[near, None] + length[near, None] * np.minimum(np.arange(n) / (n - 1), 1.0)[None, :]
    strand_of = np.searchsorted(offsets, near, side="right") - 1
    for k in np.unique(strand_of):
        mine = strand_of == k
        els, d, s = near[mine], dist[mine].ravel(), arc[mine].ravel()
        owner = np.repeat(els, n)
        valid = (s >= settings.root_clearance) & (d <= settings.layer_max_gap)
        run = np.cumsum(~valid | np.r_[False, np.diff(owner) > 1])
        for r in np.unique(run[valid]):
            members = valid & (run == r)
            gap = float(np.median(np.maximum(d[members], 0.0)))
            idx = np.flatnonzero(members)
            in_band = d[idx] <= gap + settings.layer_tolerance
            stretch = np.cumsum(np.r_[True, in_band[1:] != in_band[:-1]])
            declared = False
            for t in np.unique(stretch[in_band]):
                sel = idx[in_band & (stretch == t)]
                lo, hi = s[sel].min(), s[sel].max()
                if hi - lo < settings.layer_min_length:
                    continue
                for e in np.unique(owner[sel]):
                    step = length[e] / (n - 1)
                    if (has[e] and settings.body_distance <= sd[e] <= gap + settings.layer_tolerance
                            and lo - step <= s0[e] + sigma[e] <= hi + step):
                        out[e] = declared = True
            if declared:
                gaps.append(gap)
    return out, np.asarray(gaps)


@pytest.mark.parametrize("name", ["wavy.h5", "settled.h5"])
def test_the_layer_rule_kernel_declares_what_the_rule_says(monkeypatch, name):
    """The compiled layer rule against a direct numpy reading of it, on the inputs detection gives it for
    a sample groom on the sample bust (hundreds of runs, some broken by gaps between near elements)."""
    from hairinv.contacts import detect as detect_module

    calls = []
    real = detect_module._layer_elements

    def spy(*args):
        out = real(*args)
        calls.append((args, out))
        return out

    monkeypatch.setattr(detect_module, "_layer_elements", spy)
    groom, _ = load_groom(SAMPLES / name, ImportSettings())
    h, _ = fit_groom(groom, FitSettings())
    body = load_body(SAMPLES / "body.obj", hair_unit_transform(groom.scale_to_m))
    detect_contacts(h, body, SETTINGS, up=groom.up)
    (args, (out, gaps)), = calls
    expected, expected_gaps = _layer_by_the_rule(*args)
    assert out.sum() > 10 and len(gaps) > 10
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(gaps, expected_gaps)


def test_body_distances_of_many_points_are_the_boxs_signed_distance():
    """``BodyMesh.closest`` on thousands of points (queried in chunks on the worker threads) against the
    closed form of a box: outside, the distance to the box; inside, minus the distance to the nearest face;
    the closest point on the surface at that distance."""
    half = np.array([0.1, 0.05, 0.15])
    body = BodyMesh.from_mesh(trimesh.creation.box(extents=2 * half))
    points = np.random.default_rng(3).uniform(-0.3, 0.3, size=(5003, 3))  # not a whole number of chunks
    q = np.abs(points) - half
    expected = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    sd, closest, normal, face = body.closest(points)
    np.testing.assert_allclose(sd, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(points - closest, axis=1), np.abs(expected), rtol=0, atol=1e-12)
    assert np.all(np.abs(closest) <= half + 1e-12) and np.all(face >= 0)
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, rtol=0, atol=1e-12)
