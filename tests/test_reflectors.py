"""Reflector-aware mapping (``mapping.mode = "reflectors"``, clsonar/mapping/models.py,
families.py, patches.py, joins.py, reflectors.py): the path models against independent
float64 geometry (mirror images, brute-force specular points, explicit double bounces), the
fits and the plane/point/corner/circle distinction of Kleeman & Kuc (1995) on synthetic
families, and whole runs, with the default settings, on scenes the old defaults failed
(issue 14: a tilted wall, a corner seen at 45°, a cylinder, a sinusoid, two arrays)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.mapping import in_beams, models
from clsonar.mapping.families import Window, find_families
from clsonar.opencl import get_context
from clsonar.pipeline import run
from clsonar.scene import scene_from_dict

finite = functools.partial(st.floats, allow_nan=False, allow_infinity=False)


@functools.cache
def context():
    return get_context()


def _array(n: int, pitch: float, centre=(0.0, 0.0), heading_deg=0.0) -> np.ndarray:
    h = math.radians(heading_deg)
    along = np.array([-math.sin(h), math.cos(h)])
    return np.asarray(centre) + ((np.arange(n) - (n - 1) / 2) * pitch)[:, None] * along


def _pairs(E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    i, j = np.triu_indices(len(E))
    return E[i], E[j]


def _reflect(p: np.ndarray, a: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``p`` mirrored across the line through ``a`` with unit normal ``n``."""
    return p - 2.0 * ((p - a) @ n)[..., None] * n


# --- the path models against independent geometry -------------------------------------


@settings(max_examples=60, deadline=None)
@given(phi=finite(min_value=-0.5, max_value=0.5), d=finite(min_value=0.5, max_value=9.0),
       n=st.integers(2, 12), pitch=finite(min_value=0.01, max_value=0.2))
def test_plane_path_is_the_mirror_image_distance(phi, d, n, pitch):
    T, R = _pairs(_array(n, pitch))
    path, q = models.plane_points(phi, d, T, R)
    normal = np.array([math.cos(phi), math.sin(phi)])
    mirror = _reflect(R, d * normal, normal)
    assert np.allclose(path, np.hypot(*(T - mirror).T), rtol=0, atol=1e-12)
    assert np.allclose(q @ normal, d, atol=1e-12)  # on the plane
    legs = np.hypot(*(T - q).T) + np.hypot(*(R - q).T)
    assert np.allclose(legs, path, atol=1e-12)  # the path goes through q


@settings(max_examples=40, deadline=None)
@given(dist=finite(min_value=1.5, max_value=6.0), radius=finite(min_value=0.05, max_value=3.0),
       lateral=finite(min_value=-0.3, max_value=0.3), n=st.integers(2, 8),
       pitch=finite(min_value=0.02, max_value=0.12), concave=st.booleans())
def test_circle_path_is_the_stationary_path_on_the_circle(dist, radius, lateral, n, pitch,
                                                          concave):
    """The specular path on a circle whose apex is ``dist`` in front of the array — convex:
    the shortest path through its near half; concave (a trough, the array outside it): the
    longest through its far half — against 400 000 points of that half."""
    if concave:
        radius = min(radius, 0.45 * dist)
    T, R = _pairs(_array(n, pitch))
    centre = np.array([dist + (-radius if concave else radius), lateral])
    rho = -radius if concave else radius
    length = float(np.hypot(*centre))
    unit = centre / length
    params = np.array([math.atan2(unit[1], unit[0]), length - rho, 1.0 / length])
    path, q = models.curve_paths(params, np.zeros(2), T, R)
    a = np.linspace(-math.pi, math.pi, 400_001)
    u = np.stack([np.cos(a), np.sin(a)], axis=-1)
    half = u[(u @ unit > 0) if concave else (u @ unit < 0)]
    ring = centre + radius * half
    lengths = (np.hypot(*(T[:, None] - ring[None]).transpose(2, 0, 1))
               + np.hypot(*(R[:, None] - ring[None]).transpose(2, 0, 1)))
    brute = lengths.max(axis=1) if concave else lengths.min(axis=1)
    assert np.allclose(path, brute, atol=2e-9)
    assert np.allclose(np.hypot(*(q - centre).T), radius, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(x=finite(min_value=1.0, max_value=6.0), y=finite(min_value=-0.5, max_value=0.5))
def test_a_circle_of_radius_zero_is_a_point(x, y):
    T, R = _pairs(_array(6, 0.08))
    f = np.array([x, y])
    length = float(np.hypot(x, y))
    params = np.array([math.atan2(y, x), length, 1.0 / length])
    assert np.allclose(models.curve_paths(params, np.zeros(2), T, R)[0],
                       models.point_paths(f, T, R)[0], atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(phi=finite(min_value=-0.4, max_value=0.4), d=finite(min_value=1.0, max_value=8.0))
def test_curve_model_tends_to_the_plane(phi, d):
    T, R = _pairs(_array(8, 0.1))
    plane, _ = models.curve_paths(np.array([phi, d, 0.0]), np.zeros(2), T, R)
    almost, _ = models.curve_paths(np.array([phi, d, 1e-5]), np.zeros(2), T, R)
    assert np.allclose(plane, almost, atol=1e-5)  # a circle of 10⁵ m sags 5 µm over 1 m


@settings(max_examples=60, deadline=None)
@given(dist=finite(min_value=1.0, max_value=9.0), view=finite(min_value=-40.0, max_value=40.0),
       n=st.integers(2, 10), pitch=finite(min_value=0.02, max_value=0.11))
def test_corner_path_is_the_double_bounce(dist, view, n, pitch):
    """The double bounce off a right-angled corner, reflected across one wall and then the
    other (the order does not matter), is |T + R − 2V|."""
    v = np.array([dist, 0.0])
    b = math.radians(view)
    walls = [np.array([math.cos(b + s), math.sin(b + s)]) for s in (math.pi / 4, -math.pi / 4)]
    T, R = _pairs(_array(n, pitch))
    path, q = models.corner_paths(v, T, R)
    image = _reflect(_reflect(R, v, walls[0]), v, walls[1])
    assert np.allclose(path, np.hypot(*(T - image).T), atol=1e-12)
    assert np.allclose(q, v)


# --- fits and the distinction of the reflectors ---------------------------------------


def _window(T, R, paths, axis=(1.0, 0.0), half_beam_deg=12.0) -> Window:
    ax = np.broadcast_to(np.asarray(axis, float), T.shape)
    m = len(paths)
    return Window(rows=np.arange(m), T=T, R=R, axT=ax, axR=ax, paths=paths,
                  amplitude=np.full(m, 3.0), tolerance=np.full(m, 2e-4),
                  x0=0.5 * (T + R).mean(axis=0),
                  cut_sin2=math.sin(math.radians(half_beam_deg)) ** 2, neighbour_m=0.15)


CASES = {
    "plane": lambda T, R: models.curve_paths(np.array([0.06, 3.0, 0.0]), np.zeros(2), T, R),
    "point": lambda T, R: models.point_paths(np.array([2.5, 0.1]), T, R),
    "corner": lambda T, R: models.corner_paths(np.array([4.0, -0.2]), T, R),
    "curve": lambda T, R: models.curve_paths(np.array([0.0, 2.0, 1 / 2.3]), np.zeros(2), T, R),
}


@pytest.mark.parametrize("kind", sorted(CASES))
def test_families_tell_plane_point_corner_and_circle_apart(kind):
    """A 10-element array's 55 pairs of one reflector make one family of its kind whose
    reflection points the model gives."""
    T, R = _pairs(_array(10, 0.1))
    paths, q = CASES[kind](T, R)
    w = _window(T, R, paths)
    heard = in_beams(q, T, w.axT, w.cut_sin2) & in_beams(q, R, w.axR, w.cut_sin2)
    T, R, paths, q = T[heard], R[heard], paths[heard], q[heard]
    families, left = find_families(_window(T, R, paths), resolution=0.0185)
    assert [f.kind for f in families] == [kind]
    assert len(left) == 0 and len(families[0].rows) == len(paths)
    assert np.allclose(families[0].q, q, atol=1e-6)


def test_two_reflectors_make_two_families():
    """A wall and a corner in one array's beams: each echo goes to its own reflector."""
    T, R = _pairs(_array(10, 0.1))
    wall, _ = CASES["plane"](T, R)
    corner, _ = models.corner_paths(np.array([4.0, 0.05]), T, R)
    paths = np.concatenate([wall, corner])
    families, left = find_families(
        _window(np.concatenate([T, T]), np.concatenate([R, R]), paths), resolution=0.0185)
    assert sorted(f.kind for f in families) == ["corner", "plane"]
    assert len(left) == 0


@settings(max_examples=25, deadline=None)
@given(phi=finite(min_value=-0.2, max_value=0.2), d=finite(min_value=1.5, max_value=8.0),
       noise=finite(min_value=0.0, max_value=2e-5))
def test_plane_fit_recovers_the_wall(phi, d, noise):
    T, R = _pairs(_array(10, 0.1))
    paths, _ = models.plane_points(phi, d, T, R)
    paths = paths + noise * np.sin(np.arange(len(paths)))
    start = models.plane_start(np.zeros(2), T, R, paths, np.radians(np.arange(-15, 15, 0.25)))
    fit = models.fit_curve(np.zeros(2), T, R, paths, start, fix_psi=True)
    assert abs(fit.params[0] - phi) < 1e-3 and abs(fit.params[1] - d) < 1e-3


@settings(max_examples=40, deadline=None)
@given(far=finite(min_value=0.0, max_value=5000.0), bearing=finite(min_value=-math.pi,
                                                                    max_value=math.pi),
       facing=finite(min_value=-math.pi, max_value=math.pi),
       radius=finite(min_value=0.02, max_value=2.0), dist=finite(min_value=0.3, max_value=3.0))
def test_a_circle_is_fitted_as_well_kilometres_from_the_origin(far, bearing, facing, radius,
                                                               dist):
    """models.curve_frame: the fit in a frame within 71 m of the array. In the scene's
    own frame φ and d are nearly collinear 300 m out and the fit stopped millimetres short
    (the zoo's seed 16 post-03, 1.1 km out: an empty map)."""
    u = np.array([math.cos(facing), math.sin(facing)])
    E = far * np.array([math.cos(bearing), math.sin(bearing)]) + _array(
        3, 0.1, heading_deg=math.degrees(facing))
    T, R = np.repeat(E, 3, axis=0), np.tile(E, (3, 1))
    x0 = E.mean(axis=0)
    centre = x0 + (dist + radius) * u
    paths, _ = models.circle_points(centre, radius, 1.0, T, R)
    turned = facing + 0.01  # a start 0.01 rad, 3 mm and a tenth of ψ off, about x0
    n = np.array([math.cos(turned), math.sin(turned)])
    start = np.array([turned, dist + 0.003 + float(n @ x0), 0.9 / (dist + radius)])
    fit = models.fit_curve(x0, T, R, paths, start)
    _, rho, A = models.curve_geometry(fit.params, x0)
    apex = x0 + A * np.array([math.cos(fit.params[0]), math.sin(fit.params[0])])
    assert np.hypot(*(apex - (centre - radius * u))) < 1e-4  # 1.7-4.7 mm 0.3-5 km out before
    assert abs(rho - radius) < 1e-3  # a 2 m circle's radius from a 0.2 m array
    assert fit.rms < 1e-5  # noise-free detections: a few µm (DETECTION_FLOOR_M 20 µm)


# --- whole runs with the default settings ----------------------------------------------


def _scene(name, extent, surfaces, transducers, noise=0.0, seed=1):
    return scene_from_dict({"clsonar": 1, "name": name, "extent": extent, "surfaces": surfaces,
                            "signal": {"noise_std": noise, "seed": seed},
                            "sensors": {"transducers": transducers}}, name)


def _transducers(E: np.ndarray, heading_deg: float, group: int = 0) -> list[dict]:
    return [{"position": [float(x), float(y)], "heading_deg": heading_deg, "group": group}
            for x, y in E]


def _wall(tilt_deg: float, dist: float = 3.0) -> list[dict]:
    t = math.radians(tilt_deg)
    base = np.array([5.0 + dist, 3.45])
    d = np.array([math.sin(t), math.cos(t)])
    return [{"type": "polyline", "points": [list(base - 4 * d), list(base + 4 * d)]}]


def _metrics(scene):
    return run(scene, context=context()).metrics


@pytest.mark.parametrize("tilt", [0.0, 3.6])
def test_a_wall_at_any_angle_is_mapped_exactly_and_completely(tilt):
    """Issue 14: a wall 3 m from a 10-element array, square-on or tilted by 3.6° (the old
    defaults: patches drawn level, 2.2 cm RMS)."""
    m = _metrics(_scene("wall", [4, -1, 10, 8], _wall(tilt),
                        _transducers(_array(10, 0.1, (5.0, 3.45)), 0.0)))
    assert m["accuracy_m"]["rms"] < 0.001
    assert m["completeness"]["2cm"] >= 0.95


def test_a_corner_seen_at_45_degrees_is_its_vertex():
    """Issue 14: a concave corner 5 m away seen at 45° (every echo a double bounce; the old
    defaults drew an arc through the vertex, 26 cm RMS)."""
    v = np.array([10.0, 10.0])
    centre = v + 5.0 * np.array([-1.0, -1.0]) / math.sqrt(2)
    scene = _scene("corner45", [4, 4, 11, 11],
                   [{"type": "polyline", "points": [[10, 6], [10, 10], [6, 10]]}],
                   _transducers(_array(10, 0.1, centre, 45.0), 45.0))
    m = _metrics(scene)
    assert m["vertices"][0]["error_m"] < 0.005
    assert m["accuracy_m"]["rms"] < 0.005


@pytest.mark.parametrize("noise", [0.6, 1.2])
@pytest.mark.parametrize("seed", [1, 3])
def test_a_noisy_corner_seen_at_45_degrees_is_its_vertex(noise, seed):
    """The same corner with noise σ 0.6 and 1.2: the corner fits its detections best of
    all models, but one or two of them lie outside their tolerance, which the free curve,
    with a parameter more, takes in; it was drawn as a curve across the vertex (2.8 and
    6.2 cm RMS, the vertex not found) — a best-fitting simpler model may leave
    NOISY_OUTSIDE_SHARE of the members out."""
    a = math.radians(45.0)
    first = np.array([7.0 - 5.0 * math.cos(a) - 0.225 * math.sin(a),
                      6.0 - 5.0 * math.sin(a) + 0.225 * math.cos(a)])
    array = first + 0.05 * np.arange(10)[:, None] * np.array([math.cos(-a), math.sin(-a)])
    m = _metrics(_scene("corner45", [0, 0, 9, 8],
                        [{"type": "polyline", "points": [[4, 6], [7, 6], [7, 3]]}],
                        _transducers(array, 45.0), noise, seed))
    assert m["vertices"][0]["error_m"] < 0.02
    assert m["accuracy_m"]["rms"] < 0.02


def test_a_cylinder_is_an_arc_not_a_bar():
    """Issue 14: a 0.3 m cylinder 2 m in front of an array (the old defaults: a flat bar,
    5 cm RMS)."""
    scene = _scene("cyl03", [4, 0, 9, 8],
                   [{"type": "circle", "center": [7.3, 3.45], "radius": 0.3}],
                   _transducers(_array(10, 0.1, (5.0, 3.45)), 0.0))
    m = _metrics(scene)
    assert m["accuracy_m"]["rms"] < 0.002
    assert m["completeness"]["2cm"] >= 0.8


def test_a_sinusoid_is_mapped_at_its_crests_and_troughs():
    """Issue 14: a sinusoid of 0.1 m amplitude and 1 m period 2 m away (the old defaults:
    vertical stubs, 4.4 cm RMS)."""
    scene = _scene("sinus", [4, 0, 9, 8],
                   [{"type": "sinusoid", "from": [7, 0.5], "to": [7, 7.5], "amplitude": 0.1,
                     "period": 1.0}], _transducers(_array(10, 0.1, (5.0, 3.45)), 0.0))
    m = _metrics(scene)
    assert m["accuracy_m"]["rms"] < 0.005
    assert m["completeness"]["2cm"] >= 0.8


def test_two_arrays_on_one_wall_join():
    scene = _scene("two", [4, 0, 9, 8], _wall(0.0, 2.0),
                   _transducers(_array(10, 0.1, (5.0, 2.5)), 0.0)
                   + _transducers(_array(10, 0.1, (5.2, 4.6)), 0.0, group=1))
    m = _metrics(scene)
    assert m["accuracy_m"]["rms"] < 0.001
    assert m["completeness"]["2cm"] >= 0.95


def test_overlay_puts_patches_in_place_of_the_maps_curves():
    """post.overlay: the fitted patches replace the map's curve where they lie, the rest of
    the map's curves stays (in runs of at least MIN_CURVE_CELLS points)."""
    from clsonar.post import MIN_CURVE_CELLS, Profile, overlay, runs

    x = np.arange(0.0, 1.0, 0.01)
    mapped = np.stack([x, 0.003 * np.ones_like(x)], axis=-1)  # the map's curve, 3 mm off
    patch = np.stack([x[:60], np.zeros(60)], axis=-1)  # a fitted patch over its first 60 cm
    out = overlay(Profile((mapped,), np.array([[1.0, 1.0]])), [patch], 0.02)
    assert np.array_equal(out.curves[0], patch)
    assert len(out.curves) == 2 and out.curves[1][0, 0] > 0.6 - 1e-9
    assert np.array_equal(out.vertices, [[1.0, 1.0]])
    keep = np.array([True] * 3 + [False] + [True] * MIN_CURVE_CELLS)
    assert [len(r) for r in runs(mapped[:len(keep)], keep, MIN_CURVE_CELLS)] == [5]


def test_the_profile_is_the_patches_and_vertices():
    """A wall and a corner: the profile holds the fitted patch as it is (its points on the
    wall to the µm) and the corner's located vertex."""
    v = np.array([10.0, 10.0])
    centre = v + 5.0 * np.array([-1.0, -1.0]) / math.sqrt(2)
    scene = _scene("corner45", [4, 4, 11, 11],
                   [{"type": "polyline", "points": [[10, 6], [10, 10], [6, 10]]}],
                   _transducers(_array(10, 0.1, centre, 45.0), 45.0))
    r = run(scene, context=context())
    assert r.counts["vertices_located"] == 1
    assert np.allclose(r.profile.vertices, [v], atol=0.005)
    wall = run(_scene("wall", [4, -1, 10, 8], _wall(0.0),
                      _transducers(_array(10, 0.1, (5.0, 3.45)), 0.0)), context=context())
    assert wall.counts["patches"] == 1
    assert np.allclose(wall.profile.points[:, 0], 8.0, atol=1e-5)


def test_a_planes_echo_is_as_strong_as_a_mirrors_and_an_edges_past_its_end_is_not():
    from clsonar import physics
    from clsonar.mapping.strength import MIRROR_SHARE, mirror_strong

    T = np.array([[0.0, 0.0], [0.0, 0.0], [0.1, 0.0]])  # monostatic: R = T
    axis = np.array([[0.0, 1.0]] * 3)
    q = np.array([[0.0, 2.0], [0.0, 2.0], [0.3, 2.0]])  # the last 5.7° off the axis
    ka = 18.3
    off = physics.piston_pattern(ka * math.sin(math.atan2(0.2, 2.0))) ** 2
    amplitude = np.array([4.5, 0.5 * 4.5, 0.9 * 4.5 * off])  # mirror, edge on the boundary
    assert mirror_strong(amplitude, q, T, axis, T, axis, 4.5, ka, 0.0).tolist() == [
        True, False, True]
    assert mirror_strong(amplitude, q, T, axis, T, axis, 0.0, ka, 0.0).all()  # unchecked
    sigma = (MIRROR_SHARE - 0.5) * 4.5 / 3 + 1e-9  # within three noise σ of the share
    assert mirror_strong(amplitude[1:2], q[:1], T[:1], axis[:1], T[:1], axis[:1], 4.5, ka,
                         sigma).tolist() == [True]


def test_a_points_echoes_agree_over_their_beams_and_a_faces_echo_is_not_its_edges():
    from dataclasses import replace

    from clsonar.mapping.families import POINT_SPREAD, Window, _strong

    T = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.3, 0.0]])
    axis = np.array([[0.0, 1.0]] * 4)
    w = Window(rows=np.arange(4), T=T, R=T, axT=axis, axR=axis, paths=np.full(4, 4.0),
               amplitude=np.array([0.03, 0.028, 0.031, 4.5]), tolerance=np.full(4, 2e-4),
               x0=np.zeros(2), cut_sin2=0.04, neighbour_m=0.15, mirror=4.5, ka=0.0)
    q = np.broadcast_to([0.15, 2.0], (4, 2))  # an edge 2 m away, heard by all four
    point = np.array([0.15, 2.0])
    assert _strong(w, "point", np.arange(4), q, point).tolist() == [True, True, True, False]
    # a curve's echoes are a mirror's weakened by its convex divergence (issue 18): a
    # 1 mm wire's may be as weak as the edge's, a nearly flat wall's not
    wire, flat = np.array([math.pi / 2, 2.0, 1 / 2.001]), np.array([math.pi / 2, 2.0, 1e-3])
    assert _strong(w, "curve", np.arange(4), q, wire).all()
    assert _strong(w, "curve", np.arange(4), q, flat).tolist() == [False, False, False, True]
    unchecked = replace(w, mirror=0.0)
    assert _strong(unchecked, "point", np.arange(4), q, point).all()
    assert _strong(unchecked, "curve", np.arange(4), q, flat).all()
    assert 4.5 / 0.031 > POINT_SPREAD  # the face's echo, 43 dB above the edge's


@pytest.mark.parametrize("distance", [2.0, 3.0, 4.0])
def test_a_convex_edge_is_located_with_the_defaults_from_2_to_4_m(distance):
    """Issue 18: a box corner, faces at 45° to the beams, in front of a 10-element array:
    its diffraction (the default uniform theory: 0.016–0.05 units for a 5-unit pulse; the
    estimate's 0.010–0.033) is above an open scene's envelope floor
    (clsonar.survey.OPEN_MIN_ENVELOPE). Located within 0.04 mm by either model."""
    box = [{"type": "polyline", "points": [[4.0, 2.0], [5.0, 3.0], [4.0, 4.0]]}]
    scene = _scene("edge", [3.0, 1.0, 5.0 + distance + 1.0, 5.0], box,
                   _transducers(_array(10, 0.05, (5.0 + distance, 3.0)), 180.0))
    m = _metrics(scene)
    assert m["vertices"][0]["error_m"] is not None and m["vertices"][0]["error_m"] < 0.02
    assert m["accuracy_m"]["rms"] < 0.01


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(-20, 20), min_size=1, max_size=40),
       st.lists(st.integers(-50, 50), min_size=1, max_size=40), st.sampled_from([1, 2, 4]))
def test_nearest_index_is_the_argmin_of_the_distances(values, queries, scale):
    """Issue 19: numerics.nearest_index (binary search) picks the same index as the
    [queries × values] argmin, ties included (half-integer queries meet exact ties)."""
    from clsonar.numerics import nearest_index

    v = np.asarray(values, dtype=np.float64) / scale
    q = np.asarray(queries, dtype=np.float64) / (2 * scale)
    np.testing.assert_array_equal(nearest_index(v, q), np.abs(q[:, None] - v[None]).argmin(axis=1))


def _line_patch(u: list[float], bend: float, paths: float = 4.0):
    """A straight patch along y = 2 (normal +y) with reflection points at ``u``."""
    from clsonar.mapping.patches import Patch

    k = len(u)
    return Patch(params=np.array([math.pi / 2, 2.0, 0.0]), x0=np.zeros(2),
                 u=np.asarray(u, dtype=float), lo=min(u) - 0.1, hi=max(u) + 0.1,
                 loci=np.arange(k), bend=bend, tx=np.arange(k), rx=np.arange(k),
                 T=np.zeros((k, 2)), R=np.zeros((k, 2)), paths=np.full(k, paths))


def test_a_patch_is_not_drawn_across_a_gap_no_echo_came_from():
    """drawn_spans: a patch whose curvature is unknown (two elements' echoes) is drawn
    around its reflection points, not across the 1.4 m between them; one whose detections
    show it straight, and gaps of 0.3 m beyond the trusted reach, are drawn whole."""
    from clsonar.mapping.joins import JOIN_GAP_M, drawn_spans
    from clsonar.mapping.patches import trusted_reach

    unknown = _line_patch([0.0, 0.05, 1.45, 1.5], math.inf)
    reach = trusted_reach(unknown)
    assert drawn_spans(unknown) == [(-0.1, 0.05 + reach), (1.45 - reach, 1.6)]
    assert drawn_spans(_line_patch([0.0, 0.05, 1.45, 1.5], 1e-6)) == [(-0.1, 1.6)]
    near = _line_patch([0.0, 0.29 + 2 * reach], math.inf)
    assert len(drawn_spans(near)) == 1 and 0.29 < JOIN_GAP_M


@settings(max_examples=200, deadline=None)
@given(seen=st.lists(st.floats(-4.0, 4.0), min_size=1, max_size=40),
       bearings=st.lists(st.floats(-4.0, 4.0), min_size=1, max_size=60),
       edge=st.booleans())
def test_a_corner_s_aperture_test_is_the_whole_matrix_s(seen, bearings, edge):
    """reflectors._within (the seen directions nearest each bearing round the circle)
    gives what the bearings × seen matrix of turns gave, bearings on the aperture's
    edge and duplicated directions included."""
    from clsonar.mapping.reflectors import CORNER_APERTURE_RAD, _within

    s, b = np.array(seen), np.array(bearings)
    if edge:  # bearings exactly an aperture from a seen direction, and duplicates
        s = np.concatenate([s, s[:2]])
        b = np.concatenate([b, s[:3] + CORNER_APERTURE_RAD, s[:3] - CORNER_APERTURE_RAD])
    matrix = np.min(np.abs(np.angle(np.exp(1j * (b[:, None] - s)))), axis=1)
    assert np.array_equal(_within(b, s), matrix <= CORNER_APERTURE_RAD)
