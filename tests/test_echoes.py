"""The analytic echo engine: OpenCL kernels (kernels/echoes.cl) against the NumPy float64
reference (clsonar/echoes/) and both against independent geometry, on PoCL's CPU device."""

from __future__ import annotations

import dataclasses
import functools
import io
import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsonar
import clsonar.echoes as echoes
from clsonar import physics
from clsonar.echoes import KINDS, compute_echoes, reference_echoes
from clsonar.errors import DeviceError
from clsonar.geometry import build_geometry, curve_derivatives, curve_point
from clsonar.opencl import get_context, has_fp64
from clsonar.scene import (
    Circle,
    EchoModel,
    Polyline,
    Scene,
    Sensors,
    Sinusoid,
    Transducer,
)


@functools.cache
def context():
    return get_context()


def kernel(scene: Scene, precision: str):
    if precision == "float64" and not has_fp64(context()):
        pytest.skip("the OpenCL device has no cl_khr_fp64")
    return compute_echoes(scene, context=context(), precision=precision)


# --------------------------------------------------------------------------- scene builders


def make_scene(surfaces, transducers, *, extent=(0.0, 0.0, 4.0, 3.0), offset=(0.0, 0.0),
               **echo) -> Scene:
    """A scene with ``surfaces`` and transducers ``(x, y, heading_deg[, group])``, all moved
    by ``offset`` (to exercise the local origin)."""
    ox, oy = offset

    def move(p):
        return (p[0] + ox, p[1] + oy)

    moved = []
    for s in surfaces:
        if isinstance(s, Polyline):
            moved.append(Polyline(tuple(move(p) for p in s.points), s.closed, s.solid))
        elif isinstance(s, Circle):
            moved.append(Circle(move(s.center), s.radius))
        else:
            moved.append(Sinusoid(move(s.start), move(s.end), s.amplitude, s.period))
    sensors = tuple(Transducer(move(t[:2]), t[2], t[3] if len(t) > 3 else 0) for t in transducers)
    x0, y0, x1, y1 = extent
    return Scene(name="test", extent=(x0 + ox, y0 + oy, x1 + ox, y1 + oy),
                 surfaces=tuple(moved), sensors=Sensors(transducers=sensors),
                 echo=EchoModel(**echo))


def room(w: float = 4.0, h: float = 3.0) -> Polyline:
    return Polyline(((0.0, 0.0), (w, 0.0), (w, h), (0.0, h)), closed=True)


def rows(table) -> list[tuple]:
    return list(zip(table.tx.tolist(), table.rx.tolist(), table.kind_names().tolist(),
                    table.order.tolist(), table.element.tolist(), strict=True))


def assert_finite(table) -> None:
    for col in (table.tof_s, table.amplitude, table.point):
        assert np.all(np.isfinite(col))
    assert np.all(table.amplitude > 0)
    assert np.all(table.tof_s > 0)


def match_tables(ref, other, *, n_circles: int, tof_tol: float, amp_rtol: float,
                 loose_below: float = 0.0, position_error_m: float = 0.0) -> list[str]:
    """Problems matching ``other`` to ``ref`` row by row on (tx, rx, kind, order, element).

    A sinusoid's echo may come from the neighbouring sampling interval when its specular point
    is on the shared sample (within rounding). Echoes weaker than ``loose_below`` may be
    missing from either side (the beam edge, where float32 rounding decides). Positions
    known to ``position_error_m`` (float32's rounding of the local coordinates) add that
    over the path length to an amplitude's relative tolerance: a transducer a millimetre
    from a curve sees its curvature and beam angles through its position's rounding.
    """
    problems = []
    index: dict[tuple, list[int]] = {}
    for i, key in enumerate(rows(other)):
        index.setdefault(key, []).append(i)
    used = np.zeros(len(other), dtype=bool)
    for i, key in enumerate(rows(ref)):
        candidates = [key]
        if key[2] == "curved" and key[4] >= n_circles:
            candidates += [(*key[:4], key[4] - 1), (*key[:4], key[4] + 1)]
        j = next((j for k in candidates for j in index.get(k, []) if not used[j]), None)
        if j is None or (key not in index and abs(other.tof_s[j] - ref.tof_s[i]) > tof_tol):
            if ref.amplitude[i] >= loose_below:
                problems.append(f"missing {key} amp={ref.amplitude[i]:.4g} tof={ref.tof_s[i]}")
            continue
        used[j] = True
        if abs(other.tof_s[j] - ref.tof_s[i]) > tof_tol:
            problems.append(f"{key}: tof {other.tof_s[j]} vs {ref.tof_s[i]}")
        path = ref.tof_s[i] * 343.0
        rtol = amp_rtol + position_error_m / max(path, 1e-12)
        if abs(other.amplitude[j] - ref.amplitude[i]) > rtol * ref.amplitude[i]:
            problems.append(f"{key}: amplitude {other.amplitude[j]} vs {ref.amplitude[i]}")
        # the carrier phase (an edge's diffraction) as the complex amplitude A·e^{iφ}
        turn = abs(np.exp(1j * other.phase[j]) - np.exp(1j * ref.phase[i]))
        if turn > rtol:
            problems.append(f"{key}: phase {other.phase[j]} vs {ref.phase[i]}")
    for j in np.flatnonzero(~used):
        if other.amplitude[j] >= loose_below:
            problems.append(f"extra {rows(other)[j]} amp={other.amplitude[j]:.4g}")
    return problems


# --------------------------------------------------------------------------- image sources


def image_source_echoes(w: float, h: float, transducers, scene: Scene) -> dict[tuple, tuple]:
    """Independent first- and second-order image sources of the room [0, w] × [0, h].

    Returns {(tx, rx, kind, order, walls): (tof, amplitude)} for the paths whose reflection
    points lie strictly inside their walls and whose legs are inside both beams.
    """
    mirror = {"left": lambda p: (-p[0], p[1]), "right": lambda p: (2 * w - p[0], p[1]),
              "bottom": lambda p: (p[0], -p[1]), "top": lambda p: (p[0], 2 * h - p[1])}
    line = {"left": (0, 0.0), "right": (0, w), "bottom": (1, 0.0), "top": (1, h)}
    span = {"left": h, "right": h, "bottom": w, "top": w}
    parallel = {frozenset(("left", "right")), frozenset(("bottom", "top"))}
    t = scene.transducer
    c = scene.medium.c
    ka = physics.wavenumber(t.frequency_hz, c) * t.radius_m
    half_beam = math.radians(t.half_beam_deg)

    def crossing(x, img, wall):
        axis, value = line[wall]
        f = (value - x[axis]) / (img[axis] - x[axis])
        if not 0.0 < f < 1.0:
            return None
        p = [x[0] + f * (img[0] - x[0]), x[1] + f * (img[1] - x[1])]
        p[axis] = value
        return p if 0.0 < p[1 - axis] < span[wall] else None

    def beam(sensor, target):
        angle = math.atan2(target[1] - sensor[1], target[0] - sensor[0]) - math.radians(sensor[2])
        angle = (angle + math.pi) % (2 * math.pi) - math.pi
        if abs(angle) >= half_beam:
            return 0.0
        return float(physics.piston_pattern(ka * math.sin(abs(angle))))

    out = {}
    for (i, ts), (j, rs) in itertools.product(enumerate(transducers), repeat=2):
        if (ts[3] if len(ts) > 3 else 0) != (rs[3] if len(rs) > 3 else 0):
            continue
        for k in (1, 2):
            for walls in itertools.product(line, repeat=k):
                if k == 2 and walls[0] == walls[1]:
                    continue
                images = [ts[:2]]
                for wall in walls:
                    images.append(mirror[wall](images[-1]))
                points, x = [], rs[:2]
                for wall, img in zip(reversed(walls), reversed(images[:-1]), strict=True):
                    p = crossing(x, mirror[wall](img), wall)
                    if p is None:
                        break
                    points.insert(0, p)
                    x = p
                if len(points) < k:
                    continue
                amp = t.amplitude * beam(ts, points[0]) * beam(rs, points[-1])
                if amp <= 0:
                    continue
                amp *= scene.echo.reflection_coefficient**k
                kind = "specular" if k == 1 or frozenset(walls) in parallel else "corner"
                length = math.dist(rs[:2], images[-1])
                out[(i, j, kind, k, walls)] = (length / c, amp)
        # A right-angled corner returns every ray parallel to itself; the ray through the
        # vertex V comes back along itself, so R on the ray from V through T (T = R in
        # particular) hears T→V→R.
        for vertex in ((0.0, 0.0), (w, 0.0), (w, h), (0.0, h)):
            vt = (ts[0] - vertex[0], ts[1] - vertex[1])
            vr = (rs[0] - vertex[0], rs[1] - vertex[1])
            if abs(vt[0] * vr[1] - vt[1] * vr[0]) > 1e-12 or vt[0] * vr[0] + vt[1] * vr[1] <= 0:
                continue
            amp = t.amplitude * beam(ts, vertex) * beam(rs, vertex)
            if amp > 0:
                length = math.dist(ts[:2], vertex) + math.dist(rs[:2], vertex)
                out[(i, j, "corner", 2, ("vertex", vertex))] = (
                    length / c, amp * scene.echo.reflection_coefficient**2)
    return out


ROOM_W, ROOM_H = 4.0, 3.0
ROOM_TRANSDUCERS = [
    (1.0, 1.2, 177.0, 0), (1.07, 1.25, 183.0, 0), (1.3, 1.1, 5.0, 0),  # left and right walls
    (2.0, 1.5, 181.0, 1), (2.05, 1.52, -1.0, 1),  # back to back: left → right double bounces
    (0.9, 0.8, 222.0, 2), (0.95, 0.72, 228.0, 2), (0.84, 0.86, 219.0, 2),  # corner (0, 0)
    (3.1, 2.2, 40.0, 3), (3.15, 2.25, 50.0, 3), (3.0, 2.6, 95.0, 3),  # corner (4, 3), top wall
]


@pytest.mark.parametrize("offset", [(0.0, 0.0), (3000.0, -7000.0)])
def test_rectangular_room_matches_image_sources(offset):
    """First- and second-order specular and corner echoes equal the image sources (1e-9)."""
    scene = make_scene([room(ROOM_W, ROOM_H)], ROOM_TRANSDUCERS, offset=offset)
    expected = image_source_echoes(ROOM_W, ROOM_H, ROOM_TRANSDUCERS, scene)
    names = {"corner": 0, "specular": 0}
    for key in expected:
        names[key[2]] += 1
    assert names["corner"] >= 4 and names["specular"] >= 10  # the scene exercises both
    assert any(key[3] == 2 and key[2] == "specular" for key in expected)

    ref = reference_echoes(scene)
    f64 = kernel(scene, "float64")
    for table in (ref, f64):
        assert_finite(table)
        got = sorted(zip(rows(table), table.tof_s, table.amplitude, strict=True))
        want = sorted(((k[0], k[1], k[2], k[3]), v) for k, v in expected.items())
        assert [g[0][:4] for g in got] == [w[0] for w in want]
        by_key = {}
        for (key, (tof, amp)) in want:
            by_key.setdefault(key, []).append((tof, amp))
        for key, tof, amp in got:
            options = by_key[key[:4]]
            best = min(options, key=lambda o: abs(o[0] - tof))
            assert tof == pytest.approx(best[0], rel=1e-9)
            assert amp == pytest.approx(best[1], rel=1e-9)

    f32 = kernel(scene, "float32")
    assert_finite(f32)
    problems = match_tables(ref, f32, n_circles=0, tof_tol=1e-6, amp_rtol=1e-3)
    assert not problems, problems
    # Reflection points lie on the walls of the room, in scene coordinates.
    for table in (ref, f64, f32):
        x = table.point[:, 0] - offset[0]
        y = table.point[:, 1] - offset[1]
        on_wall = (np.minimum(np.abs(x), np.abs(x - ROOM_W)) < 1e-3) | (
            np.minimum(np.abs(y), np.abs(y - ROOM_H)) < 1e-3)
        assert on_wall.all()


BOX = ((2.0, 2.0), (4.0, 2.0), (4.0, 3.0), (2.0, 3.0))
BOX_TRANSDUCERS = [
    (1.0, 2.5, 0.0, 0), (1.0, 2.6, 2.0, 0), (0.9, 2.45, -3.0, 0),  # the box's left face
    (3.0, 4.2, -90.0, 1), (3.1, 4.2, -88.0, 1),  # its top face
    (5.0, 1.0, 135.0, 2), (5.05, 0.95, 135.0, 2),  # its convex vertex (4, 2)
]


@pytest.mark.parametrize("box", [BOX, BOX[::-1]], ids=["ccw", "cw"])
def test_a_box_inside_a_room_reflects_on_its_outside(box):
    """A closed polyline inside the room is a solid box (outlines.solid_surfaces): its
    faces echo towards the outside, its vertices diffract as edges, it hides the wall
    behind it; kernels equal the float64 reference. As a room ("solid": false) its outside
    is silent."""
    room = Polyline(((0.0, 0.0), (6.0, 0.0), (6.0, 5.0), (0.0, 5.0)), closed=True)
    scene = make_scene([room, Polyline(box, closed=True)], BOX_TRANSDUCERS,
                       extent=(0.0, 0.0, 6.0, 5.0))
    c = scene.medium.c
    ref = reference_echoes(scene)
    for precision, tol in (("float64", 1e-12), ("float32", 1e-6)):
        problems = match_tables(ref, kernel(scene, precision), n_circles=0, tof_tol=tol,
                                amp_rtol=1e-4 if precision == "float64" else 1e-3)
        assert not problems, (precision, problems)
    kinds = ref.kind_names()
    for tx, point, distance in ((0, (2.0, 2.5), 1.0), (3, (3.0, 3.0), 1.2)):
        i = np.flatnonzero((ref.tx == tx) & (ref.rx == tx))
        assert len(i) == 1 and kinds[i[0]] == "specular"  # the box's face, nothing behind
        assert np.allclose(ref.point[i[0]], point, atol=1e-9)
        assert ref.tof_s[i[0]] == pytest.approx(2 * distance / c, rel=1e-9)
        assert ref.amplitude[i[0]] == pytest.approx(5.0 * 0.9, rel=1e-9)  # on axis: b = 1
    edge = np.flatnonzero((ref.tx == 5) & (ref.rx == 5))
    assert [kinds[i] for i in edge] == ["edge"] and np.allclose(ref.point[edge[0]], (4, 2))
    assert not np.any(ref.point[:, 0] > 5.9)  # the right wall is behind the box
    hollow = dataclasses.replace(scene, surfaces=(room, Polyline(box, True, solid=False)))
    assert not np.any(np.abs(reference_echoes(hollow).point[:, 0] - 2.0) < 1e-9)


def test_table_is_sorted_and_writes_csv():
    scene = make_scene([room(ROOM_W, ROOM_H)], ROOM_TRANSDUCERS)
    table = reference_echoes(scene)
    keys = list(zip(table.tx, table.rx, table.tof_s, table.kind, table.element, strict=True))
    assert keys == sorted(keys)
    assert table.tx.dtype == np.int64 and table.kind.dtype == np.int8
    assert table.order.dtype == np.int8 and table.element.dtype == np.int64
    assert set(table.kind_names()) <= set(KINDS)
    buf = io.StringIO()
    table.write_csv(buf)
    lines = buf.getvalue().splitlines()
    assert lines[0] == "tx,rx,tof_s,amplitude,kind,order"
    assert len(lines) == len(table) + 1
    tx, rx, tof, amp, kind, order = lines[1].split(",")
    assert (int(tx), int(rx), kind, int(order)) == (
        table.tx[0], table.rx[0], KINDS[table.kind[0]], table.order[0])
    assert float(tof) == pytest.approx(table.tof_s[0], rel=1e-11)
    assert float(amp) == pytest.approx(table.amplitude[0], rel=1e-8)


def test_chunked_launches_give_the_same_table(monkeypatch):
    scene = make_scene([room(ROOM_W, ROOM_H), Circle((2.5, 1.0), 0.2),
                        Sinusoid((0.5, 2.7), (3.5, 2.7), 0.05, 0.6)], ROOM_TRANSDUCERS)
    whole = kernel(scene, "float32")
    monkeypatch.setattr(echoes.table, "SLOTS_PER_LAUNCH", 50)
    chunked = kernel(scene, "float32")
    assert rows(chunked) == rows(whole)
    np.testing.assert_array_equal(chunked.tof_s, whole.tof_s)
    ref_chunked = reference_echoes(scene)
    monkeypatch.setattr(echoes.table, "SLOTS_PER_LAUNCH", 1 << 21)
    assert rows(ref_chunked) == rows(reference_echoes(scene))


def test_empty_scene_and_bad_precision(monkeypatch):
    scene = make_scene([], [(1.0, 1.0, 0.0)])
    assert len(reference_echoes(scene)) == 0
    assert len(kernel(scene, "float32")) == 0
    no_sensors = make_scene([room()], [])
    assert len(kernel(no_sensors, "float32")) == 0
    with pytest.raises(ValueError, match="precision"):
        compute_echoes(scene, context=context(), precision="half")
    monkeypatch.setattr("clsonar.opencl.has_fp64", lambda ctx: False)
    with pytest.raises(DeviceError, match="cl_khr_fp64"):
        compute_echoes(scene, context=context(), precision="float64")


# --------------------------------------------------------------------------- circles


CIRCLE_SCENE_TRANSDUCERS = [
    (0.6, 1.4, 2.0, 0), (0.6, 1.6, -4.0, 0), (0.65, 1.25, 12.0, 0),
    (2.0, 2.6, -80.0, 1), (2.2, 2.65, -95.0, 1), (1.7, 2.5, -60.0, 1),
    (3.4, 0.5, 150.0, 2), (3.5, 0.7, 160.0, 2),
]


def circle_scene(**kw) -> Scene:
    return make_scene([room(), Circle((2.0, 1.5), 0.5), Circle((3.0, 1.0), 0.15)],
                      CIRCLE_SCENE_TRANSDUCERS, **kw)


@pytest.mark.parametrize("implementation", ["reference", "float64"])
def test_circle_echoes_obey_the_reflection_law(implementation):
    scene = circle_scene()
    table = reference_echoes(scene) if implementation == "reference" else kernel(scene, "float64")
    geom = build_geometry(scene)
    pos = np.array([t.position for t in scene.sensors.transducers])
    curved = np.flatnonzero(table.kind_names() == "curved")
    assert len(curved) >= 8 and len(set(zip(table.tx[curved], table.rx[curved], strict=True))) >= 6
    assert any(table.tx[i] != table.rx[i] for i in curved)
    for i in curved:
        cx, cy, r = geom.circles[table.element[i]]
        p = table.point[i]
        n = (p - (cx, cy)) / r
        assert math.hypot(*n) == pytest.approx(1.0, abs=1e-12)
        u_t = pos[table.tx[i]] - p
        u_r = pos[table.rx[i]] - p
        incidence = math.atan2(n[0] * u_t[1] - n[1] * u_t[0], n @ u_t)
        reflection = math.atan2(n[0] * u_r[1] - n[1] * u_r[0], n @ u_r)
        assert abs(incidence) < math.pi / 2 and abs(reflection) < math.pi / 2
        assert incidence == pytest.approx(-reflection, abs=1e-6)
        length = np.linalg.norm(u_t) + np.linalg.norm(u_r)
        assert table.tof_s[i] == pytest.approx(length / scene.medium.c, rel=1e-12)


@pytest.mark.parametrize("implementation", ["reference", "float64", "float32"])
def test_monostatic_circle_echo_is_the_radial_point(implementation):
    scene = make_scene([Circle((2.0, 1.5), 0.4)], [(0.7, 0.9, 24.0), (3.2, 2.6, 220.0, 1)],
                       offset=(250.0, 40.0))
    table = (reference_echoes(scene) if implementation == "reference"
             else kernel(scene, implementation))
    assert len(table) == 2 and set(table.kind_names()) == {"curved"}
    tol = 1e-12 if implementation != "float32" else 2e-5
    c = np.array([252.0, 41.5])
    for i in range(2):
        t = np.array(scene.sensors.transducers[table.tx[i]].position)
        assert table.tx[i] == table.rx[i]
        radial = c + 0.4 * (t - c) / np.linalg.norm(t - c)
        np.testing.assert_allclose(table.point[i], radial, rtol=0, atol=tol)
        expected_tof = 2 * (np.linalg.norm(t - c) - 0.4) / scene.medium.c
        assert table.tof_s[i] == pytest.approx(expected_tof, rel=1e-9 if tol < 1e-9 else 1e-6)


@pytest.mark.parametrize("implementation", ["reference", "float64", "float32"])
def test_cylinder_between_transducer_and_wall_removes_the_wall_echo(implementation):
    def run(surfaces):
        scene = make_scene(surfaces, [(1.0, 1.5, 0.0)])
        return (reference_echoes(scene) if implementation == "reference"
                else kernel(scene, implementation))

    open_room = run([room()])
    wall = [i for i, p in enumerate(open_room.point) if abs(p[0] - 4.0) < 1e-6]
    assert len(wall) == 1 and open_room.kind_names()[wall[0]] == "specular"
    assert open_room.amplitude[wall[0]] == pytest.approx(4.5, rel=1e-6)

    blocked = run([room(), Circle((2.5, 1.5), 0.2)])
    assert not any(abs(p[0] - 4.0) < 1e-3 for p in blocked.point)
    assert list(blocked.kind_names()) == ["curved"]
    np.testing.assert_allclose(blocked.point[0], (2.3, 1.5), atol=1e-5)


# --------------------------------------------------------------------------- edges


@pytest.mark.parametrize("edge_model", ["estimate", "utd"])
@pytest.mark.parametrize("implementation", ["reference", "float64", "float32"])
def test_convex_edge_returns_a_diffraction_echo_from_its_vertex(implementation, edge_model):
    vertex = (3.0, 2.0)
    obstacle = Polyline(((3.0, 0.5), vertex, (4.5, 2.0)))
    outside = (1.6, 3.1)  # sees the vertex as a convex edge
    inside = (3.6, 1.3)  # inside the solid cone (the corner side)
    heading_out = math.degrees(math.atan2(vertex[1] - outside[1], vertex[0] - outside[0]))
    heading_in = math.degrees(math.atan2(vertex[1] - inside[1], vertex[0] - inside[0]))
    scene = make_scene([obstacle], [(*outside, heading_out + 2.0, 0), (*inside, heading_in, 1)],
                       extent=(0.0, 0.0, 5.0, 4.0), offset=(-1200.0, 300.0))
    scene = dataclasses.replace(scene, echo=dataclasses.replace(scene.echo,
                                                                edge_model=edge_model))
    table = (reference_echoes(scene) if implementation == "reference"
             else kernel(scene, implementation))
    edges = np.flatnonzero(table.kind_names() == "edge")
    assert len(edges) == 1
    i = edges[0]
    assert (table.tx[i], table.rx[i], table.order[i]) == (0, 0, 1)
    np.testing.assert_allclose(table.point[i], (vertex[0] - 1200.0, vertex[1] + 300.0),
                               rtol=0, atol=1e-9)
    d = math.dist(outside, vertex)
    assert table.tof_s[i] == pytest.approx(2 * d / scene.medium.c, rel=1e-6)
    t = scene.transducer
    ka = physics.wavenumber(t.frequency_hz, scene.medium.c) * t.radius_m
    b = physics.piston_pattern(ka * math.sin(math.radians(2.0)))
    # faces down (0, −1) and right (1, 0): a 270° free wedge, n = 1.5; the transducer is
    # 90° + (180° − 141.8°) from the lower face, measured through the free region
    phi = math.radians(90.0 + 180.0 - math.degrees(math.atan2(1.1, -1.4)))
    k = physics.wavenumber(t.frequency_hz, scene.medium.c)
    rho = scene.echo.reflection_coefficient  # weights the reflection-boundary terms
    gain = (physics.edge_gain(d, d, phi, phi, 1.5, k, 1.0, rho) if edge_model == "utd"
            else physics.edge_gain_estimate(d, d, k, 1.0))
    assert table.amplitude[i] == pytest.approx(t.amplitude * b * b * gain, rel=1e-5)
    # the uniform theory's phase far from the boundaries: Keller's −π/4 (the estimate: none)
    phase = physics.edge_phase(d, d, phi, phi, 1.5, k, rho) if edge_model == "utd" else 0.0
    assert table.phase[i] == pytest.approx(phase, abs=1e-5)
    assert edge_model == "estimate" or table.phase[i] == pytest.approx(-math.pi / 4, abs=0.02)
    assert np.all(table.phase[table.kind_names() != "edge"] == 0.0)


@pytest.mark.parametrize("implementation", ["reference", "float64", "float32"])
def test_a_thin_wall_s_free_end_inside_the_map_diffracts_as_a_half_plane(implementation):
    """A wall from beyond the map's border to (3, 2) inside it: its end is a knife edge
    (geometry.free_ends: n = 2, both faces along the wall); a transducer past the end, up
    and to the right, hears its diffraction alone (its foot on the wall's line is past the
    end: no specular echo), with the uniform theory's gain, in every implementation."""
    end = (3.0, 2.0)
    wall = Polyline(((-5.0, 2.0), end))
    at = (4.2, 3.0)
    heading = math.degrees(math.atan2(end[1] - at[1], end[0] - at[0]))
    scene = make_scene([wall], [(*at, heading, 0)], extent=(0.0, 0.0, 5.0, 4.0))
    table = (reference_echoes(scene) if implementation == "reference"
             else kernel(scene, implementation))
    assert table.kind_names().tolist() == ["edge"]
    np.testing.assert_allclose(table.point[0], end, rtol=0, atol=1e-6)
    d = math.dist(at, end)
    t = scene.transducer
    k = physics.wavenumber(t.frequency_hz, scene.medium.c)
    # φ from the wall's upper face (along −x) through the free region: 180° − 39.8°
    phi = math.pi - math.atan2(at[1] - end[1], at[0] - end[0])
    gain = physics.edge_gain(d, d, phi, phi, 2.0, k, 1.0, scene.echo.reflection_coefficient)
    assert table.amplitude[0] == pytest.approx(t.amplitude * gain, rel=1e-4)
    assert table.tof_s[0] == pytest.approx(2 * d / scene.medium.c, rel=1e-6)


# --------------------------------------------------------------------------- sinusoids


@pytest.mark.parametrize("implementation", ["reference", "float64", "float32"])
def test_sinusoid_echo_points_are_stationary(implementation):
    base_y, amplitude, period = 0.5, 0.12, 1.3
    wave = Sinusoid((0.3, base_y), (4.7, base_y), amplitude, period)
    sensors = [(1.0, 2.0, -88.0, 0), (1.1, 2.02, -95.0, 0), (1.25, 1.95, -80.0, 0),
               (3.0, 1.2, -100.0, 1), (3.3, 1.4, -92.0, 1), (2.2, 2.6, -70.0, 2)]
    scene = make_scene([wave], sensors, extent=(0.0, 0.0, 5.0, 3.0))
    table = (reference_echoes(scene) if implementation == "reference"
             else kernel(scene, implementation))
    assert len(table) >= 8 and set(table.kind_names()) == {"curved"}
    assert any(table.tx != table.rx)
    geom = build_geometry(scene)
    pos = np.array([t.position for t in scene.sensors.transducers])
    tol = 1e-9 if implementation != "float32" else 2e-4
    for i in range(len(table)):
        p = table.point[i]
        s = p[0] - 0.3
        np.testing.assert_allclose(curve_point(geom.curves[0], s), p, atol=tol)
        d1, _ = curve_derivatives(geom.curves[0], s)
        u_t = (pos[table.tx[i]] - p) / np.linalg.norm(pos[table.tx[i]] - p)
        u_r = (pos[table.rx[i]] - p) / np.linalg.norm(pos[table.rx[i]] - p)
        assert abs(d1 @ (u_t + u_r)) < tol
        s0, s1 = geom.interval_s[table.element[i]]
        assert s0 - 1e-6 <= s <= s1 + 1e-6


@pytest.mark.parametrize("implementation", ["reference", "float64", "float32"])
def test_specular_point_on_a_shared_sample_is_found_once(implementation):
    # A flat "sinusoid" sampled every 0.5 m; the transducer stands over the sample s = 1.5,
    # where the residual is exactly 0 in any precision.
    flat = Sinusoid((0.0, 0.5), (4.0, 0.5), 0.0, 100.0)
    scene = make_scene([flat], [(1.5, 2.0, -90.0)], curve_step_m=0.5)
    table = (reference_echoes(scene) if implementation == "reference"
             else kernel(scene, implementation))
    assert len(table) == 1
    np.testing.assert_allclose(table.point[0], (1.5, 0.5), atol=1e-12)
    assert table.element[0] == 3  # the interval [1.5, 2.0)
    assert table.amplitude[0] == pytest.approx(4.5, rel=1e-6)


def test_sinusoid_kernels_match_reference():
    wave = Sinusoid((0.3, 0.5), (4.7, 0.9), 0.2, 0.7)
    sensors = [(1.0, 2.0, -88.0, 0), (1.1, 2.02, -95.0, 0), (1.25, 1.95, -80.0, 0),
               (3.0, 1.5, -100.0, 1), (3.3, 1.6, -92.0, 1), (2.2, 2.6, -70.0, 2)]
    scene = make_scene([room(5.0, 3.0), wave, Circle((2.2, 1.8), 0.1)], sensors,
                       extent=(0.0, 0.0, 5.0, 3.0))
    ref = reference_echoes(scene)
    assert sum(ref.kind_names() == "curved") >= 8
    for precision, tol in (("float64", 1e-12), ("float32", 1e-6)):
        problems = match_tables(ref, kernel(scene, precision), n_circles=1, tof_tol=tol,
                                amp_rtol=1e-4 if precision == "float64" else 1e-3,
                                loose_below=0.0 if precision == "float64" else 0.25)
        assert not problems, (precision, problems)


# --------------------------------------------------------------------------- degenerate input


def test_degenerate_positions_give_finite_echoes():
    """Transducers on a wall, at a vertex, on a cylinder, coincident; a flat sinusoid."""
    surfaces = [room(), Polyline(((1.0, 1.0), (2.0, 1.0), (2.0, 2.0))), Circle((3.0, 2.0), 0.3),
                Sinusoid((0.5, 2.5), (3.5, 2.5), 0.0, 1.0)]
    sensors = [(4.0, 1.5, 180.0, 0), (2.0, 1.0, 135.0, 0), (3.0, 1.7, 90.0, 0),
               (1.5, 1.5, -90.0, 0), (1.5, 1.5, -90.0, 0), (0.0, 0.0, 45.0, 1),
               (1.5, 2.0, 90.0, 1), (2.0, 0.5, 90.0, 1)]
    scene = make_scene(surfaces, sensors)
    ref = reference_echoes(scene)
    assert_finite(ref)
    for precision in ("float64", "float32"):
        table = kernel(scene, precision)
        assert_finite(table)
    problems = match_tables(ref, kernel(scene, "float64"), n_circles=1, tof_tol=1e-12,
                            amp_rtol=1e-6)
    assert not problems, problems


# --------------------------------------------------------------------------- random scenes

def _aim(draw, base, surfaces) -> float:
    """A heading in degrees from ``base`` that likely sees an echo: along the normal of a wall,
    or towards a vertex, a cylinder or a point of a sinusoid; sometimes anywhere."""
    targets: dict[str, list[tuple[float, float]]] = {
        "wall": [], "vertex": [], "circle": [], "sinusoid": []}
    for s in surfaces:
        if isinstance(s, Polyline):
            pts = list(s.points) + ([s.points[0]] if s.closed else [])
            for a, b in itertools.pairwise(pts):
                ab = (b[0] - a[0], b[1] - a[1])
                f = ((base[0] - a[0]) * ab[0] + (base[1] - a[1]) * ab[1]) / (ab[0]**2 + ab[1]**2)
                f = min(max(f, 0.05), 0.95)
                targets["wall"].append((a[0] + f * ab[0], a[1] + f * ab[1]))
            targets["vertex"].extend(s.points)
        elif isinstance(s, Circle):
            targets["circle"].append(s.center)
        else:
            f = draw(st.floats(0.0, 1.0))
            targets["sinusoid"].append((s.start[0] + f * (s.end[0] - s.start[0]),
                                        s.start[1] + f * (s.end[1] - s.start[1])))
    kinds = [k for k, v in targets.items() for _ in range(2 if k == "wall" else 1) if v]
    kind = draw(st.sampled_from([*kinds, "any"]))
    if kind == "any":
        return draw(st.floats(-180.0, 180.0))
    x, y = draw(st.sampled_from(targets[kind]))
    return math.degrees(math.atan2(y - base[1], x - base[0]))


@st.composite
def random_scenes(draw) -> Scene:
    def point(box) -> tuple[float, float]:
        return (draw(st.floats(box[0], box[2])), draw(st.floats(box[1], box[3])))

    w, h = draw(st.floats(2.5, 6.0)), draw(st.floats(2.5, 5.0))
    inner = (0.2, 0.2, w - 0.2, h - 0.2)
    middle = (0.3 * w, 0.3 * h, 0.7 * w, 0.7 * h)
    surfaces: list = []
    shape = draw(st.sampled_from(["rectangle", "polygon", "none"]))
    if shape == "rectangle":
        surfaces.append(Polyline(((0.0, 0.0), (w, 0.0), (w, h), (0.0, h)), closed=True))
    elif shape == "polygon":  # star-shaped about the centre: simple, possibly non-convex
        n = draw(st.integers(4, 7))
        pts = []
        for i in range(n):
            angle = 2 * math.pi * (i + draw(st.floats(-0.3, 0.3))) / n
            radius = draw(st.floats(0.55, 1.0))
            pts.append((w / 2 + radius * w / 2 * math.cos(angle),
                        h / 2 + radius * h / 2 * math.sin(angle)))
        surfaces.append(Polyline(tuple(pts), closed=True))
    if shape != "none" and draw(st.integers(0, 3)) == 0:  # a solid box inside the room
        (x0, y0), (x1, y1) = sorted([point(middle), point(middle)])
        if x1 - x0 > 0.05 and abs(y1 - y0) > 0.05:
            corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
            surfaces.append(Polyline(corners if draw(st.booleans()) else corners[::-1], True))
    for _ in range(draw(st.integers(0, 2))):
        pts = [point(inner) for _ in range(draw(st.integers(2, 4)))]
        if all(math.dist(a, b) > 0.05 for a, b in itertools.pairwise(pts)):
            surfaces.append(Polyline(tuple(pts)))
    for _ in range(draw(st.integers(0, 2))):
        surfaces.append(Circle(point(inner), draw(st.floats(0.05, 0.5))))
    if draw(st.booleans()):
        a, b = point(inner), point(inner)
        if math.dist(a, b) > 0.3:
            surfaces.append(Sinusoid(a, b, draw(st.floats(-0.2, 0.2)),
                                     draw(st.floats(0.3, 2.0))))
    transducers = []
    for group in range(draw(st.integers(1, 2))):
        base = point(inner if shape != "polygon" else middle)
        direction = draw(st.floats(0, 2 * math.pi))
        heading = _aim(draw, base, surfaces) + draw(st.floats(-6.0, 6.0))
        for _ in range(draw(st.integers(1, 3))):
            transducers.append((base[0], base[1],
                                heading + draw(st.floats(-4.0, 4.0)), group))
            step = draw(st.floats(0.03, 0.2))
            base = (base[0] + step * math.cos(direction), base[1] + step * math.sin(direction))
    offset = draw(st.sampled_from([(0.0, 0.0), (1500.0, -800.0)]))
    echo = {"max_order": draw(st.sampled_from([1, 2, 2, 3])),
            "reflection_coefficient": draw(st.floats(0.3, 1.0)),
            "edge_coefficient": draw(st.floats(0.5, 20.0)),
            "edge_model": draw(st.sampled_from(["estimate", "utd"])),
            "absorption_db_per_m": draw(st.sampled_from([0.0, 0.0, 0.3])),
            "curve_step_m": draw(st.sampled_from([0.01, 0.02]))}
    return make_scene(surfaces, transducers, extent=(0.0, 0.0, w, h), offset=offset, **echo)


@settings(max_examples=200, deadline=None)
@given(random_scenes())
def test_kernels_match_reference_on_random_scenes(scene):
    ref = reference_echoes(scene)
    assert_finite(ref)
    n_circles = sum(isinstance(s, Circle) for s in scene.surfaces)
    f64 = kernel(scene, "float64")
    assert_finite(f64)
    problems = match_tables(ref, f64, n_circles=n_circles, tof_tol=1e-12, amp_rtol=1e-4)
    assert not problems, ("float64", problems)
    f32 = kernel(scene, "float32")
    assert_finite(f32)
    a0 = scene.transducer.amplitude
    x0, y0, x1, y1 = scene.extent  # float32 rounds the local coordinates (the centre's)
    rounding = 64 * float(np.finfo(np.float32).eps) * 0.5 * math.hypot(x1 - x0, y1 - y0)
    problems = match_tables(ref, f32, n_circles=n_circles, tof_tol=1e-6, amp_rtol=2e-3,
                            loose_below=0.05 * a0, position_error_m=rounding)
    assert not problems, ("float32", problems)


@pytest.mark.parametrize("impl", ["reference", "float32", "float64"])
def test_right_angled_corner_returns_the_monostatic_echo_through_its_vertex(impl):
    """T = R facing a 90° corner hears it (the retro-reflection through the vertex); a 60°
    corner, which does not send rays back along themselves, gives no such echo."""
    def echoes(points):
        scene = make_scene([Polyline(points)], [(8.0, 5.0, 0.0, 0)], extent=(0, 0, 12, 10))
        return (reference_echoes(scene) if impl == "reference" else kernel(scene, impl)), scene

    right, scene = echoes(((7.0, 2.0), (10.0, 5.0), (7.0, 8.0)))
    corner = np.flatnonzero(right.kind_names() == "corner")
    assert len(corner) == 1
    i = int(corner[0])
    assert right.order[i] == 2 and np.allclose(right.point[i], (10.0, 5.0), atol=1e-5)
    assert right.tof_s[i] == pytest.approx(2 * 2.0 / scene.medium.c, abs=1e-9)
    assert right.amplitude[i] == pytest.approx(5.0 * 0.9**2, rel=1e-4)  # on axis: b = 1
    half = 3.0 * math.tan(math.radians(30))
    sixty, _ = echoes(((7.0, 5.0 - half), (10.0, 5.0), (7.0, 5.0 + half)))
    assert not np.any(sixty.kind_names() == "corner")


@st.composite
def open_scenes(draw) -> Scene:
    """A few open surfaces (walls, circles, a sinusoid) and sensors aimed anywhere: many
    pairs whose beams miss every surface."""
    surfaces: list = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["wall", "circle", "sinusoid"]))
        a = (draw(st.floats(0.5, 5.5)), draw(st.floats(0.5, 5.5)))
        b = (draw(st.floats(0.5, 5.5)), draw(st.floats(0.5, 5.5)))
        if kind == "circle":
            surfaces.append(Circle(a, draw(st.floats(0.05, 0.4))))
        elif math.dist(a, b) > 0.3:
            surfaces.append(Polyline((a, b)) if kind == "wall" else
                            Sinusoid(a, b, draw(st.floats(-0.2, 0.2)), draw(st.floats(0.3, 2.0))))
    transducers = [(draw(st.floats(0.2, 5.8)), draw(st.floats(0.2, 5.8)),
                    draw(st.floats(-180.0, 180.0)), 0) for _ in range(draw(st.integers(2, 8)))]
    return make_scene(surfaces, transducers, extent=(0.0, 0.0, 6.0, 6.0),
                      max_order=draw(st.sampled_from([1, 2])))


@settings(max_examples=150, deadline=None)
@given(st.one_of(open_scenes(), random_scenes()))
def test_pairs_out_of_view_have_no_echo(scene):
    """pairs_in_view drops only pairs the float64 reference gives no echo at all."""
    pb = echoes.prepare_problem(scene)
    keep = echoes.pairs_in_view(pb)
    ref = reference_echoes(scene)
    dropped = {(int(t), int(r)) for t, r in pb.pairs[~keep]}
    assert not dropped & {(int(t), int(r)) for t, r in zip(ref.tx, ref.rx, strict=True)}


def test_skipping_pairs_out_of_view_leaves_the_table_unchanged():
    scene = clsonar.load_scene(Path(__file__).resolve().parents[1] / "scenes/cylinder-2.1m.json")
    stats: dict = {}
    skipped = compute_echoes(scene, context=get_context(), stats=stats)
    full = compute_echoes(scene, context=get_context(), skip_empty_pairs=False)
    assert stats["pairs_skipped_empty"] > 400 and stats["echo_families_run"] == 1
    for column in ("tx", "rx", "tof_s", "amplitude", "kind", "order", "point", "element",
                   "phase"):
        assert np.array_equal(getattr(skipped, column), getattr(full, column)), column
