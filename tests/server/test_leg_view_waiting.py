"""The leg view before any data and as a client finds it: a grey standing leg under "waiting for data"
(never a blank view), viser's panel minimized, no share button, and the camera on the leg."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import viser
from viser import _messages

from gaitscope.server.leg_view import (
    CAMERA_FOV_DEG,
    CAMERA_LOOK_AT,
    CAMERA_POSITION,
    LEG,
    NO_LEG_TEXT,
    WAITING,
    WAITING_TEXT,
    LegView,
)
from gaitscope.sessions.schema import GaitState

SEGMENTS = [f"{LEG}{node}/segment" for node in ("/thigh", "/thigh/shank", "/thigh/shank/foot")]
BLUE, GREY = (40, 110, 200), (150, 150, 150)


def _state(**kw: Any) -> GaitState:
    base: dict[str, Any] = dict(
        seq=0, t=0.0, phase=0.3, phase_rate=1.0, stride_length_m=1.3, incline_deg=0.0, torque_Nm=12.5,
        tbe_phase=0.3, heel_strike=False, backup_reset=False, foot_angle_deg=5.0, shank_angle_deg=-10.0,
        thigh_angle_deg=15.0, foot_pred_deg=1.0, shank_pred_deg=2.0, recv_ns=0,
    )  # fmt: skip
    return GaitState(**(base | kw))


@pytest.fixture
def view() -> Iterator[LegView]:
    v = LegView(port=0)
    yield v
    v.close()


def _handle(view: LegView, name: str) -> Any:
    handle = view.server.scene.get_handle_by_name(name)
    assert handle is not None, name
    return handle


def _replayed(view: LegView) -> list[object]:
    """The messages a client gets on connecting (viser's persistent broadcast buffer)."""
    buffer = view.server._websock_server.get_message_buffer()  # no public accessor in viser 1.1
    return list(buffer.message_from_id.values())


def test_before_any_data_the_leg_stands_in_grey_under_a_label(view: LegView) -> None:
    assert view.waiting
    leg, ghost = _handle(view, LEG), _handle(view, "/world/ghost")
    assert leg.visible and not ghost.visible
    for name in SEGMENTS:
        box = _handle(view, name)
        assert box.visible
        assert tuple(box.color) == GREY
    for node in ("/thigh", "/thigh/shank", "/thigh/shank/foot"):  # standing straight: no rotation
        np.testing.assert_allclose(_handle(view, LEG + node).wxyz, [1.0, 0.0, 0.0, 0.0], atol=1e-12)
    label = _handle(view, WAITING)
    assert isinstance(label, viser.LabelHandle)
    assert label.text == WAITING_TEXT == "Waiting for data"
    assert label.visible
    assert label.position[2] > 0.88  # above the hip


def test_first_state_paints_the_leg_blue_and_hides_the_label(view: LegView) -> None:
    view.show(_state(), 0.9)
    assert not view.waiting
    assert not _handle(view, WAITING).visible
    for name in SEGMENTS:
        assert tuple(_handle(view, name).color) == BLUE
    assert _handle(view, "/world/ghost").visible
    view.show(_state(thigh_angle_deg=None, shank_angle_deg=None), 0.9)  # no shank: hidden; the ghost stays
    assert not _handle(view, LEG).visible and _handle(view, "/world/ghost").visible
    assert not view.waiting and not _handle(view, WAITING).visible


def test_a_state_with_neither_leg_says_so_instead_of_a_bare_floor(view: LegView) -> None:
    view.show(_state(thigh_angle_deg=None, shank_angle_deg=None, phase=float("nan")), 0.9)
    assert not _handle(view, LEG).visible and not _handle(view, "/world/ghost").visible
    label = _handle(view, WAITING)
    assert label.visible and label.text == NO_LEG_TEXT == "No leg angles at this moment"
    assert not view.waiting
    view.show(_state(), 0.9)
    assert not label.visible
    assert _handle(view, LEG).visible


def test_panel_starts_minimized_without_share_button_or_logo(view: LegView) -> None:
    messages = _replayed(view)
    collapsed = [m for m in messages if isinstance(m, _messages.GuiSetPanelCollapsedMessage)]
    assert [m.collapsed for m in collapsed] == [True]
    themes = [m for m in messages if isinstance(m, _messages.ThemeConfigurationMessage)]
    assert len(themes) == 1
    assert not themes[0].show_share_button and not themes[0].show_logo
    assert themes[0].control_layout == "floating"  # "collapsible" is deprecated in viser 1.1


def test_camera_looks_at_the_leg_from_its_right(view: LegView) -> None:
    cam = view.server.initial_camera
    np.testing.assert_allclose(cam.position, CAMERA_POSITION)
    np.testing.assert_allclose(cam.look_at, CAMERA_LOOK_AT)
    assert cam.fov == pytest.approx(math.radians(CAMERA_FOV_DEG))
    # From the subject's right (-y), level with the knee, the hip and the ground both in the field.
    position, look_at = np.array(CAMERA_POSITION), np.array(CAMERA_LOOK_AT)
    distance = float(np.linalg.norm(look_at - position))
    half_height = distance * math.tan(math.radians(CAMERA_FOV_DEG) / 2)
    assert position[1] < 0 and abs(position[0] - look_at[0]) < 1e-9
    assert look_at[2] + half_height > 0.9 + 0.1 and look_at[2] - half_height < -0.1  # hip and floor in view
    assert 2 * half_height < 2.0  # and the leg still fills most of the height
