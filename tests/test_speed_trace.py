"""Issue 16, the room's pipeline: the wall-following trace's faster forms give the bits of
the forms they replace, kept here as the references."""

from __future__ import annotations

import numpy as np
import pytest

from clsonar.errors import SceneError
from clsonar.files import bundled_scenes
from clsonar.geometry import (
    SurfaceSets,
    build_geometry,
    nearest_distances,
    nearest_points,
    nearest_xy,
)
from clsonar.scene import load_scene, scene_from_dict
from clsonar.sensors import wall_following_paths
from clsonar.sensors.space import NearestOne
from clsonar.tools.floors import floor_scene


def _nearest_points_reference(surfaces: SurfaceSets, points: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray]:
    """``nearest_points`` before issue 16's pipeline work (x and y apart)."""
    shape = points.shape[:2]
    flat = np.arange(shape[0] * shape[1])
    any_wall, ragged, any_circle, ragged_circles = surfaces.kinds
    if any_wall:
        a, ab, ab2 = surfaces.a[:, None], surfaces.ab[:, None], surfaces.ab2[:, None]
        px, py = points[..., 0:1], points[..., 1:2]
        t = np.clip(((px - a[..., 0]) * ab[..., 0] + (py - a[..., 1]) * ab[..., 1]) / ab2,
                    0.0, 1.0)
        qx, qy = a[..., 0] + t * ab[..., 0], a[..., 1] + t * ab[..., 1]
        d = np.hypot(px - qx, py - qy)
        d = np.where(surfaces.walls[:, None], d, np.inf) if ragged else d
        o = d.shape[-1]
        j = d.argmin(axis=-1).ravel()
        best = d.reshape(-1, o)[flat, j].reshape(shape)
        near = np.empty(points.shape)
        near[..., 0], near[..., 1] = (v.reshape(-1, o)[flat, j].reshape(shape) for v in (qx, qy))
        if ragged:
            near = np.where(np.isfinite(best)[..., None], near, np.nan)
    else:
        best, near = np.full(shape, np.inf), np.full(points.shape, np.nan)
    if any_circle:
        c, r = surfaces.circles[:, None, :, :2], surfaces.circles[:, None, :, 2]
        v = points[:, :, None] - c
        dist_c = np.hypot(v[..., 0], v[..., 1])
        d = np.abs(dist_c - r)
        if ragged_circles:
            d = np.where(surfaces.rings[:, None], d, np.inf)
        k = d.shape[-1]
        j = np.argmin(d, axis=-1).ravel()
        d_j = d.reshape(-1, k)[flat, j].reshape(shape)
        unit = (v.reshape(-1, k, 2)[flat, j]
                / np.maximum(dist_c.reshape(-1, k)[flat, j], 1e-300)[:, None])
        circle = surfaces.circles[flat // shape[1], j]
        q = (circle[:, :2] + unit * circle[:, 2:3]).reshape(points.shape)
        closer = d_j < best
        best = np.where(closer, d_j, best)
        near = np.where(closer[..., None], q, near)
    return best, near


def _geometries() -> list:
    """Walls, chords of sinusoids and circles: the bundled scenes', and a floor's rooms."""
    names = ["room.json", "room-cylinder.json", "room-obstacles.json", "sinusoid-4m.json",
             "cylinder-3m.json", "edge-3m.json"]
    geoms = [build_geometry(load_scene(bundled_scenes() / n)) for n in names]
    return [*geoms, build_geometry(floor_scene(10.0))]


@pytest.mark.parametrize("m", [1, 5, 24, 72])
def test_nearest_points_are_the_reference_bits(m):
    """``nearest_points`` and ``nearest_distances`` (x and y apart, segments as columns) give the
    earlier form's distances and points to the bit: one scene, and scenes side by side with
    their segments and circles padded (ragged)."""
    geoms = _geometries()
    rng = np.random.default_rng(m)
    for rows in [[0], [1], [3], [6], [0, 1], [2, 4, 5], list(range(len(geoms)))]:
        surfaces = SurfaceSets.of([geoms[k] for k in rows])
        pts = rng.uniform(-1.0, 11.0, (len(rows), m, 2))
        pts[:, 0] = [g.walls[0, :2] if len(g.walls) else (0.0, 0.0)
                     for g in (geoms[k] for k in rows)]  # a point on a surface
        want = _nearest_points_reference(surfaces, pts)
        got = nearest_points(surfaces, pts)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        assert np.array_equal(nearest_distances(surfaces, pts[..., 0], pts[..., 1]), want[0])
    assert want[0].shape == (len(geoms), m) and np.all(np.isfinite(want[0]))


def _scene(surfaces: list, **placement) -> tuple:
    scene = scene_from_dict({
        "clsonar": 1, "name": "t", "extent": [0.0, 0.0, 10.0, 10.0], "surfaces": surfaces,
        "sensors": {"transducers": [], "placement": {"type": "wall-following", **placement}}})
    return scene.sensors.placement, scene, build_geometry(scene)


def _rect(points: list) -> dict:
    return {"type": "polyline", "points": points, "closed": True}


RECT = [[1, 1], [9, 1], [9, 6], [1, 6]]


def _jobs() -> list:
    """Traces that close (rooms, an obstacle run clockwise, a cylinder, a sinusoid's chords),
    and traces that fail: no room for the clearance, unclosed within max_poses, leaving
    the extent."""
    jobs = []
    for name in ["room.json", "room-l.json", "room-cylinder.json", "room-obstacles.json"]:
        scene = load_scene(bundled_scenes() / name)
        jobs.append((scene.sensors.placement, scene, build_geometry(scene)))
    circle = {"type": "circle", "center": [5.0, 3.5], "radius": 0.5}
    wave = {"type": "sinusoid", "from": [1.5, 5.5], "to": [8.5, 5.5], "amplitude": 0.1,
            "period": 1.0}
    jobs += [_scene([_rect(RECT), circle], start=[2.0, 2.0], direction="cw"),
             _scene([_rect(RECT), circle], start=[4.2, 3.5], clearance_m=0.3),
             _scene([_rect(RECT), wave], start=[3.0, 3.0], clearance_m=0.3, step_m=0.4),
             _scene([_rect(RECT)], start=[5.0, 3.5], clearance_m=3.0),
             _scene([_rect(RECT)], start=[3.0, 3.0], max_poses=5),
             _scene([{"type": "polyline", "points": [[0, 1], [10, 1]], "closed": False}],
                    start=[3.0, 3.0], clearance_m=0.3),
             _scene([_rect([[1, 1], [9, 1], [9, 6], [5, 1.05], [1, 6]])], start=[3.0, 3.0],
                    clearance_m=0.3)]
    return jobs


def test_a_trace_alone_is_the_traces_side_by_side():
    """One trace runs its sub-steps in floats (``_trace_alone``); traces side by side run
    them as arrays (``_advance``, the form before issue 16's pipeline work): the same paths,
    arcs and lengths to the bit, and the same errors."""
    jobs = _jobs()
    together = wall_following_paths(jobs)
    for job, pair in zip(jobs, together, strict=True):
        alone = wall_following_paths([job])[0]
        if isinstance(pair, SceneError):
            assert isinstance(alone, SceneError) and str(alone) == str(pair)
            continue
        assert not isinstance(alone, SceneError)
        for a, b in zip(alone, pair, strict=True):
            assert np.array_equal(a, b)
    room = together[0]
    assert not isinstance(room, SceneError)
    # the room's curve at 0.5 m: 36 m of walls, 1 m less at each of 6 corners, a quarter
    # circle of 0.5 m round each of 2 edges; chords of 2 cm
    assert len(room[0]) == 1578 and room[2] == pytest.approx(30.0 + np.pi / 2, abs=0.02)
    failed = [str(f) for f in together if isinstance(f, SceneError)]
    assert len(failed) == 3 and "did not return to its start" in failed[1]
    assert "left the extent at (10.020, 1.299)" in failed[2]


def test_the_nearest_point_of_one_point_in_floats_is_the_arrays_bits():
    """``NearestOne`` (a trace's projection, Python floats) gives ``nearest_xy``'s distance
    and point to the bit: random points, the walls' vertices and middles, a circle's centre
    (no direction: the 1e-300 guard) and points on it; unusable past MAX_SEGMENTS."""
    names = ["room.json", "room-cylinder.json", "room-obstacles.json", "cylinder-3m.json",
             "edge-3m.json", "plane-2m.json"]
    rng = np.random.default_rng(7)
    for name in names:
        geom = build_geometry(load_scene(bundled_scenes() / name))
        one = NearestOne(geom)
        assert one.usable
        pts = [*rng.uniform(-1.0, 11.0, (300, 2)), *geom.walls[:, :2],
               *(0.5 * (geom.walls[:, :2] + geom.walls[:, 2:]))]
        for cx, cy, r in geom.circles:
            pts += [np.array([cx, cy]), np.array([cx + r, cy]), np.array([cx, cy - 2 * r])]
        pts = np.array(pts)
        want = nearest_xy(SurfaceSets.of([geom]), pts[None, :, 0], pts[None, :, 1])
        got = np.array([one(x, y) for x, y in pts.tolist()])
        for k in range(3):
            assert np.array_equal(got[:, k], want[k][0])
    sinusoid = NearestOne(build_geometry(load_scene(bundled_scenes() / "sinusoid-4m.json")))
    assert not sinusoid.usable  # hundreds of chords


def test_the_poses_projected_in_floats_are_the_arrays_bits():
    """``place_wall_following`` projects each pose with ``_project_alone`` (floats): the
    poses of ``_project`` (arrays), as the placement computed them before."""
    from clsonar.sensors.rings import _project, place_wall_following, wall_following_path

    for name in ["room.json", "room-l.json", "room-cylinder.json", "room-obstacles.json"]:
        scene = load_scene(bundled_scenes() / name)
        p, geom = scene.sensors.placement, build_geometry(scene)
        path, arc, length = wall_following_path(p, scene, geom)
        closed_path, closed_arc = np.concatenate([path, path[:1]]), np.append(arc, length)
        want = []
        for s in np.arange(0.0, length - 0.5 * min(p.clearance_m / 4, p.step_m / 4, 0.02),
                           p.step_m):
            i = min(int(np.searchsorted(closed_arc, s, side="right")) - 1, len(path) - 1)
            t = (s - closed_arc[i]) / (closed_arc[i + 1] - closed_arc[i])
            guess = closed_path[i] + t * (closed_path[i + 1] - closed_path[i])
            want.append(_project(geom, guess, p.clearance_m)[0])
        poses = place_wall_following(p, scene, geom)[3]
        assert len(poses) > 40 and poses.tobytes() == np.asarray(want).tobytes()
