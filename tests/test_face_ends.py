"""Where a face ends at a convex edge (issue 18): the face's last echoes and its edge's
diffraction arrive together, and with the uniform theory's diffraction (half a mirror's
echo on the reflection boundary) the mapping must still end the face at its edge."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from clsonar.mapping.heard import amplitude_noise
from clsonar.mapping.joins import OWN_ECHOES_M, cut_at_vertices, meet
from clsonar.mapping.patches import Patch, carrier_points, coordinates
from clsonar.opencl import get_context
from clsonar.pipeline import run
from clsonar.scene import DetectionSettings, Scene, Signal
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


def _patch(params: tuple[float, float, float], u: np.ndarray, hi: float) -> Patch:
    """A patch of the curve model ``params`` about the origin with reflection points at
    coordinates ``u``, drawn from the first to ``hi``."""
    k = len(u)
    zeros = np.zeros((k, 2))
    return Patch(np.asarray(params, float), np.zeros(2), u, float(u.min()), hi,
                 np.arange(k), math.inf, np.zeros(k, np.int64), np.zeros(k, np.int64),
                 zeros, zeros, np.ones(k))


def test_a_located_edge_on_a_curved_patch_ends_it_where_it_ran_past():
    """A face's last stretch, its echoes shifted by the edge's diffraction arriving with
    them, may be fitted by a slightly bent circle that runs on past the edge: a located
    vertex on the circle beyond the reflection points cuts it there (as one on a plane's
    line does), but neither extends the circle to a vertex nor cuts inside its points,
    nor cuts a circle more bent than its range (a curved wall's own)."""
    params = (math.pi / 2, 0.0, -0.05)  # a circle of radius 20 m touching y = 0 at x = 0
    u = np.linspace(-0.02, -0.001, 8)
    curved = _patch(params, u, hi=0.02)
    vertex = carrier_points(curved.params, curved.x0, np.array([0.005]))
    (cut,), _ = meet([curved], vertex + np.array([0.0, 0.004]))  # 4 mm off the circle: on it
    assert cut.hi == pytest.approx(float(coordinates(cut.params, cut.x0, vertex)[0]),
                                   abs=1e-4)
    assert cut.lo == curved.lo
    (kept,), _ = meet([curved], carrier_points(curved.params, curved.x0,
                                               np.array([-0.01])))  # among its points
    assert kept.hi == curved.hi
    short = _patch(params, u, hi=float(u.max()))
    (same,), _ = meet([short], vertex)  # never extended along a circle
    assert same.hi == short.hi
    (far,), _ = meet([curved], vertex + np.array([0.0, 0.05]))  # 5 cm off: another reflector's
    assert far.hi == curved.hi
    # a curved wall's own circle (radius 0.5 m seen from 2 m) runs on past a located
    # crest: it is no face's slightly bent end
    wall = replace(_patch((math.pi / 2, 0.0, -2.0), u, hi=0.02), paths=np.full(8, 4.0))
    crest = carrier_points(wall.params, wall.x0, np.array([0.005]))
    (kept_on,), _ = meet([wall], crest)
    assert kept_on.hi == wall.hi


def test_a_located_edge_at_a_face_s_last_reflection_point_ends_the_stretch_past_it():
    """A face's last echoes may be its edge's own (their reflection points on the edge): a
    located vertex on the line within ``OWN_ECHOES_M`` of the last reflection point cuts
    the stretch drawn beyond it, found before the faces met or after; one among the middle
    of its points, or farther inside (a noisy edge's), cuts nothing."""
    u = np.linspace(-0.5, 0.2, 15)
    face = _patch((math.pi / 2, 0.0, 0.0), u, hi=0.35)  # the line y = 0, points to x = 0.2
    at = carrier_points(face.params, face.x0, np.array([0.195]))
    (cut,) = cut_at_vertices([face], at + np.array([0.0, 0.005]), OWN_ECHOES_M)
    assert cut.hi == pytest.approx(0.195) and cut.lo == face.lo
    for u_vertex, inside in ((0.195, 0.0), (0.185, OWN_ECHOES_M), (-0.15, 1.0)):
        vertex = carrier_points(face.params, face.x0, np.array([u_vertex]))
        (kept,) = cut_at_vertices([face], vertex, inside)
        assert (kept.lo, kept.hi) == (face.lo, face.hi), u_vertex


@pytest.mark.parametrize("seed, index", [(127, 4), (136, 1)])
def test_a_face_is_not_drawn_past_its_located_edge(seed, index):
    """The zoo's unseen seeds 127 and 136 edge arrays, noise-free: a circle fitted to a
    face's last echoes near its edge ran 17 cm past the edge a diffraction located after
    the faces met (127), and one fitted to a face's and its edge's echoes ran 12 cm past
    it (136): 3.8 and 2.9 cm RMS. Both end at the edge now."""
    case = draw(seed, "edge", index)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"] and row["accuracy_m"] < 0.005


def test_a_detection_s_amplitude_noise_is_the_envelope_s():
    """The amplitude a plane's echo must reach is a mirror's share less three σ of the
    detection's amplitude: the envelope's noise (0.145·σn, docs/detection.md), not the
    signal's σn, which let an edge's diffraction (half a mirror's) pass for a face's
    echo at σn 0.3."""
    def scene(noise: float, mode: str = "envelope") -> Scene:
        return Scene(name="noise", extent=(0.0, 0.0, 1.0, 1.0), signal=Signal(noise_std=noise),
                     detection=DetectionSettings(mode=mode))

    assert amplitude_noise(scene(0.0)) == 0.0
    assert amplitude_noise(scene(1.0)) == pytest.approx(0.145, abs=0.005)
    assert amplitude_noise(scene(0.6)) == pytest.approx(0.6 * amplitude_noise(scene(1.0)))
    assert amplitude_noise(scene(0.6, "threshold")) == 0.6


def _wall_run(top: float, arrays: list[tuple[float, int, float]]) -> np.ndarray:
    """The profile of a run, with the defaults, of a wall along x = 8 from y = 0 to
    ``top`` seen by arrays facing it from x = 5: (centre y, elements, pitch) each, one
    group each."""
    from clsonar.opencl import get_context
    from clsonar.pipeline import run
    from clsonar.scene import scene_from_dict

    transducers = [{"position": [5.0, float(y0 + (k - (n - 1) / 2) * pitch)],
                    "heading_deg": 0.0, "group": g}
                   for g, (y0, n, pitch) in enumerate(arrays) for k in range(n)]
    scene = scene_from_dict({"clsonar": 1, "name": "free-end", "extent": [4, -1, 9, 5],
                             "cell": 0.01,
                             "surfaces": [{"type": "polyline", "points": [[8, 0], [8, top]]}],
                             "sensors": {"transducers": transducers}}, "free-end")
    return np.asarray(run(scene, context=get_context(None)).profile.points).reshape(-1, 2)


def test_another_array_s_silence_ends_a_wall_past_its_free_end():
    """A wall that ends 0.125 m past an array's last reflection point, within the region
    of constant depth of its echoes (0.235 m at 3 m): alone, the array cannot tell, and
    the wall is drawn past its end; a second array whose pairs would hear the wall just
    past its end, and hear nothing, ends it between the first array's last reflection
    point and its own first (patches.clamp_to_silence: every group's pairs, for a
    plane, over the span drawn)."""
    top = 2.85
    alone = _wall_run(top, [(2.5, 10, 0.05)])
    assert alone[:, 1].max() > top + 0.05  # the end of the region: past the wall
    both = _wall_run(top, [(2.5, 10, 0.05), (3.1, 10, 0.05)])
    assert len(both) and both[:, 1].max() <= top + 1e-3
    assert np.abs(both[:, 0] - 8.0).max() < 1e-3


def test_a_wall_ends_halfway_between_its_last_echo_and_the_first_silent_pair():
    """A 16-element array of 9 cm pitch whose pairs' reflection points lie 4.5 cm apart
    along a wall that ends 2 cm past one of them: the wall is drawn to halfway to the
    next (silent) pair's, 2.25 cm past the last echo's reflection point, not stopped at
    it (off by up to half the gap instead of all of it)."""
    top = 3.02
    pts = _wall_run(top, [(3.0, 16, 0.09)])
    end = float(pts[:, 1].max())
    assert abs(end - top) < 0.005 and end > 3.0 + 0.01


@pytest.mark.parametrize("top,array", [(2.9, (2.9, 16, 0.05)), (3.0, (2.9, 10, 0.1)),
                                       (2.95, (2.9, 20, 0.03))])
def test_a_wall_ending_inside_the_map_is_drawn_to_its_end(top, array):
    """A thin wall's end inside the map is a knife edge (geometry.free_ends) that
    diffracts: the pairs whose reflection points would lie past it hear half a mirror's
    echo on its reflection boundary and less beyond, so the wall is drawn to its end
    within 5 mm. Without that diffraction (an end that gave no echo) these walls were drawn
    0.4-2.4 cm past their ends, to halfway to the first silent pair."""
    pts = _wall_run(top, [array])
    assert abs(float(pts[:, 1].max()) - top) < 0.005
    assert np.abs(pts[:, 0] - 8.0).max() < 1e-3


def test_face_and_edge_sum_to_half_a_face_s_echo_on_its_reflection_boundary():
    """With faces that reflect ρ of the sound, the uniform theory's reflection-boundary
    terms carry ρ (physics.edge_diffraction, Luebbers 1984): on a face's reflection
    boundary the face's echo ρ and the edge's diffraction sum to ρ/2 from the lit side, and
    the diffraction alone is ρ/2 on the shadow side — half the face's echo either way, as
    patches._end ends a face (strength.EDGE_SHARE of the walls' mirror echo). With the
    rigid coefficient the shadow side read 1/2 of a rigid mirror, 0.56 of the walls' echo
    at ρ 0.9, and the zoo's seed 2 corner-06 drew a thin wall 6 cm past its end."""
    from clsonar import physics

    k = physics.wavenumber(50e3, 343.0)
    n = np.full(2, 1.5)
    phi = np.array([0.5 * math.pi - 1e-7, 0.5 * math.pi + 1e-7])  # face a's boundary
    for rho in (1.0, 0.9, 0.5):
        g = physics.edge_diffraction(2.0, 2.0, phi, phi, n, k, 1.0, rho)
        assert abs(rho + g[0]) == pytest.approx(rho / 2, rel=0.02)  # lit: face + edge
        assert abs(g[1]) == pytest.approx(rho / 2, rel=0.02)  # shadow: the edge alone
    far = np.array([0.75 * math.pi])  # the bisector, far from both boundaries
    assert abs(physics.edge_diffraction(2.0, 2.0, far, far, n[:1], k, 1.0, 0.9)[0]) \
        < abs(physics.edge_diffraction(2.0, 2.0, far, far, n[:1], k, 1.0, 1.0)[0])


def test_a_face_ends_where_its_echo_falls_to_half_a_mirror_s():
    """patches._end: past a face's last echo the pairs' echoes at its path, over a
    mirror's, fall to a half on its edge (the uniform theory): the face ends where they
    cross a half, linearly between the pairs either side; with nothing heard there (a
    free end, an edge model without that diffraction) a plane ends halfway to the first
    silent pair and a circle at its last echo; a patch whose curvature is unknown at its
    last echo; and one no pair beyond was silent for not at all."""
    from clsonar.mapping.patches import _end

    along = np.array([-0.05, 0.0, 0.04, 0.08])
    loud = np.array([True, True, False, False])
    edge = np.array([1.0, 0.9, 0.3, 0.0])
    assert _end(along, edge, loud, True, True) == pytest.approx(0.04 * 0.4 / 0.6)
    free = np.array([1.0, 1.0, 0.0, 0.0])
    assert _end(along, free, loud, True, True) == pytest.approx(0.02)
    assert _end(along, free, loud, True, False) == 0.0
    assert _end(along, edge, loud, False, True) == 0.0
    assert _end(along, edge, np.ones(4, dtype=bool), True, True) == math.inf
    fresnel = np.array([1.0, 0.9, 0.55, 0.2])  # weak but above a half: still the face
    assert _end(along, fresnel, loud, True, True) == pytest.approx(0.04 + 0.04 / 7)


def test_another_array_s_echoes_of_a_located_face_draw_no_tangent_points():
    """Zoo seed 5, edge-03 (random lines at a 95° edge, scenes nobody tuned on): three of
    the face's last echoes, heard by lines that found no family of their own and moved by
    the edge's diffraction arriving with them, were left to the tangent map, whose arcs'
    middles drew a stub 17 cm past the edge (accuracy 1.7 cm): a face that ends at a
    located vertex does not go on past it (``reflectors.past_located_ends``)."""
    from clsonar import pipeline
    from clsonar.opencl import get_context
    from clsonar.tools.zoo import zoo
    from clsonar.tools.zoo.score import score

    (case,) = [c for c in zoo(5) if c.name == "edge-03-random-lines"]
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.002
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.002


def test_no_tangent_point_continues_a_face_past_its_located_end():
    """``past_located_ends``: points within 0.5 m beyond a patch's end that a located
    vertex marks, close to the patch's line (1 cm plus a tenth of the distance), go;
    points before the end, off the line, past an end no vertex marks, or with no patch
    drawn at all, stay."""
    from clsonar.mapping.patches import Patches
    from clsonar.mapping.reflectors import past_located_ends

    face = np.column_stack([np.linspace(0.0, 1.0, 51), np.zeros(51)])  # (0,0) to (1,0)
    drawn = Patches(face, np.zeros(51, np.int64), np.array([[1.005, 0.0]]), np.array([51]))
    points = np.array([[1.1, 0.005], [1.3, 0.035], [1.3, 0.06], [0.9, 0.0], [-0.1, 0.0],
                       [1.6, 0.0]])
    assert past_located_ends(points, drawn).tolist() == [True, True, False, False, False,
                                                        False]
    no_patch = Patches(np.zeros((0, 2)), np.zeros(0, np.int64), np.array([[1.0, 0.0]]),
                       np.zeros(0, np.int64))
    assert not past_located_ends(points, no_patch).any()


def _face_and_pair(r: float, sep: float, s: float) -> tuple[np.ndarray, ...]:
    """A pair (T, R) ``sep`` apart at range ``r`` in front of a face along y = 0 whose
    reflection point is the origin, the face ending at ``s`` along −x (its outward
    tangent): ``(T, R, q, t, E)``."""
    t = np.array([-1.0, 0.0])
    q = np.zeros((1, 2))
    return (np.array([[-sep / 2, -r]]), np.array([[sep / 2, -r]]), q, t, q + s * t)


@settings(max_examples=60, deadline=None)
@given(r=st.floats(0.5, 9.0), sep=st.floats(0.0, 0.6), s=st.floats(0.0, 0.3),
       wedge=st.floats(math.radians(11), math.radians(150)))
def test_a_face_s_echo_near_its_edge_is_any_wedge_s_within_5_percent(r, sep, s, wedge):
    """strength.face_end_echo, a half-plane's end, against physics.edge_diffraction of
    a solid wedge of any angle behind the face: the face's specular echo and its edge's
    diffraction, (d1 + d2) − the mirror path later, together over a mirror's, within 5 %."""
    from clsonar import physics
    from clsonar.mapping.strength import face_end_echo

    k = physics.wavenumber(50e3, 343.0)
    T, R, _, t, E = _face_and_pair(r, sep, s)
    half_plane = face_end_echo(T, R, E, t, k, 1.0)[0]
    va, vb = np.array([[1.0, 0.0]]), np.array([[math.cos(wedge), math.sin(wedge)]])
    d1, d2 = np.hypot(*(E - T).T), np.hypot(*(E - R).T)
    phi_t, n = physics.wedge_angles(T, E, va, vb)
    phi_r, _ = physics.wedge_angles(R, E, va, vb)
    detour = float((d1 + d2)[0]) - math.sqrt(4.0 * r * r + sep * sep)
    g = physics.edge_diffraction(d1, d2, phi_t, phi_r, n, k, 1.0, 1.0)[0]
    assert half_plane == pytest.approx(abs(1.0 + g * np.exp(-1j * k * detour)), rel=0.05)


def test_a_face_s_echo_rises_from_half_a_mirror_s_on_its_edge():
    """strength.face_end_echo: half a mirror's with the reflection point on the edge,
    rising steadily to the knife edge's first Fresnel maximum, 1.17–1.19 of a mirror's,
    4–15 cm inside at 0.5–9 m; and as clsonar's echoes and detection give it near the
    edge (a wall's free end seen square-on from 1.5 m by one element, its reflection
    point up to 3.5 cm from the end: within 0.005 of a mirror's; at 6 cm, where the
    diffraction arrives 2.4 mm later, 1.155 for 1.178)."""
    from clsonar import physics, pipeline
    from clsonar.mapping.strength import face_end_echo, mirror_echo
    from clsonar.opencl import get_context
    from clsonar.scene import scene_from_dict

    k = physics.wavenumber(50e3, 343.0)
    s = np.linspace(0.0, 0.3, 3001)
    for r, top in ((0.5, 0.04), (1.0, 0.06), (3.0, 0.1), (9.0, 0.16)):
        T, R, q, t, _ = _face_and_pair(r, 0.2, 0.0)
        echo = face_end_echo(np.repeat(T, len(s), 0), np.repeat(R, len(s), 0),
                             q + s[:, None] * t, t, k, 1.0)
        peak = int(np.argmax(np.diff(echo) < 0))  # the first maximum
        assert echo[0] == pytest.approx(0.5, abs=0.01)
        assert np.all(np.diff(echo[:peak + 1]) > 0) and 1.17 <= echo[peak] <= 1.19
        assert 0.6 * top <= s[peak] <= top
    for offset in (0.0, 0.015, 0.035):
        scene = scene_from_dict({
            "clsonar": 1, "name": "end", "extent": [-0.5, -1.0, 2.0, 3.5], "cell": 0.01,
            "surfaces": [{"type": "polyline", "points": [[0.0, 3.0], [0.0, 0.0]]}],
            "sensors": {"transducers": [{"position": [1.5, offset], "heading_deg": 180.0,
                                         "group": 0}]}}, "end")
        heard = pipeline.run(scene, context=get_context()).detections.amplitude
        T = np.array([[1.5, offset]])
        face = face_end_echo(T, T, np.zeros((1, 2)), np.array([0.0, -1.0]),
                             physics.wavenumber(scene.transducer.frequency_hz, scene.medium.c),
                             scene.echo.reflection_coefficient)
        assert heard.max() / mirror_echo(scene) == pytest.approx(face[0], abs=0.005)


@settings(max_examples=60, deadline=None)
@given(r=st.floats(0.5, 9.0), sep=st.floats(0.0, 0.6), s=st.floats(0.0, 0.3),
       rho=st.floats(0.5, 1.0))
def test_edge_distance_finds_the_edge_whose_echo_the_pair_heard(r, sep, s, rho):
    """strength.edge_distance inverts face_end_echo: the edge it puts beyond the pair's
    reflection point gives the pair the echo it heard (to 10⁻⁵ of a mirror's); 0 for an
    echo at most the edge's own, the reach for one stronger than the face gives there."""
    from clsonar import physics
    from clsonar.mapping.strength import edge_distance, face_end_echo

    k = physics.wavenumber(50e3, 343.0)
    T, R, q, t, E = _face_and_pair(r, sep, s)
    heard = face_end_echo(T, R, E, t, k, rho)
    # on the rising stretch that a weak echo reads (its top, 1.17-1.18, may lie between
    # the grid's steps, and the mapping inverts echoes under 0.9 of a face's)
    assume(float(heard[0]) < 1.1)
    found = edge_distance(heard, T, R, q, t, k, rho, 1.0)
    assert face_end_echo(T, R, q + found[:, None] * t, t, k, rho) == pytest.approx(heard,
                                                                                  abs=1e-5)
    assert edge_distance(np.array([0.3]), T, R, q, t, k, rho, 1.0)[0] == 0.0
    assert edge_distance(np.array([1.3]), T, R, q, t, k, rho, 1.0)[0] == 1.0


def test_a_face_every_pair_beyond_heard_fading_ends_where_its_echo_says():
    """patches._fading_end: no pair beyond a face's last echo was silent, but the farthest
    heard it weak (falling towards half a mirror's): the face ends where a face ending
    there gives the weak pairs' echoes (the median of theirs), no nearer than the
    farthest pair's reflection point; at that point with the edges' estimate model (no
    such fall); not at all (inf) where the farthest pair heard it fully; at the farthest
    pair's reflection point where it heard it raised."""
    from clsonar import physics
    from clsonar.mapping.patches import _fading_end
    from clsonar.mapping.strength import face_end_echo
    from clsonar.scene import EchoModel

    scene = Scene(name="fade", extent=(-1.0, -4.0, 1.0, 1.0), cell=0.01)
    k = physics.wavenumber(scene.transducer.frequency_hz, scene.medium.c)
    along = np.array([-0.02, 0.0, 0.01, 0.02, 0.03])
    T = np.column_stack([along, np.full(5, -3.0)])  # T = R, reflection points at along
    q, t = np.zeros(2), np.array([1.0, 0.0])
    edge = 0.05
    ratio = face_end_echo(T, T, np.tile(q + edge * t, (5, 1)), t, k,
                          scene.echo.reflection_coefficient)
    weak = ratio < 0.85
    none = np.zeros(5, dtype=bool)
    end = _fading_end(scene, q, t, along, ratio, weak, none, T, T, 0.5)
    assert weak[-1] and end == pytest.approx(edge, abs=1e-5)
    estimate = replace(scene, echo=EchoModel(edge_model="estimate"))
    assert _fading_end(estimate, q, t, along, ratio, weak, none, T, T, 0.5) == 0.03
    full = weak.copy()
    full[-1] = False
    assert _fading_end(scene, q, t, along, ratio, full, none, T, T, 0.5) == math.inf
    # the farthest raised instead (the edge's diffraction in phase): the face ends there
    raised = ~full & (np.arange(5) == 4)
    assert _fading_end(scene, q, t, along, ratio, full, raised, T, T, 0.5) == 0.03


def test_a_face_whose_farthest_pair_beyond_heard_it_raised_ends_there():
    """The zoo's unseen seed 172 wall-04 (three arrays, noise-free): beyond a family's last
    reflection point, 6 cm from the wall's free end, its array's pairs heard 0.90, 1.14
    and (the farthest) 1.15 of its echo, none silent, and the face was drawn over its
    region of constant depth 7 cm past the end (0.89 cm RMS). A raised echo is the edge's
    diffraction in phase, a Fresnel zone or so from the edge: the face ends there."""
    from clsonar import pipeline
    from clsonar.opencl import get_context
    from clsonar.tools.zoo.cases import draw
    from clsonar.tools.zoo.score import score

    case = draw(172, "wall", 4)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["passed"] and row["accuracy_m"] <= 0.001


def test_a_noisy_face_whose_last_pairs_heard_it_fading_is_drawn_to_its_edge():
    """The zoo's unseen seed 59 edge-02 (σ 0.3): a face's last two pairs beyond its family
    heard 0.83 and 0.72 of a mirror's echo, none was silent, and the face was drawn over
    its echoes' region of constant depth, 19 cm past the edge (4.7 cm RMS): it now ends
    where its fading echo puts the edge."""
    from clsonar import pipeline
    from clsonar.opencl import get_context
    from clsonar.tools.zoo.cases import draw
    from clsonar.tools.zoo.score import score

    case = draw(59, "edge", 2)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.005
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.01


def test_a_face_seen_by_several_arrays_ends_where_any_of_them_heard_nothing():
    """The zoo's unseen seed 61 edge-02 (σ 0.3): a face seen by three arrays, one of them
    with 20 echoes whose own pairs could not test the face past them, so its region of
    constant depth ran 21 cm past the edge that the other arrays' silent pairs placed;
    joined, the union kept it (4.8 cm RMS). The join is cut again by every pair that
    would hear its surface (joins.silence_clamp)."""
    from clsonar import pipeline
    from clsonar.opencl import get_context
    from clsonar.tools.zoo.cases import draw
    from clsonar.tools.zoo.score import score

    case = draw(61, "edge", 2)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.001
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.005
