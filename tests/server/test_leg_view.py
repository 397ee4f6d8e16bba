"""The viser leg view: a real server on a free port, its scene poses, and the ghost's angles."""

from __future__ import annotations

import math
import socket
import threading
import time
import urllib.request
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import viser

from gaitscope.estimators.gait_model import OUT_FOOT, OUT_SHANK, evaluate
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.server.leg_view import LegView, knee_flexion_deg, quat_y, segment_angles_for, status_markdown
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.schema import GaitState
from gaitscope.sessions.synth.cohort import ANKLE_HEIGHT_FRAC, FOOT_FRAC, HEEL_BACK_FRAC, SHANK_FRAC, THIGH_FRAC

LEG = 0.9
H = LEG / 0.53
NODES = ("/thigh", "/thigh/shank", "/thigh/shank/foot")


def _state(**kw: Any) -> GaitState:
    base: dict[str, Any] = dict(
        seq=0, t=0.0, phase=0.3, phase_rate=1.0, stride_length_m=1.3, incline_deg=0.0, torque_Nm=12.5,
        tbe_phase=0.3, heel_strike=False, backup_reset=False, foot_angle_deg=0.0, shank_angle_deg=0.0,
        thigh_angle_deg=0.0, foot_pred_deg=1.0, shank_pred_deg=2.0, recv_ns=0,
    )  # fmt: skip
    return GaitState(**(base | kw))


def _rot(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _world(view: LegView, name: str) -> tuple[np.ndarray, np.ndarray]:
    """World rotation and position of a scene node, composed from its ancestors' handles."""
    R, t = np.eye(3), np.zeros(3)
    parts = name.strip("/").split("/")
    for i in range(1, len(parts) + 1):
        handle = view.server.scene.get_handle_by_name("/" + "/".join(parts[:i]))
        assert handle is not None, parts[:i]
        t = t + R @ handle.position
        R = R @ _rot(handle.wxyz)
    return R, t


def _box(view: LegView, name: str) -> viser.BoxHandle:
    handle = view.server.scene.get_handle_by_name(name)
    assert isinstance(handle, viser.BoxHandle), name
    return handle


def _sagittal_deg(R: np.ndarray) -> float:
    """Counter-clockwise angle seen from the right (about -y) of a rotation about y."""
    assert R[1, 1] == pytest.approx(1.0)
    return math.degrees(math.atan2(R[2, 0], R[0, 0]))


@pytest.fixture(scope="module")
def model() -> TrainedModel:
    return load_model(default_model_path())[0]


@pytest.fixture(scope="module")
def view(model: TrainedModel) -> Iterator[LegView]:
    v = LegView(port=0, model=model)
    yield v
    v.close()


# --- server lifecycle ----------------------------------------------------------------------------


def test_port_and_url_serve_the_viewer(view: LegView) -> None:
    assert view.port > 0
    assert view.url == f"http://127.0.0.1:{view.port}/"
    with urllib.request.urlopen(view.url, timeout=5) as r:
        assert r.status == 200
        assert r.headers["Content-Type"].startswith("text/html")
        assert b"<html" in r.read().lower()


def test_busy_port_moves_to_the_next_free_one() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        v = LegView(port=busy)
        try:
            assert v.port > busy
            assert v.url == f"http://127.0.0.1:{v.port}/"
        finally:
            v.close()


def test_close_stops_the_thread_and_later_calls_do_nothing() -> None:
    before = set(threading.enumerate())
    v = LegView(port=0)
    assert len(set(threading.enumerate()) - before) == 1
    v.show(_state(), LEG)
    v.close()
    assert set(threading.enumerate()) - before == set()
    assert v.closed
    v.show(_state(), LEG)  # no "queued on a closed connection" warning (pytest turns it into an error)
    v.close()


# --- the scene -----------------------------------------------------------------------------------


def test_hierarchy_exists(view: LegView) -> None:
    scene = view.server.scene
    names = ["/world/ground"] + [root + n for root in ("/world/leg", "/world/ghost") for n in NODES]
    for name in names:
        assert scene.get_handle_by_name(name) is not None, name
        if name != "/world/ground":
            assert scene.get_handle_by_name(name + "/segment") is not None, name


def test_positive_thigh_puts_the_knee_forward(view: LegView) -> None:
    view.show(_state(thigh_angle_deg=20.0, shank_angle_deg=0.0, foot_angle_deg=0.0), LEG)
    _, hip = _world(view, "/world/leg/thigh")
    R, knee = _world(view, "/world/leg/thigh/shank")
    a = math.radians(20.0)
    np.testing.assert_allclose(hip, [0.0, 0.0, LEG], atol=1e-12)
    np.testing.assert_allclose(knee, [THIGH_FRAC * H * math.sin(a), 0.0, LEG - THIGH_FRAC * H * math.cos(a)])
    assert knee[0] > 0
    assert _sagittal_deg(R) == pytest.approx(0.0, abs=1e-9)
    # Knee flexed: the shank's distal end (the ankle) behind the knee.
    view.show(_state(thigh_angle_deg=20.0, shank_angle_deg=-30.0, foot_angle_deg=0.0), LEG)
    _, ankle = _world(view, "/world/leg/thigh/shank/foot")
    _, knee = _world(view, "/world/leg/thigh/shank")
    assert ankle[0] - knee[0] == pytest.approx(-SHANK_FRAC * H * math.sin(math.radians(30.0)))


def test_straight_leg_stands_on_level_ground_and_toes_point_forward(view: LegView) -> None:
    view.show(_state(thigh_angle_deg=0.0, shank_angle_deg=0.0, foot_angle_deg=0.0, incline_deg=0.0), LEG)
    R, ankle = _world(view, "/world/leg/thigh/shank/foot")
    np.testing.assert_allclose(ankle, [0.0, 0.0, ANKLE_HEIGHT_FRAC * H], atol=1e-12)
    toe = ankle + R @ [FOOT_FRAC * H, 0.0, 0.0]
    assert toe[0] > 0
    _, box = _world(view, "/world/leg/thigh/shank/foot/segment")
    foot_box = _box(view, "/world/leg/thigh/shank/foot/segment")
    assert box[2] - foot_box.dimensions[2] / 2 == pytest.approx(0.0, abs=1e-12)  # sole on the floor
    assert box[0] == pytest.approx(FOOT_FRAC * H * (0.5 - HEEL_BACK_FRAC))


@pytest.mark.parametrize("foot", [15.0, -25.0])
def test_foot_angle_from_horizontal_positive_toes_up(view: LegView, foot: float) -> None:
    view.show(_state(thigh_angle_deg=10.0, shank_angle_deg=-5.0, foot_angle_deg=foot), LEG)
    R, _ = _world(view, "/world/leg/thigh/shank/foot")
    assert _sagittal_deg(R) == pytest.approx(foot)
    assert np.sign((R @ [1.0, 0.0, 0.0])[2]) == np.sign(foot)


def test_missing_thigh_follows_shank_and_normative_knee(view: LegView) -> None:
    view.show(_state(phase=0.72, thigh_angle_deg=None, shank_angle_deg=-50.0), LEG)
    R, _ = _world(view, "/world/leg/thigh")
    knee = knee_flexion_deg(0.72)
    assert 40.0 < knee < 70.0  # swing
    assert _sagittal_deg(R) == pytest.approx(-50.0 + knee)


def test_missing_shank_hides_the_leg_and_missing_foot_the_foot(view: LegView) -> None:
    scene = view.server.scene
    leg, foot = (
        scene.get_handle_by_name("/world/leg"),
        scene.get_handle_by_name("/world/leg/thigh/shank/foot/segment"),
    )
    assert leg is not None and foot is not None
    view.show(_state(shank_angle_deg=None, thigh_angle_deg=None), LEG)
    assert not leg.visible
    view.show(_state(foot_angle_deg=None), LEG)
    assert leg.visible and not foot.visible
    view.show(_state(foot_angle_deg=float("nan")), LEG)
    assert not foot.visible
    view.show(_state(), LEG)
    assert foot.visible


def test_ghost_is_posed_by_the_model_at_the_estimate(view: LegView, model: TrainedModel) -> None:
    state = _state(phase=0.62, stride_length_m=1.2, incline_deg=7.5, thigh_angle_deg=5.0)
    view.show(state, LEG)
    y = evaluate(model.coef, np.array([0.62]), np.array([1.2 / LEG]), np.array([7.5]))[0]
    R_thigh, _ = _world(view, "/world/ghost/thigh")
    R_shank, _ = _world(view, "/world/ghost/thigh/shank")
    R_foot, _ = _world(view, "/world/ghost/thigh/shank/foot")
    assert _sagittal_deg(R_thigh) == pytest.approx(5.0)  # shares the measured thigh
    assert _sagittal_deg(R_shank) == pytest.approx(y[OUT_SHANK])
    assert _sagittal_deg(R_foot) == pytest.approx(y[OUT_FOOT])
    ghost = view.server.scene.get_handle_by_name("/world/ghost")
    assert ghost is not None and ghost.visible
    view.show(_state(phase=float("nan")), LEG)
    assert not ghost.visible


def test_ground_tilts_by_the_incline_with_its_top_through_the_origin(view: LegView) -> None:
    view.show(_state(incline_deg=10.0), LEG)
    R, centre = _world(view, "/world/ground")
    assert _sagittal_deg(R) == pytest.approx(10.0)
    ground = _box(view, "/world/ground")
    top = centre + R @ [0.0, 0.0, ground.dimensions[2] / 2]
    np.testing.assert_allclose(top, 0.0, atol=1e-12)
    assert (R @ [1.0, 0.0, 0.0])[2] > 0  # uphill ahead


def test_leg_length_scales_the_segments(view: LegView) -> None:
    view.show(_state(), 1.06)
    thigh = _box(view, "/world/leg/thigh/segment")
    assert thigh.dimensions[2] == pytest.approx(THIGH_FRAC * 1.06 / 0.53)
    _, hip = _world(view, "/world/leg/thigh")
    assert hip[2] == pytest.approx(1.06)
    with pytest.raises(ValueError, match="leg length"):
        view.show(_state(), 0.0)


def test_panel_shows_session_phase_incline_torque(view: LegView) -> None:
    view.show(_state(phase=0.456, incline_deg=-5.0, torque_Nm=12.34), LEG, session_id=7)
    assert view._status.content == ("**session** 7  \n**phase** 0.46  \n**incline** -5.0 deg  \n**torque** 12.3 N m")
    view.show(_state(), LEG)
    assert view._status.content.startswith("**session** -  \n")
    assert status_markdown(None, None).count(" -") == 4


def test_show_skips_while_another_update_runs(view: LegView) -> None:
    view.show(_state(thigh_angle_deg=0.0), LEG)
    thigh = view.server.scene.get_handle_by_name("/world/leg/thigh")
    assert thigh is not None
    before = thigh.wxyz.copy()
    held, release = threading.Event(), threading.Event()

    def other_update() -> None:  # stands for another thread's show() in progress
        with view._lock:
            held.set()
            release.wait(5.0)

    other = threading.Thread(target=other_update)
    other.start()
    try:
        assert held.wait(5.0)
        t0 = time.monotonic()
        view.show(_state(thigh_angle_deg=30.0), LEG)
        elapsed = time.monotonic() - t0
    finally:
        release.set()
        other.join()
    assert elapsed < 0.5
    np.testing.assert_array_equal(thigh.wxyz, before)


def test_concurrent_shows_leave_a_consistent_pose(view: LegView) -> None:
    errors: list[BaseException] = []

    def run(angle: float) -> None:
        try:
            for _ in range(50):
                view.show(_state(thigh_angle_deg=angle, shank_angle_deg=angle), LEG)
        except BaseException as e:  # pragma: no cover - reported below
            errors.append(e)

    threads = [threading.Thread(target=run, args=(a,)) for a in (10.0, 20.0, 30.0)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    R_thigh, _ = _world(view, "/world/leg/thigh")
    R_shank, _ = _world(view, "/world/leg/thigh/shank")
    # Whichever update came last, it set thigh and shank together.
    assert _sagittal_deg(R_thigh) == pytest.approx(_sagittal_deg(R_shank))


def test_set_model_switches_the_ghost_from_the_states_predictions(model: TrainedModel) -> None:
    v = LegView(port=0)
    try:
        state = _state(phase=0.1, foot_pred_deg=3.0, shank_pred_deg=4.0)
        v.show(state, LEG)
        R, _ = _world(v, "/world/ghost/thigh/shank/foot")
        assert _sagittal_deg(R) == pytest.approx(3.0)
        v.set_model(model)
        v.show(state, LEG)
        R, _ = _world(v, "/world/ghost/thigh/shank/foot")
        y = evaluate(model.coef, np.array([0.1]), np.array([1.3 / LEG]), np.array([0.0]))[0]
        assert _sagittal_deg(R) == pytest.approx(y[OUT_FOOT])
    finally:
        v.close()


# --- pure helpers --------------------------------------------------------------------------------


@pytest.mark.parametrize("a", [0.3, -0.7])
def test_quat_y_turns_z_towards_x(a: float) -> None:
    np.testing.assert_allclose(_rot(quat_y(a)) @ [0.0, 0.0, 1.0], [math.sin(a), 0.0, math.cos(a)], atol=1e-15)


@pytest.mark.parametrize(
    ("phase", "stride", "incline"), [(0.0, 1.3, 0.0), (0.35, 1.0, 10.0), (0.8, 1.5, -7.5), (1.2, 1.3, 2.0)]
)
def test_segment_angles_match_the_gait_model(model: TrainedModel, phase: float, stride: float, incline: float) -> None:
    state = _state(phase=phase, stride_length_m=stride, incline_deg=incline, thigh_angle_deg=None)
    got = segment_angles_for(state, model, LEG)
    y = evaluate(model.coef, np.array([phase]), np.array([stride / LEG]), np.array([incline]))[0]
    assert got is not None
    assert got["foot_deg"] == pytest.approx(y[OUT_FOOT], abs=1e-12)
    assert got["shank_deg"] == pytest.approx(y[OUT_SHANK], abs=1e-12)
    # No thigh measured: the measured shank (0 deg) plus the normative knee.
    assert got["thigh_deg"] == pytest.approx(0.0 + knee_flexion_deg(phase))


def test_segment_angles_thigh_rules_and_fallbacks(model: TrainedModel) -> None:
    assert segment_angles_for(_state(thigh_angle_deg=12.0), model, LEG)["thigh_deg"] == 12.0  # type: ignore[index]
    no_leg = _state(thigh_angle_deg=None, shank_angle_deg=None, phase=0.5)
    got = segment_angles_for(no_leg, model, LEG)
    assert got is not None
    assert got["thigh_deg"] == pytest.approx(got["shank_deg"] + knee_flexion_deg(0.5))
    assert segment_angles_for(_state(), None, LEG) == {"thigh_deg": 0.0, "shank_deg": 2.0, "foot_deg": 1.0}
    assert segment_angles_for(_state(incline_deg=float("inf")), model, LEG) is None
    assert segment_angles_for(_state(foot_pred_deg=float("nan")), None, LEG) is None
    with pytest.raises(ValueError, match="leg length"):
        segment_angles_for(_state(), model, -1.0)


def test_normative_knee_is_periodic_and_flexes_in_swing() -> None:
    assert knee_flexion_deg(0.0) == pytest.approx(knee_flexion_deg(1.0))
    assert knee_flexion_deg(0.0) < 10.0 < 50.0 < knee_flexion_deg(0.72)
