"""The registry's declarations (what a screen and a review's picker know without building anything) match
the estimators it builds, and :func:`~gaitscope.sessions.registry.feeds` says which ones a log's channels can run."""

from __future__ import annotations

from dataclasses import replace

import pytest

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.registry import (
    DECLARED,
    DERIVERS,
    ESTIMATORS,
    OPT_IN,
    Feed,
    MissingChannels,
    StackContext,
    descriptors,
    feeds,
    resolve,
)

HS = "heel_strike"


def test_each_registered_estimator_declares_what_it_is_built_as() -> None:
    model, _ = load_model(default_model_path())  # its fingerprint map keeps 3 components, as declared
    assert model.fingerprints is not None and model.fingerprints.n_components == 3
    ctx = StackContext(model, 0.9, 70.0, 0.01, fingerprint=(1.0, -0.5, 0.2))
    assert list(DECLARED) == list(ESTIMATORS)
    for name, make in ESTIMATORS.items():
        est = make(ctx)
        assert (est.name, est.inputs, est.outputs) == (name, DECLARED[name].inputs, DECLARED[name].outputs)
        d = descriptors()[name]
        assert (est.optional_inputs, est.tunables) == (d.optional_inputs, d.tunable_names)
    assert {n: d.label for n, d in DECLARED.items()} == {
        "imu_foot": "IMU front end (foot)",
        "imu_shank": "IMU front end (shank)",
        "imu_thigh": "IMU front end (thigh)",
        "imu_foot_contra": "IMU front end (foot contra)",
        "imu_shank_contra": "IMU front end (shank contra)",
        "imu_thigh_contra": "IMU front end (thigh contra)",
        "hs_detector": "Heel-strike detector",
        "phase_ekf": "Phase EKF (seed 000)",
        "tbe": "Timing-based estimate",
        "hs_backup": "Heel-strike backup",
        "fp_avg": "Average thigh model (seed 004)",
        "fp_ls": "Personalized thigh model (seed 004 LS-GF)",
        "fp_gf": "Online fingerprint EKF (seed 004 GF)",
        "com_kin": "Centre of mass from leg kinematics (seed 001)",
        "intent": "Speed-change intent (seed 001)",
        "sdre_knee": "SDRE knee angle from IMUs (seed 002)",
        "gp_ekf": "GP-EKF (seed 003)",
    }


def test_a_fingerprint_filter_the_session_cannot_build_is_left_out_or_refused_with_why(
    small_model: TrainedModel,
) -> None:
    assert small_model.fingerprints is not None and small_model.fingerprints.n_components == 2  # 3 subjects
    thigh = {"thigh_angle_deg", "foot_angle_deg"}
    ctx = StackContext(small_model, 0.9, 70.0, 0.01)
    assert [e.name for e in resolve(None, thigh, ctx)] == ["hs_detector", "phase_ekf", "tbe", "fp_avg", "fp_gf"]
    with pytest.raises(MissingChannels, match="fp_ls: the subject has no personalized fingerprint yet"):
        resolve(["phase_ekf", "fp_ls"], thigh, ctx)
    wrong = StackContext(small_model, 0.9, 70.0, 0.01, fingerprint=(1.0,))
    with pytest.raises(MissingChannels, match="1 components and the model's map 2: calibrate again"):
        resolve(["fp_ls"], thigh, wrong)
    no_map = StackContext(replace(small_model, fingerprints=None), 0.9, 70.0, 0.01)
    assert "fp_avg" not in [e.name for e in resolve(None, thigh, no_map)]
    with pytest.raises(MissingChannels, match="no fingerprint map"):
        resolve(["fp_gf"], thigh, no_map)
    # without a thigh channel they cannot run, and say so
    with pytest.raises(MissingChannels, match="fp_avg needs thigh_angle_deg"):
        resolve(["fp_avg"], {"foot_angle_deg"}, ctx)


def test_feeds_counts_a_channel_an_earlier_estimator_derives() -> None:
    every = {"foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", "thigh_angle_deg", HS}
    intent, kin = set(DECLARED["intent"].inputs), set(DECLARED["com_kin"].inputs)
    imus = [n for n in ESTIMATORS if n.startswith("imu_")]
    raw_readers = [n for n, d in DECLARED.items() if any(c.startswith("imu_") for c in d.inputs)]  # + sdre
    encoders = {"hip_angle_deg", "knee_angle_deg", "ankle_angle_deg"}  # gp_ekf's
    assert {n: f for n, f in feeds(every | intent | kin | encoders).items() if n not in raw_readers} == {
        n: Feed((), {}) for n in ESTIMATORS if n not in raw_readers
    }
    # raw IMUs alone: the front ends derive the angles, the detector the heel strikes
    raw = {c for n in imus for c in DECLARED[n].inputs}
    from_imus = feeds(raw)
    assert from_imus["phase_ekf"] == Feed((), {"foot_angle_deg": ("imu_foot",), "shank_angle_deg": ("imu_shank",)})
    # the phase EKF runs on a foot angle or a shank angle: one shank IMU feeds it (issue #25)
    shank_imu = feeds(set(DECLARED["imu_shank"].inputs))
    assert shank_imu["phase_ekf"] == Feed((), {"shank_angle_deg": ("imu_shank",)})
    assert feeds({"shank_angle_deg"})["phase_ekf"] == Feed((), {})
    assert feeds({"thigh_angle_deg"})["phase_ekf"].missing == ("foot_angle_deg or shank_angle_deg",)
    assert from_imus["com_kin"].missing == ("foot_force_N", "foot_force_contra_N")
    assert feeds(every)["intent"].missing == DECLARED["intent"].inputs
    # no centre of mass sent: the leg kinematics give it (seed 001's way)
    com = {"com_forward_m", "com_up_m", "com_forward_vel_m_s", "com_up_vel_m_s"}
    assert feeds(every | kin | (intent - com))["intent"] == Feed((), {c: ("com_kin",) for c in sorted(com)})
    # the foot angle alone: its velocity is differentiated, heel strikes come from the detector or the EKF
    foot = feeds({"foot_angle_deg"})
    assert foot["hs_detector"] == foot["phase_ekf"] == Feed((), {})
    assert foot["tbe"] == foot["hs_backup"] == Feed((), {HS: ("hs_detector", "phase_ekf")})
    # heel strikes alone: only the estimators that read nothing else
    strikes = feeds({HS})
    assert strikes["hs_detector"] == Feed(("foot_angle_deg", "foot_vel_dps"), {})
    assert strikes["phase_ekf"] == Feed(("foot_angle_deg or shank_angle_deg",), {})
    assert strikes["tbe"] == strikes["hs_backup"] == Feed((), {})
    assert all(f.missing for f in feeds(set()).values())


@pytest.mark.parametrize("channels", [{"foot_angle_deg"}, {HS}, {"foot_angle_deg", HS}, {"shank_angle_deg", HS}])
def test_feeds_agrees_with_what_resolve_builds(small_model: TrainedModel, channels: set[str]) -> None:
    ctx = StackContext(small_model, 0.9, 70.0, 0.01)
    runnable = [n for n, f in feeds(channels).items() if not f.missing]
    assert [e.name for e in resolve(runnable, channels, ctx)] == runnable


def test_the_registry_s_roles_come_from_the_descriptors() -> None:
    assert set(OPT_IN) == {"hs_backup", "sdre_knee", "gp_ekf"}
    assert set(DERIVERS) == {"imu_foot", "imu_shank", "imu_thigh", "imu_foot_contra", "imu_shank_contra",
                             "imu_thigh_contra", "com_kin"}  # fmt: skip
    assert OPT_IN | {"x"} == {"hs_backup", "sdre_knee", "gp_ekf", "x"}  # a set like the frozenset it was
    d = descriptors()
    assert [n for n, x in d.items() if x.quantities.get("phase") == "stance_phase"] == ["gp_ekf"]
    assert [n for n, x in d.items() if x.learned_model] == ["gp_ekf"]
    assert {n: x.fingerprint for n, x in d.items() if x.fingerprint} == {
        "fp_avg": "average",
        "fp_ls": "personal",
        "fp_gf": "online",
    }
    assert [(n, p.key, p.outputs) for n, x in d.items() for p in x.plots] == [
        ("intent", "intent", ("desired_speed_m_s", "speed_m_s"))
    ]
