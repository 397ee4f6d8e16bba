"""The supervised stack compiled (``gaitscope.estimators._lock_batch``) against stepping the stack it replaces.

Every output must be the stepped stack's bit for bit (compared as bytes: ``-0.0`` is not ``0.0``), with the
backup resets, lock losses and time standing, on real walks (starts, stops, standing, turns, dropouts), a
shank-only walk, given heel strikes, gaps, adversarial values (NaN, infinities, huge, denormal, out of
range) and any supervisor settings; in parts of any size; and where the stack would mark an estimator failed,
the compiled loop stops at that sample.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.estimators.lock import LockConfig
from gaitscope.estimators.pipeline import PipelineConfig
from gaitscope.estimators.protocol import HEEL_STRIKE, SENSOR_CHANNELS
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.offline.replay import compiled_stack, replay_stack
from gaitscope.sessions.stack import EstimatorStack
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.real_walks import RealWalkSpec, real_walk

MODEL, _ = load_model(default_model_path())
SUBJECT = make_subjects(CohortSpec())[1]
CONFIG = PipelineConfig(leg_length=SUBJECT.leg_length_m, body_mass_kg=SUBJECT.mass_kg)
SHANK_ONLY = ("shank_angle_deg", "shank_vel_dps")


@pytest.fixture(scope="module")
def walk() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two bouts of real walking, each after standing (with dropouts): times, the six channels, true heel strikes."""
    f = real_walk(SUBJECT, RealWalkSpec(bouts=2))
    z = np.column_stack([f[c].to_numpy(np.float64) for c in SENSOR_CHANNELS])
    return f["time_s"].to_numpy(np.float64), z, f[HEEL_STRIKE].to_numpy(np.float64)


def _stepped(stack: EstimatorStack, t: np.ndarray, z: np.ndarray, hs: np.ndarray) -> dict[str, object]:
    """The stack stepped as the replay steps it: its columns, counts, and the first sample it failed at."""
    rows, resets, lost, standing_s, failed_at = [], 0, 0, 0.0, -1
    k_ekf = stack.names.index("phase_ekf")
    i_standing = stack.outputs[k_ekf].index("standing")
    for k in range(t.size):
        channels = dict(zip(SENSOR_CHANNELS, z[k].tolist(), strict=True))
        channels[HEEL_STRIKE] = float(hs[k])
        e = stack.step(float(t[k]), channels)
        if stack.failed and failed_at < 0:
            failed_at = k
        nan = math.nan
        rows.append([nan if v is None else v for v in (e.phase, e.phase_rate, e.stride_length_m, e.incline_deg)]
                    + [e.torque_Nm, nan if e.tbe_phase is None else e.tbe_phase, float(e.heel_strike)])  # fmt: skip
        resets += e.backup_reset
        lost += e.fault == "lost"
        y = e.outputs[k_ekf]
        if y is not None and y[i_standing] >= 1.0 and k:
            standing_s += float(t[k]) - float(t[k - 1])
    return {"out": np.array(rows).reshape(-1, 7), "resets": resets, "lost": lost, "standing_s": standing_s,
            "failed_at": failed_at}  # fmt: skip


def _compiled(
    stack: EstimatorStack, t: np.ndarray, z: np.ndarray, hs: np.ndarray, parts: tuple[int, ...] = ()
) -> dict[str, object]:
    """The same stack on the compiled path, cut at ``parts``."""
    batch = compiled_stack(stack)
    assert batch is not None
    out, out_hs = np.full((t.size, 6), np.nan), np.zeros(t.size, dtype=np.bool_)
    failed_at = -1
    cuts = [0, *parts, t.size]
    for a, b in itertools.pairwise(cuts):
        f = batch.run(t[a:b], z[a:b], hs[a:b], out[a:b], out_hs[a:b])
        if f >= 0:
            failed_at = a + f
            break
    return {"out": np.column_stack([out, out_hs.astype(np.float64)]), "resets": batch.backup_resets,
            "lost": batch.lost, "standing_s": batch.standing_s, "failed_at": failed_at}  # fmt: skip


def _assert_same(t: np.ndarray, z: np.ndarray, hs: np.ndarray, lock: LockConfig | None = None,
                 config: PipelineConfig = CONFIG, parts: tuple[int, ...] = ()) -> dict[str, object]:  # fmt: skip
    """Compiled and stepped agree bit for bit (up to the failure, if any); returns the stepped run."""
    ref = _stepped(replay_stack(MODEL, config, 0.01, lock), t, z, hs)
    got = _compiled(replay_stack(MODEL, config, 0.01, lock), t, z, hs, parts)
    assert got["failed_at"] == ref["failed_at"]
    n = t.size if ref["failed_at"] < 0 else ref["failed_at"]
    for j, name in enumerate(("phase", "phase_rate", "stride", "incline", "torque", "tbe_phase", "heel_strike")):
        a, b = got["out"][:n, j], ref["out"][:n, j]
        bad = np.flatnonzero(a.view(np.int64) != b.view(np.int64))
        assert bad.size == 0, f"{name} differs first at sample {bad[0]}: {a[bad[0]]!r} != {b[bad[0]]!r}"
    if ref["failed_at"] < 0:
        for key in ("resets", "lost", "standing_s"):
            assert got[key] == ref[key], key
    return ref


def test_real_walks_with_standing_are_the_stacks_bit_for_bit(walk: tuple[np.ndarray, ...]) -> None:
    t, z, hs = walk
    none = np.full(t.size, np.nan)
    ref = _assert_same(t, z, none)  # heel strikes detected from the foot
    assert ref["standing_s"] > 3.0 and ref["failed_at"] < 0  # it stood, and resumed
    assert (ref["out"][:, 6] > 0).sum() > 20
    _assert_same(t, z, hs)  # heel strikes given
    _assert_same(t, z, np.where(np.arange(t.size) % 3 == 0, hs, np.nan))  # given on some samples only


def test_a_shank_only_walk_is_the_stacks_bit_for_bit(walk: tuple[np.ndarray, ...]) -> None:
    t, z, _ = walk
    shank = np.where(np.isin(SENSOR_CHANNELS, SHANK_ONLY), z, np.nan)
    ref = _assert_same(t, shank, np.full(t.size, np.nan))  # heel strikes from the shank
    assert (ref["out"][:, 6] > 0).sum() > 20


def test_starts_stops_gaps_and_dropouts_are_the_stacks_bit_for_bit(walk: tuple[np.ndarray, ...]) -> None:
    t, z, hs = walk
    rng = np.random.default_rng(24)
    t = t.copy()
    t[t.size // 3 :] += 1.5  # a gap: every filter restarts
    t[2 * t.size // 3 :] += 0.7  # a pause shorter than a gap
    z = z.copy()
    for _ in range(40):  # dropouts of one channel or all, and values the screens refuse
        a = int(rng.integers(0, t.size - 50))
        z[a : a + int(rng.integers(1, 50)), rng.integers(0, 6) if rng.random() < 0.7 else slice(None)] = np.nan
    for bad in (np.inf, -np.inf, 1e300, 5e-324, 1e4, -400.0):
        z[rng.integers(0, t.size, 5), rng.integers(0, 6, 5)] = bad
    ref = _assert_same(t, z, np.full(t.size, np.nan))
    assert ref["lost"] >= 0  # (counted alike)
    _assert_same(t, z, hs, parts=(1, 777, 778, 5000))  # in parts, cut anywhere


@pytest.mark.parametrize(
    "lock",
    [
        LockConfig(enabled=False),
        LockConfig(ramp_s=0.0, backdate_resume=False),
        LockConfig(advance_at_onset=False, onset_dps=30.0),
        LockConfig(ramp_s=0.0, onset_dps=5.0, backdate_resume=False),
        LockConfig(rate_noise_scale=5.0, cadence_change=0.01, adapt_strides=3, adapt_after_resume=0),
        LockConfig(rate_noise_scale=1.0, adapt_after_resume=9),
        LockConfig(still_s=0.2, move_dps=35.0, max_stride_s=0.8, out_of_range_s=0.1, phase_rate_range=(0.9, 1.1)),
    ],
)
def test_any_supervisor_settings_are_the_stacks_bit_for_bit(walk: tuple[np.ndarray, ...], lock: LockConfig) -> None:
    t, z, _ = walk
    ref = _assert_same(t, z, np.full(t.size, np.nan), lock=lock)
    if lock.max_stride_s < 1.0:
        assert ref["lost"] > 0  # the lock-loss resets are exercised


def test_other_pipeline_settings_are_the_stacks_bit_for_bit(walk: tuple[np.ndarray, ...]) -> None:
    t, z, _ = walk
    n = 3000
    config = PipelineConfig(leg_length=0.8, body_mass_kg=90.0, torque_gain=1.7, max_torque=12.0, use_backup=False)
    _assert_same(t[:n], z[:n], np.full(n, np.nan), config=config)


def test_a_sample_the_stack_refuses_stops_the_compiled_loop(walk: tuple[np.ndarray, ...]) -> None:
    t, z, _ = walk
    n = 2000
    hs = np.full(n, np.nan)
    stacks = [replay_stack(MODEL, CONFIG, 0.01) for _ in range(2)]
    for s in stacks:  # a covariance bound the filter's own health limit lets through: the stack fails it
        s.max_variance = 2e-3
    ref = _stepped(stacks[0], t[:n], z[:n], hs)
    got = _compiled(stacks[1], t[:n], z[:n], hs)
    assert 0 < ref["failed_at"] == got["failed_at"]
    k = ref["failed_at"]
    assert got["out"][:k].tobytes() == ref["out"][:k].tobytes()


def test_only_a_fresh_stack_of_the_phase_ekf_and_the_tbe_is_compiled() -> None:
    stack = replay_stack(MODEL, CONFIG, 0.01)
    assert compiled_stack(stack) is not None
    stack.step(0.0, {})
    assert compiled_stack(stack) is None  # stepped already
    stack = replay_stack(MODEL, CONFIG, 0.01)
    stack.set_primary("tbe")
    assert compiled_stack(stack) is None
    with pytest.raises(ValueError, match="increasing"):
        batch = compiled_stack(replay_stack(MODEL, CONFIG, 0.01))
        assert batch is not None
        batch.run(np.array([1.0, 1.0]), np.zeros((2, 6)), np.zeros(2), np.empty((2, 6)), np.empty(2, dtype=np.bool_))


_FLOATS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-400.0, 400.0),
    st.sampled_from([0.0, -0.0, 5e-324, 1e308, 29.0, 31.0, 59.0, 61.0, 151.0, -1.0]),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(
            st.sampled_from([0.001, 0.01, 0.01, 0.01, 0.3, 1.2, 3.0]),
            st.lists(_FLOATS, min_size=6, max_size=6),
            st.sampled_from([math.nan, math.nan, 0.0, 1.0]),
        ),
        min_size=1,
        max_size=120,
    ),
    st.integers(0, 120),
)
def test_any_input_is_the_stacks_bit_for_bit(rows: list[tuple[float, list[float], float]], cut: int) -> None:
    t = np.cumsum([r[0] for r in rows])
    z = np.array([r[1] for r in rows], dtype=np.float64)
    hs = np.array([r[2] for r in rows])
    lock = LockConfig(still_s=0.02, ramp_s=0.05)  # standing within a few samples
    _assert_same(t, z, hs, lock=lock, parts=(min(cut, t.size),))
