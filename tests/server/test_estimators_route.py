"""``GET /api/estimators`` (``server/routes/estimators.py``) on the real app: every registered estimator, as its
descriptor states it, with its time per sample as the start-up warm-up measured it on this machine."""

from __future__ import annotations

import math

from fastapi.testclient import TestClient

from gaitscope.sessions import registry

#: The five seeds' methods, which the warm-up builds from the default model and so times.
SEEDS = {"phase_ekf", "tbe", "hs_detector", "com_kin", "intent", "sdre_knee", "gp_ekf", "fp_avg", "fp_gf"}


def test_every_registered_estimator_with_what_it_needs_and_is_for(client: TestClient) -> None:
    r = client.get("/api/estimators")
    assert r.status_code == 200
    got = {e["name"]: e for e in r.json()}
    assert [e["name"] for e in r.json()] == list(registry.DECLARED)  # the order a stack runs them in
    for name, declared in registry.DECLARED.items():
        e = got[name]
        assert e["label"] == declared.label
        assert tuple(e["inputs"]) == declared.inputs
        assert tuple(e["inputs_any"]) == declared.inputs_any
        assert e["optional_inputs"] == list(registry.descriptors()[name].optional_inputs)
        assert e["phase"] == any(o == "phase" for o, _ in declared.outputs)
        assert e["purpose"] and "\n" not in e["purpose"], name  # each one says what it is for, in a line
    assert {n for n, e in got.items() if e["opt_in"]} == set(registry.OPT_IN) == {"hs_backup", "sdre_knee", "gp_ekf"}
    assert {n for n, e in got.items() if e["derives"]} == set(registry.DERIVERS)
    assert {"imu_foot", "imu_shank", "imu_thigh", "com_kin"} <= set(registry.DERIVERS)
    assert {n for n, e in got.items() if e["phase"]} == {"phase_ekf", "tbe", "hs_backup", "fp_avg", "fp_ls", "fp_gf",
                                                         "gp_ekf"}  # fmt: skip

    sdre = got["sdre_knee"]
    assert sdre["label"] == "SDRE knee angle from IMUs (seed 002)"
    assert sdre["inputs"] == ["imu_thigh_gyro_z_dps", "imu_thigh_accel_x_m_s2", "imu_shank_gyro_z_dps",
                              "imu_shank_accel_x_m_s2"]  # fmt: skip
    assert "seated, FES-driven" in sdre["purpose"] and "12 deg" in sdre["purpose"]
    assert sdre["paper"] == "Zhong 2016, MS thesis (seed 002)"
    assert got["gp_ekf"]["inputs"] == ["hip_angle_deg", "knee_angle_deg", "ankle_angle_deg"]
    assert got["gp_ekf"]["paper"] == "Thatte, Shah and Geyer 2019 (seed 003)"
    assert got["phase_ekf"]["inputs"] == [] and got["phase_ekf"]["inputs_any"] == ["foot_angle_deg", "shank_angle_deg"]
    assert got["phase_ekf"]["paper"] == "Medrano et al., IEEE T-RO 2023 (seed 000)"
    assert got["intent"]["paper"] == "Karulkar and Wensing 2021 (seed 001)"
    assert got["fp_gf"]["paper"] == "Montes Pérez, Thomas and Gregg (seed 004)"
    assert got["imu_shank"]["paper"] is None  # gaitscope's own front end


def test_cost_per_sample_is_what_the_warm_up_timed_here(client: TestClient) -> None:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    measured: dict[str, float] = ctx.estimator_cost_us
    got = {e["name"]: e["cost_us"] for e in client.get("/api/estimators").json()}
    timed = {n for n, us in got.items() if us is not None}
    assert timed == set(measured) and timed <= set(registry.DECLARED)
    assert SEEDS <= timed  # every seed's method, opt-in ones included
    for name in timed:
        assert got[name] == measured[name]
        assert math.isfinite(got[name]) and 0.0 < got[name] < 50_000.0, (name, got[name])  # compiled: well under 50 ms

    ctx.estimator_cost_us = {}  # not measured (yet): null, never a made-up number
    assert {e["cost_us"] for e in client.get("/api/estimators").json()} == {None}
