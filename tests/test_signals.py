"""Received signals and detection: OpenCL kernels (kernels/signals.cl) against the NumPy float64
reference (clsonar/signals/), both against eq. 2.3 and against the statistics the detectors
are meant to have, on PoCL's CPU device."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import physics
from clsonar import signals as sig
from clsonar.echoes import EchoTable
from clsonar.opencl import get_context, has_fp64
from clsonar.scene import DetectionSettings, Scene, Signal
from clsonar.sensors import SensorArray, pairs
from clsonar.signals import detection as sig_detection
from clsonar.signals import host as sig_host
from clsonar.signals import reference as sig_reference
from clsonar.signals import synthesis as sig_synthesis
from clsonar.survey import with_detection_chosen

FS = 1.0e6
SIGMA = physics.DEFAULT_PULSE_SIGMA_S


@functools.cache
def context():
    return get_context()


def sensors(n: int, groups=None) -> SensorArray:
    g = np.zeros(n, np.int64) if groups is None else np.asarray(groups, np.int64)
    return SensorArray(np.zeros((n, 2)), np.zeros(n), g, np.zeros((0, 2)))


def table(rows) -> EchoTable:
    """An echo table from (tx, rx, tof_s, amplitude[, phase]) rows (sorted as the engine
    sorts it; phase 0 where a row has none)."""
    rows = sorted(tuple(r) + (0.0,) * (5 - len(r)) for r in rows)
    n = len(rows)

    def col(i, dtype):
        return np.array([r[i] for r in rows], dtype=dtype).reshape(n)

    return EchoTable(col(0, np.int64), col(1, np.int64), col(2, float), col(3, float),
                     np.zeros(n, np.int8), np.ones(n, np.int8), np.zeros((n, 2)),
                     np.arange(n, dtype=np.int64), col(4, float))


def scene(mode="envelope", noise=0.0, *, seed=1, threshold=4.0, size=1.0, **detection) -> Scene:
    detection.setdefault("min_envelope", 1.0)  # the floor of a room's scan (clsonar.survey)
    return Scene(name="signals", extent=(0.0, 0.0, size, size),
                 signal=Signal(noise_std=noise, threshold=threshold, seed=seed),
                 detection=DetectionSettings(mode=mode, **detection))


def rows(d: sig.Detections) -> list[tuple]:
    return list(zip(d.tx.tolist(), d.rx.tolist(), d.tof_s.tolist(), d.amplitude.tolist(),
                    strict=True))


def assert_same(ref: sig.Detections, got: sig.Detections, *, tof_tol=1.0 / FS, rtol=1e-3):
    assert len(got) == len(ref), f"{len(got)} detections vs {len(ref)}:\n{rows(got)}\n{rows(ref)}"
    np.testing.assert_array_equal(got.tx, ref.tx)
    np.testing.assert_array_equal(got.rx, ref.rx)
    np.testing.assert_allclose(got.tof_s, ref.tof_s, rtol=0, atol=tof_tol)
    np.testing.assert_allclose(got.amplitude, ref.amplitude, rtol=rtol)


def assert_sorted(d: sig.Detections):
    order = np.lexsort((d.tof_s, d.rx, d.tx))
    np.testing.assert_array_equal(order, np.arange(len(d)))


# --------------------------------------------------------------------------- noise


def test_philox_known_answers():
    """random123's published known-answer vectors for philox4x32-10."""
    cases = [
        ((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
        ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
        ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
         (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1)),
    ]
    for ctr, key, expected in cases:
        got = sig.philox4x32(np.array([ctr], np.uint32), key)[0]
        assert [int(v) for v in got] == list(expected)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_kernel_philox_and_normals_match_reference(precision):
    if precision == "float64" and not has_fp64(context()):
        pytest.skip("no cl_khr_fp64")
    seed, tx, rx, block0, count = 2**40 + 12345, 7, 3, 2**20 - 5, 4000
    raw, normals = sig_host.kernel_philox(context(), seed, tx, rx, block0, count, precision)
    ctr = np.zeros((count, 4), np.uint32)
    ctr[:, 0] = np.arange(block0, block0 + count)
    ctr[:, 1], ctr[:, 2] = tx, rx
    ref = sig.philox4x32(ctr, (seed & 0xFFFFFFFF, seed >> 32))
    np.testing.assert_array_equal(raw, ref)  # bitwise
    z = sig.box_muller(ref)
    tol = 2e-6 if precision == "float32" else 1e-12
    np.testing.assert_allclose(normals, z, rtol=0, atol=tol * np.maximum(1, np.abs(z)).max())
    np.testing.assert_array_equal(z.ravel(), sig.noise(seed, tx, rx, 4 * count, start=4 * block0))


def test_noise_statistics():
    z = sig.noise(1, 0, 1, 10**6)
    assert abs(z.mean()) < 0.005
    assert abs(z.std() - 1.0) < 0.005
    assert abs(np.mean(z**4) - 3.0) < 0.05  # Gaussian kurtosis
    assert abs(np.mean(np.abs(z) > 3.0) - 0.0027) < 0.0005
    # independent streams per pair and per seed
    assert abs(np.corrcoef(z[:10**5], sig.noise(1, 1, 0, 10**5))[0, 1]) < 0.02
    assert abs(np.corrcoef(z[:10**5], sig.noise(2, 0, 1, 10**5))[0, 1]) < 0.02
    assert abs(np.corrcoef(z[:-1], z[1:])[0, 1]) < 0.005


def test_same_samples_for_any_chunk_and_work_group():
    sen = sensors(3)
    ech = table([(0, 1, 1.0e-3, 4.5), (0, 1, 1.1e-3, 2.0), (2, 2, 3.0e-3, 3.0),
                 (1, 0, 2.5e-3, 1.0)])
    sc = scene("threshold", noise=1.0, seed=99)
    runs = [sig_host.kernel_a_scans(sc, sen, ech, context=context(), window_s=5e-3, chunk=c,
                                work_group=w) for c, w in ((4096, None), (333, 4), (1000, 16))]
    for other in runs[1:]:
        np.testing.assert_array_equal(other, runs[0])
    for p, (tx, rx) in enumerate(pairs(sen)):
        _, s = sig.a_scan(sc, sen, ech, int(tx), int(rx), window_s=5e-3)
        np.testing.assert_allclose(runs[0][p], s, rtol=0, atol=2e-5 * max(1, np.abs(s).max()))


def test_a_scan_is_eq_2_3_plus_noise():
    sen = sensors(2)
    ech = table([(0, 1, 1.2345e-3, 4.5), (0, 1, 1.4e-3, 2.0), (1, 1, 0.5e-3, 3.0)])
    sc = scene("threshold", noise=0.7, seed=5)
    t, s = sig.a_scan(sc, sen, ech, 0, 1, window_s=3e-3)
    assert len(t) == 3001 and t[0] == 0 and t[-1] == pytest.approx(3e-3)
    f = sc.transducer.frequency_hz
    clean = (4.5 * physics.pulse(t - 1.2345e-3, SIGMA, f, 1.0)
             + 2.0 * physics.pulse(t - 1.4e-3, SIGMA, f, 1.0))
    np.testing.assert_allclose(s, clean + 0.7 * sig.noise(5, 0, 1, len(t)), atol=1e-9)
    # the reference A-scans of detect_reference are the same samples
    model, pe = sig_synthesis.inputs(sc, sen, ech, 3e-3)
    slot = [tuple(p) for p in pe.pairs.tolist()].index((0, 1))
    np.testing.assert_array_equal(sig_synthesis.reference_signal(model, pe, slot, len(t)), s)


# --------------------------------------------------------------------------- noise-free


def test_threshold_mode_isolated_echo_crossing_delay():
    """The thesis' estimate is late by the time the pulse of eq. 2.3 takes to reach the
    threshold: for A = 4.5, thr = 4 the envelope reaches 4/(4.5·K) at 3σ − 0.49σ and the next
    carrier peak above it comes about 2.67σ after the arrival."""
    f = 50e3
    fine = np.arange(0, 6 * SIGMA, 1e-9)
    t_cross = fine[np.argmax(4.5 * physics.pulse(fine, SIGMA, f, 1.0) >= 4.0)]
    assert 2.5 * SIGMA < t_cross < 2.8 * SIGMA
    taus = [1.0e-3, 1.2345678e-3, 2.0000004e-3]
    ech = table([(0, 1, tau, 4.5) for tau in taus[:1]] + [(1, 0, taus[1], 4.5)]
                + [(1, 1, taus[2], 4.5)])
    sc = scene("threshold")
    for d in (sig.detect_reference(sc, sensors(2), ech),
              sig.detect(sc, sensors(2), ech, context=context())):
        assert len(d) == 3
        got = {(int(a), int(b)): (tof, amp) for a, b, tof, amp in rows(d)}
        for (a, b), tau in zip([(0, 1), (1, 0), (1, 1)], taus, strict=True):
            tof, amp = got[(a, b)]
            # the first sample at or after τ + t_cross (within rounding of the fine grid)
            assert tau + t_cross - 1e-8 <= tof < tau + t_cross + 1.0 / FS + 1e-8
            assert tof * FS == pytest.approx(round(tof * FS), abs=1e-6)
            assert 4.0 <= amp <= 4.5 * 1.0001


@pytest.mark.parametrize("amp", [4.5, 1.5, 40.0])
def test_envelope_mode_isolated_echo_is_unbiased(amp):
    taus = [1.0e-3 + k * 0.13e-6 for k in range(8)]  # sub-sample arrival times
    ech = table([(0, 1, tau + 0.5e-3 * k, amp) for k, tau in enumerate(taus)])
    truth = np.sort([tau + 0.5e-3 * k for k, tau in enumerate(taus)])
    sc = scene("envelope")
    for d in (sig.detect_reference(sc, sensors(2), ech),
              sig.detect(sc, sensors(2), ech, context=context())):
        assert len(d) == len(truth)
        assert np.all(np.abs(d.tof_s - truth) < 1e-6)  # within 1 µs (in fact ≈ 0.1 µs)
        assert np.all(np.abs(d.amplitude / amp - 1) < 0.02)


def test_monostatic_first_crossing_and_holdoff():
    """T = R: only the first crossing. T ≠ R: every crossing, one pulse length apart."""
    echoes_at = [(1.0e-3, 4.5), (1.2e-3, 4.5), (2.0e-3, 4.5), (3.0e-3, 4.6)]
    ech = table([(0, 0, t, a) for t, a in echoes_at] + [(0, 1, t, a) for t, a in echoes_at])
    sc = scene("threshold")
    model, pe = sig_synthesis.inputs(sc, sensors(2), ech, None)
    cand, _ = sig_reference.reference_candidates(model, pe)
    mono = cand.slot == [tuple(p) for p in pe.pairs.tolist()].index((0, 0))
    bi = cand.slot == [tuple(p) for p in pe.pairs.tolist()].index((0, 1))
    assert mono.sum() == 1 and bi.sum() > 6  # several carrier cycles cross per echo
    for d in (sig.detect_reference(sc, sensors(2), ech),
              sig.detect(sc, sensors(2), ech, context=context())):
        assert_sorted(d)
        mono_tof = d.tof_s[(d.tx == 0) & (d.rx == 0)]
        bi_tof = d.tof_s[(d.tx == 0) & (d.rx == 1)]
        assert len(mono_tof) == 1 and 1.0e-3 < mono_tof[0] < 1.0e-3 + 6 * SIGMA
        # the echo 200 µs after the first falls inside its hold-off (6σ ≈ 324 µs)
        assert len(bi_tof) == 3
        assert np.all(np.diff(bi_tof) >= 6 * SIGMA)
        np.testing.assert_allclose(bi_tof - [1.0e-3, 2.0e-3, 3.0e-3], 144e-6, atol=3e-6)


def test_holdoff_counts_from_the_last_counted_crossing():
    model = sig.signal_model(scene("threshold"))
    pe = sig_synthesis.pair_echoes(model, sensors(2), table([]))
    slot = [tuple(p) for p in pe.pairs.tolist()].index((0, 1))
    n = np.array([900, 100, 300, 430, 500, 1300])
    cand = sig_detection.Candidates(np.full(len(n), slot), n, np.full(len(n), 4.2))
    d = sig_detection.finish_threshold(model, pe, cand)
    assert model.holdoff == 324
    np.testing.assert_array_equal(np.round(d.tof_s * FS), [100, 430, 900, 1300])


def test_envelope_peaks_within_a_pulse_length_merge_to_the_stronger():
    ech = table([(0, 1, 1.0e-3, 3.0), (0, 1, 1.2e-3, 4.5), (0, 1, 2.0e-3, 2.0),
                 (0, 1, 2.4e-3, 2.5)])
    for d in (sig.detect_reference(scene(), sensors(2), ech),
              sig.detect(scene(), sensors(2), ech, context=context())):
        assert len(d) == 3
        assert abs(d.tof_s[0] - 1.2e-3) < 60e-6  # the weaker one 200 µs before is absorbed
        np.testing.assert_allclose(d.tof_s[1:], [2.0e-3, 2.4e-3], atol=2e-6)


def test_an_echo_s_carrier_phase_shifts_its_carrier_not_its_envelope():
    """A lone echo reads the same amplitude and time whatever its carrier phase; two echoes
    arriving together interfere by their phases (an edge's diffraction against its face's
    specular echo, physics.edge_phase): in phase they add, in antiphase they subtract."""
    t = np.arange(0, 2e-3, 1 / FS)
    f = scene().transducer.frequency_hz
    np.testing.assert_allclose(physics.pulse(t - 1e-3, SIGMA, f, 1.0, math.pi),
                               -physics.pulse(t - 1e-3, SIGMA, f, 1.0), atol=1e-12)
    lone = [table([(0, 1, 1.0e-3, 3.0, phase)]) for phase in (0.0, 2.0, -math.pi)]
    both = {name: table([(0, 1, 1.0e-3, 3.0), (0, 1, 1.0e-3, 1.0, phase)])
            for name, phase in (("in phase", 0.0), ("antiphase", math.pi),
                                ("quadrature", 0.5 * math.pi))}
    want = {"in phase": 4.0, "antiphase": 2.0, "quadrature": math.hypot(3.0, 1.0)}
    for detect in (sig.detect_reference,
                   functools.partial(sig.detect, context=context())):
        for ech in lone:
            d = detect(scene(), sensors(2), ech)
            assert len(d) == 1
            assert d.amplitude[0] == pytest.approx(3.0, rel=0.01)
            assert d.tof_s[0] == pytest.approx(1.0e-3, abs=2e-6)
        for name, ech in both.items():
            d = detect(scene(), sensors(2), ech)
            assert len(d) == 1
            assert d.amplitude[0] == pytest.approx(want[name], rel=0.01), name


# --------------------------------------------------------------------------- kernel vs reference


def draw_echo_rows(draw, n_sensors: int, most: int, tof, amp, phase=None) -> list[tuple]:
    """Up to ``most`` echoes (tx, rx, tof, amplitude[, phase]) of every pair of
    ``n_sensors`` transducers, drawn from the strategies given."""
    rows = []
    for tx in range(n_sensors):
        for rx in range(n_sensors):
            for _ in range(draw(st.integers(0, most))):
                row = (tx, rx, draw(tof), draw(amp))
                rows.append(row if phase is None else (*row, draw(phase)))
    return rows


@st.composite
def cases(draw):
    mode = draw(st.sampled_from(["threshold", "envelope"]))
    noise = draw(st.sampled_from([0.0, 0.3, 0.8, 1.0, 1.5]))
    n_sensors = draw(st.integers(1, 3))
    window = 6e-3
    echo_rows = draw_echo_rows(draw, n_sensors, 3, st.floats(0.1e-3, window),
                               st.floats(0.3, 8.0),
                               st.sampled_from([0.0, math.pi]) | st.floats(-math.pi, math.pi))
    seed = draw(st.integers(0, 2**63 - 1))
    chunk = draw(st.sampled_from([None, 257, 1000, 3000]))
    capacity = draw(st.sampled_from([None, 1, 3]))
    return mode, noise, n_sensors, echo_rows, seed, chunk, capacity, window


@settings(max_examples=50)
@given(cases())
def test_kernel_matches_reference(case):
    mode, noise, n_sensors, echo_rows, seed, chunk, capacity, window = case
    sc = scene(mode, noise, seed=seed)
    sen, ech = sensors(n_sensors), table(echo_rows)
    ref = sig.detect_reference(sc, sen, ech, window_s=window)
    got = sig.detect(sc, sen, ech, context=context(), window_s=window, chunk=chunk,
                     capacity=capacity)
    assert_sorted(ref)
    assert_same(ref, got)


def test_float64_kernel_matches_reference_closely():
    if not has_fp64(context()):
        pytest.skip("no cl_khr_fp64")
    ech = table([(0, 1, 1.0e-3, 4.5), (0, 1, 2.2e-3, 2.0), (1, 1, 1.5e-3, 3.0)])
    for mode in ("threshold", "envelope"):
        sc = scene(mode, 0.8, seed=3)
        ref = sig.detect_reference(sc, sensors(2), ech, window_s=5e-3)
        got = sig.detect(sc, sensors(2), ech, context=context(), precision="float64",
                         window_s=5e-3, chunk=700)
        assert_same(ref, got, tof_tol=1e-10, rtol=1e-9)


def test_groups_scenes_without_pairs_or_echoes_and_bad_precision():
    sen = sensors(4, groups=[0, 0, 1, 1])
    ech = table([(0, 1, 1e-3, 4.5), (0, 2, 1e-3, 4.5), (3, 2, 2e-3, 4.5)])
    d = sig.detect(scene(), sen, ech, context=context())
    assert {(int(a), int(b)) for a, b in zip(d.tx, d.rx, strict=True)} == {(0, 1), (3, 2)}
    empty = sensors(0)
    assert len(sig.detect(scene(), empty, table([]), context=context())) == 0
    assert len(sig.detect_reference(scene("threshold"), sensors(2), table([]))) == 0
    assert len(sig.detect(scene("threshold"), sensors(2), table([]), context=context())) == 0
    with pytest.raises(ValueError, match="precision"):
        sig.detect(scene(), sen, ech, context=context(), precision="float16")


# --------------------------------------------------------------------------- statistics


def test_envelope_noise_estimate_is_the_rayleigh_scale():
    """ŝ from the histogram median matches the theory: the two boxes' triangle h gives
    per-quadrature noise σ_n·calibration·√(Σh²/2). One 82 ms A-scan holds only ~600
    independent envelope values, so each pair's ŝ scatters by ≈ 3 % (measured over 100 pairs
    with the reference: mean 0.998, std 0.028)."""
    model = sig.signal_model(scene("envelope", 1.0))
    tri = np.convolve(np.ones(model.box), np.ones(model.box))
    expected = model.calibration * math.sqrt(np.sum(tri**2) / 2.0)
    sc = scene("envelope", 1.0, seed=11, size=10.0)
    sen = sensors(4)
    model, pe = sig_synthesis.inputs(sc, sen, table([]), None)
    run = sig_host.Runner(model, pe, context(), "float32", None, None)
    _, _, s_hat = run.scan(np.arange(len(pe.pairs)), 16, np.full(len(pe.pairs), 1.0), True)
    assert abs(np.mean(s_hat) / expected - 1) < 0.02
    assert np.all(np.abs(s_hat / expected - 1) < 0.10)
    assert 0.14 < expected < 0.15  # ≈ 0.145·σ_n: 6 ŝ < min_envelope = 1 up to σ_n ≈ 1.15


@pytest.mark.parametrize("noise", [1.0, 1.5])
def test_envelope_beats_threshold_in_noise(noise):
    """80 ms A-scans (10 m × 10 m extent): the envelope detector has no false detection far
    from the echo in ≥ 95 % of pairs and finds the echo in all; the thesis' threshold detector
    drowns in false crossings (its map "falls apart above noise 0.8")."""
    n = 6
    sen = sensors(n)
    tau = {(tx, rx): 5e-3 + 1e-3 * (tx * n + rx) for tx in range(n) for rx in range(n)}
    ech = table([(tx, rx, t, 4.5) for (tx, rx), t in tau.items()])
    result = {}
    for mode in ("threshold", "envelope"):
        sc = scene(mode, noise, seed=2024, size=10.0)
        assert sig.signal_model(sc).n_samples > 80_000
        d = sig.detect(sc, sen, ech, context=context())
        true_tau = np.array([tau[(int(a), int(b))] for a, b in zip(d.tx, d.rx, strict=True)])
        near = np.abs(d.tof_s - true_tau) < 6 * SIGMA
        false_per_pair = np.bincount(d.tx[~near] * n + d.rx[~near], minlength=n * n)
        found = np.zeros(n * n, bool)
        found[(d.tx * n + d.rx)[near]] = True
        result[mode] = (false_per_pair, found, d, near)
    false_env, found_env, d_env, near_env = result["envelope"]
    assert np.mean(false_env == 0) >= 0.95
    assert found_env.all()
    err = d_env.tof_s[near_env] - np.array([tau[(int(a), int(b))] for a, b in
                                            zip(d_env.tx[near_env], d_env.rx[near_env],
                                                strict=True)])
    assert np.sqrt(np.mean(err**2)) < 5e-6  # a few µs: ~1 mm of range
    false_thr, _, _, _ = result["threshold"]
    # ≈ 2.6 false crossings per 80 ms at σ = 1 (P(N > 4) = 3e-5 per sample), ≈ 80 at σ = 1.5
    assert np.mean(false_thr > 0) > 0.75
    assert false_thr.mean() > (1.5 if noise == 1.0 else 40)


# --------------------------------------------------------------------------- envelopes


def test_envelopes_for_backprojection():
    ech = table([(0, 1, 1.0e-3, 4.5), (1, 1, 2.5e-3, 2.0)])
    sc = scene("envelope", 0.5, seed=4)
    dt, env = sig.envelopes(sc, sensors(2), ech, rate_hz=1e5, context=context(), window_s=4e-3)
    dt_ref, ref = sig.envelopes_reference(sc, sensors(2), ech, rate_hz=1e5, window_s=4e-3)
    assert dt == dt_ref == pytest.approx(1e-5)
    assert env.shape == ref.shape == (4, 401)
    np.testing.assert_allclose(env, ref, rtol=1e-4, atol=1e-4)
    p01 = [tuple(p) for p in pairs(sensors(2)).tolist()].index((0, 1))
    j = int(np.argmax(env[p01]))
    assert abs(j * dt - 1.0e-3) <= dt and env[p01, j] == pytest.approx(4.5, rel=0.05)
    _, env8 = sig.envelopes(sc, sensors(2), ech, rate_hz=1e5, context=context(),
                              window_s=4e-3, chunk=333)
    np.testing.assert_allclose(env8, env, rtol=1e-5, atol=1e-5)


def test_envelope_with_zero_min_envelope_stays_finite_and_matches():
    ech = table([(0, 1, 1.0e-3, 4.5), (1, 1, 2.0e-3, 0.05)])
    for noise in (0.0, 0.02):
        sc = scene("envelope", noise, min_envelope=0.0, seed=8)
        ref = sig.detect_reference(sc, sensors(2), ech, window_s=4e-3)
        got = sig.detect(sc, sensors(2), ech, context=context(), window_s=4e-3)
        assert_same(ref, got)
        assert len(ref) == 2  # the weak echo too: the threshold adapts to the tiny noise


@pytest.mark.parametrize("name", ["room", "sinusoid-1m"])
@pytest.mark.parametrize("preset", [None, "thesis"])
def test_skipping_silent_pairs_changes_no_detection(name, preset):
    """A noise-free pair without an echo is not scanned (signals.scanned_slots): the
    detections are the same, value for value, as when every pair is scanned."""
    import clsonar
    from clsonar.echoes import compute_echoes
    from clsonar.files import bundled_scenes
    from clsonar.pipeline import apply_preset
    from clsonar.sensors import place_sensors

    scene = apply_preset(clsonar.load_scene(bundled_scenes() / f"{name}.json"), preset)
    sensors = place_sensors(scene)
    echoes = compute_echoes(scene, sensors)
    every = sig.detect(scene, sensors, echoes, skip_silent=False)
    skipped = sig.detect(scene, sensors, echoes)
    assert len(every.tof_s) > 0
    for key in ("tx", "rx", "tof_s", "amplitude"):
        assert np.array_equal(np.asarray(getattr(every, key)), np.asarray(getattr(skipped, key)))


@pytest.mark.parametrize("name", ["plane-2m", "sinusoid-1m", "room-l"])
@pytest.mark.parametrize("mode", ["threshold", "envelope"])
@pytest.mark.parametrize("noise", [0.0, 0.3, 0.5])
def test_quiet_samples_skipped_change_no_detection(name, mode, noise):
    """Where noise cannot reach a threshold (noise-free, or every threshold 10 noise scales
    up: the room's floor of 1 unit up to σn ≈ 0.69, the thesis' threshold of 4 up to 0.4),
    only the chunks an echo reaches are synthesised: the same detections, value for value;
    elsewhere (an open scene's floor of 0.01, or σn = 0.5 against the threshold of 4)
    every sample is."""
    import dataclasses
    from pathlib import Path

    import clsonar
    from clsonar.echoes import compute_echoes
    from clsonar.geometry import build_geometry
    from clsonar.sensors import place_sensors

    scene = clsonar.load_scene(Path(__file__).resolve().parents[1] / "scenes" / f"{name}.json")
    scene = dataclasses.replace(
        scene, detection=dataclasses.replace(scene.detection, mode=mode),
        signal=dataclasses.replace(scene.signal, noise_std=noise))
    sensors = place_sensors(scene, build_geometry(scene))
    ctx = get_context()
    echoes = compute_echoes(scene, sensors, context=ctx)
    quick: dict = {}
    a = sig.detect(scene, sensors, echoes, context=ctx, stats=quick)
    full: dict = {}
    b = sig.detect(scene, sensors, echoes, context=ctx, skip_quiet=False, stats=full)
    assert len(a) == len(b) > 0
    for column in ("tx", "rx", "tof_s", "amplitude"):
        assert np.array_equal(getattr(a, column), getattr(b, column)), column
    assert full["samples_skipped_quiet"] == 0
    quiet = noise == 0 or (name == "room-l" and mode == "envelope") or (
        mode == "threshold" and noise == 0.3)
    assert sig.noise_stays_quiet(sig.signal_model(with_detection_chosen(scene, sensors))) \
        == quiet
    if quiet:
        assert quick["samples_skipped_quiet"] > 2 * quick["samples_scanned"]
    else:
        assert quick["samples_skipped_quiet"] == 0


def test_noise_stays_quiet_ten_noise_scales_below_every_threshold():
    """The envelope's noise scale is 0.145·σn (docs/detection.md); the floor must be 10 of
    them, the thesis' threshold 10 σn."""
    for noise, floor, quiet in ((0.0, 0.01, True), (0.68, 1.0, True), (0.7, 1.0, False),
                                (0.006, 0.01, True), (0.007, 0.01, False)):
        model = sig.signal_model(scene("envelope", noise, min_envelope=floor))
        assert 0.144 < sig.envelope_noise_scale(model) / max(noise, 1e-300) < 0.146 or noise == 0
        assert sig.noise_stays_quiet(model) == quiet, (noise, floor)
    for noise, quiet in ((0.4, True), (0.41, False)):
        assert sig.noise_stays_quiet(sig.signal_model(scene("threshold", noise))) == quiet


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 50), st.integers(1, 400))
def test_echo_ranges_of_pairs_in_order_are_searchsorteds(seed, n_echoes, n_pairs):
    """The echoes of each pair, looked up echo by echo among many ordered pairs, are the
    ranges searchsorted gives pair by pair (echoes of pairs not listed included)."""
    from clsonar.signals.synthesis import _echo_ranges

    rng = np.random.default_rng(seed)
    pkey = np.unique(rng.integers(0, 500, n_pairs))
    ekey = np.sort(rng.integers(0, 520, n_echoes))
    lo, hi = _echo_ranges(ekey, pkey)
    np.testing.assert_array_equal(lo, np.searchsorted(ekey, pkey, side="left"))
    np.testing.assert_array_equal(hi, np.searchsorted(ekey, pkey, side="right"))


# --------------------------------------------------------------------------- Polaroid 6500


def polaroid(noise=0.0, *, seed=1) -> Scene:
    return scene("envelope", noise, seed=seed, size=10.0, receiver="polaroid-6500")


def test_polaroid_6500_gain_steps_and_threshold_table():
    """The receiver of docs/detection.md: the TL851's step ends (2.38 … 38.04 ms) and the
    TL852's relative gains (step 2 = 1); the threshold T0·c·t/g(t) is infinite inside the
    2.38 ms blanking and past the 35 ft window, jumps down where the gain steps up, and a
    wall at 35 ft in air (1.66 dB/m over its 21.3 m path) meets it at the window's end."""
    from clsonar.signals import polaroid as pol

    model = sig.signal_model(polaroid())
    rx = model.receiver
    c = polaroid().medium.c
    assert rx is not None and rx.blanking_s == 2.38e-3 and rx.c == c
    assert rx.window_s == pytest.approx(2 * 35 * 0.3048 / c)
    assert len(pol.STEP_ENDS_S) == 11 and len(pol.RELATIVE_GAIN) == 12
    # TL851 Gain Control Output Table; TL852 Figure 2 (docs/detection.md)
    assert pol.STEP_ENDS_S == (2.38e-3, 5.12e-3, 7.87e-3, 10.61e-3, 13.35e-3, 16.09e-3,
                               18.84e-3, 21.58e-3, 27.07e-3, 32.55e-3, 38.04e-3)
    assert pol.RELATIVE_GAIN == (0.25, 0.5, 1.0, 1.66, 3.0, 4.0, 5.0, 6.0, 7.0, 8.4, 10.0, 11.2)
    assert pol.RELATIVE_GAIN[2] == 1.0 and np.all(np.diff(pol.RELATIVE_GAIN) > 0)
    ends = np.asarray(pol.STEP_ENDS_S)
    np.testing.assert_array_equal(rx.gain(ends - 1e-9), pol.RELATIVE_GAIN[:11])
    np.testing.assert_array_equal(rx.gain(ends), pol.RELATIVE_GAIN[1:])
    t = np.array([3e-3, 9e-3, 30e-3, 50e-3])
    np.testing.assert_allclose(rx.thresholds(t),
                               rx.level_per_m * c * t / np.array([0.5, 1.66, 8.4, 11.2]))
    wall = 5.0 * 0.9 * 10 ** (-1.66 * 2 * 35 * 0.3048 / 20)
    assert rx.thresholds(np.array([rx.window_s]))[0] == pytest.approx(wall)
    assert np.all(np.isinf(rx.thresholds(np.array([0.0, 2.37e-3, rx.window_s * 1.0001]))))
    starts = rx.thresholds(ends)
    assert rx.floor == pytest.approx(starts.min()) and rx.floor == starts[7]  # 21.58 ms
    assert np.all(rx.thresholds(np.linspace(2.38e-3, rx.window_s, 5001)) >= rx.floor)
    assert 0.042 < rx.floor < 0.043 and 0.065 < starts[0] < 0.066
    assert sig_detection.envelope_floor(model) == rx.floor
    np.testing.assert_array_equal(sig_detection.thresholds_of(model, np.array([0.3, 9.0])),
                                  [rx.floor, rx.floor])
    assert pol.first_per_pair(np.array([2, 2, 3, 5, 5, 5])).tolist() == [
        True, False, True, True, False, False]


def test_polaroid_6500_hand_known_echoes():
    """A wall 2 m away (11.7 ms) is detected at its time of flight with its amplitude; an
    echo inside the blanking is not; one 10 % above the threshold at 2.5 ms (gain step 1) is
    detected there, the same echo at 4.9 ms (still step 1, twice the path) is not; after
    the window nothing; only the first echo of a firing is reported (single-echo mode), for
    every pair."""
    model = sig.signal_model(polaroid())
    rx = model.receiver
    wall = 2 * 2.0 / polaroid().medium.c
    early = 1.1 * float(rx.thresholds(np.array([2.5e-3]))[0])
    late = 1.1 * float(rx.thresholds(np.array([21.7e-3]))[0])
    ech = table([
        (0, 0, 1.0e-3, 4.5), (0, 0, wall, 4.5), (0, 0, 20e-3, 4.5),  # blanking, wall, later
        (0, 1, 4.9e-3, early), (0, 1, 21.7e-3, late),
        (1, 0, 2.5e-3, early), (1, 0, 8e-3, 4.5),
        (1, 1, rx.window_s + 1e-3, 4.5),  # after the window
    ])
    for d in (sig.detect_reference(polaroid(), sensors(2), ech, window_s=0.08),
              sig.detect(polaroid(), sensors(2), ech, context=context(), window_s=0.08)):
        got = {(int(a), int(b)): (tof, amp) for a, b, tof, amp in rows(d)}
        assert set(got) == {(0, 0), (0, 1), (1, 0)}, got
        assert got[(0, 0)][0] == pytest.approx(wall, abs=1e-6)
        assert got[(0, 0)][1] == pytest.approx(4.5, rel=0.02)
        assert got[(0, 1)][0] == pytest.approx(21.7e-3, abs=1e-6)
        assert got[(1, 0)][0] == pytest.approx(2.5e-3, abs=1e-6)
        assert got[(1, 0)][1] == pytest.approx(early, rel=0.02)


def test_polaroid_6500_changes_nothing_of_the_ideal_receiver():
    """The default receiver is the ideal one: the option is off unless asked for."""
    assert sig.signal_model(scene()).receiver is None
    assert DetectionSettings().receiver == "ideal"
    with pytest.raises(ValueError, match="envelope"):
        sig.signal_model(scene("threshold", receiver="polaroid-6500"))


@st.composite
def polaroid_cases(draw):
    noise = draw(st.sampled_from([0.0, 0.005, 0.01, 0.02]))
    n_sensors = draw(st.integers(1, 3))
    window = 30e-3
    echo_rows = draw_echo_rows(draw, n_sensors, 4, st.floats(0.5e-3, window),
                               st.floats(-1.6, 0.7).map(lambda e: 10**e))  # 0.025 … 5 units
    seed = draw(st.integers(0, 2**63 - 1))
    chunk = draw(st.sampled_from([None, 257, 3000]))
    capacity = draw(st.sampled_from([None, 1, 3]))
    return noise, n_sensors, echo_rows, seed, chunk, capacity, window


@settings(max_examples=30, deadline=None)
@given(polaroid_cases())
def test_polaroid_6500_kernel_matches_reference(case):
    """The kernels with the Polaroid receiver's threshold table against the NumPy float64
    reference, on echoes around its level, with and without noise (which the fixed
    comparator, unlike the ideal receiver's noise-adaptive threshold, may report)."""
    noise, n_sensors, echo_rows, seed, chunk, capacity, window = case
    sc = polaroid(noise, seed=seed)
    sen, ech = sensors(n_sensors), table(echo_rows)
    ref = sig.detect_reference(sc, sen, ech, window_s=window)
    got = sig.detect(sc, sen, ech, context=context(), window_s=window, chunk=chunk,
                     capacity=capacity)
    assert_sorted(ref)
    assert len({(a, b) for a, b, *_ in rows(ref)}) == len(ref)  # one echo per pair
    assert_same(ref, got)
