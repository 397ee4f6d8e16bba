"""The open-source leg adapter on the ``opensourceleg`` SDK's own offline mode (``OfflineMixin``), on numpy 2.

The devices here are the smallest subclasses of the SDK's abstract bases (``ActuatorBase``, ``EncoderBase``,
``IMUBase``, ``LoadcellBase``): the SDK's concrete drivers import their hardware libraries (flexsea, smbus2,
moteus, can) at import time. Every hardware method of these raises, so a test passes only through the SDK's
offline stubs. Offline, the SDK makes each object its own ``Offline<Class>`` whose hardware properties return
constants; :func:`_reads` replaces those constants with known values (or functions of the simulated walk), and
the stubs record what the adapter commanded.
"""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from opensourceleg.actuators.base import CONTROL_MODE_CONFIGS, CONTROL_MODES, MOTOR_CONSTANTS, ActuatorBase
from opensourceleg.logging.logger import LOGGER, Logger, LogLevel
from opensourceleg.sensors.base import EncoderBase, IMUBase, LoadcellBase

from gaitscope.server.bench.launch import RunningServer, start_server
from gaitscope.sessions.devices.client import DeviceClient
from gaitscope.sessions.devices.osl import JointMap, OSLAdapter, OSLMapping
from gaitscope.sessions.schema import CHANNELS, SensorFrame
from tests.device_tokens import device_session
from tests.walks import walk_frames

G0 = 9.80665


@pytest.fixture(autouse=True, scope="module")
def _sdk_log(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The SDK's logger writes a file on its first message, in the working directory unless told otherwise."""
    where = str(tmp_path_factory.mktemp("osl-log"))
    Logger(log_path=where, file_name="osl", file_level=LogLevel.WARNING, stream_level=LogLevel.WARNING)
    LOGGER.set_file_name("osl")  # a handler already open elsewhere moves here


class _Hardware:
    """Records the SDK's offline stubs' calls (``_offline_method_stub`` takes every hardware method offline)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.on_update: Callable[[], None] | None = None
        super().__init__(*args, **kwargs)

    def _offline_method_stub(self, method_name: str, *args: Any, **kwargs: Any) -> None:
        self.calls.append((method_name, args))
        if method_name == "update" and self.on_update is not None:
            self.on_update()
        super()._offline_method_stub(method_name, *args, **kwargs)  # type: ignore[misc]


def _hardware(*_: Any, **__: Any) -> Any:
    raise AssertionError("a hardware method ran: offline mode did not stub it")


_HW = property(_hardware)


class Actuator(_Hardware, ActuatorBase):
    _CONTROL_MODE_CONFIGS = CONTROL_MODE_CONFIGS()  # type: ignore[assignment]
    start = stop = update = home = _hardware
    set_motor_voltage = set_motor_current = set_motor_position = set_motor_torque = set_output_torque = _hardware
    set_current_gains = set_position_gains = _set_impedance_gains = _hardware
    motor_position = motor_velocity = motor_voltage = motor_current = motor_torque = _HW  # type: ignore[assignment]
    case_temperature = winding_temperature = _HW  # type: ignore[assignment]


class Encoder(_Hardware, EncoderBase):
    start = stop = update = _hardware
    data = is_streaming = position = velocity = _HW  # type: ignore[assignment]


class Imu(_Hardware, IMUBase):
    start = stop = update = _hardware
    data = is_streaming = acc_x = acc_y = acc_z = gyro_x = gyro_y = gyro_z = _HW  # type: ignore[assignment]


class Loadcell(_Hardware, LoadcellBase):
    start = stop = update = calibrate = reset = _hardware
    data = is_streaming = fx = fy = fz = mx = my = mz = is_calibrated = _HW  # type: ignore[assignment]


def _reads(device: Any, **values: float | Callable[[], float]) -> None:
    """Sets what an offline device reads: its own ``Offline<Class>``'s constant properties replaced."""
    cls = type(device)
    assert device.is_offline and cls.__name__ == f"Offline{cls.__mro__[1].__name__}", cls
    for name, v in values.items():
        assert isinstance(getattr(cls, name), property), name
        setattr(cls, name, property(lambda _self, v=v: v() if callable(v) else v))


def _actuator(mode: CONTROL_MODES = CONTROL_MODES.CURRENT, gear_ratio: float = 9.0) -> Actuator:
    a = Actuator(
        tag="ankle",
        gear_ratio=gear_ratio,
        motor_constants=MOTOR_CONSTANTS(MOTOR_COUNT_PER_REV=16384, NM_PER_AMP=0.1133, MAX_CASE_TEMPERATURE=80.0,
                                        MAX_WINDING_TEMPERATURE=110.0),
        offline=True,
    )  # fmt: skip
    a.set_control_mode(mode)
    return a


def _torques(a: Actuator) -> list[float]:
    """What the adapter commanded, in the SDK's unit (N m at the joint, the SDK's sign)."""
    assert all(name != "set_motor_torque" for name, _ in a.calls)
    return [args[0] for name, args in a.calls if name == "set_output_torque"]


def test_the_sdk_runs_offline_on_numpy_2() -> None:
    """The finding behind ``pip install --no-deps``: the SDK pins numpy < 2; its bases and offline mode run on 2."""
    import numpy as np

    assert int(np.__version__.split(".")[0]) >= 2
    a = _actuator()
    assert a.is_offline and a.mode is CONTROL_MODES.CURRENT and a.case_temperature == 25.0
    assert a.MOTOR_CONSTANTS.RAD_PER_COUNT == pytest.approx(2 * math.pi / 16384)  # numpy's pi, a python float
    a.set_output_torque(3.0)
    a.update()
    assert a.calls == [("set_output_torque", (3.0,)), ("update", ())]
    e = Encoder(tag="knee", offline=True)
    assert e.is_streaming and e.position == 0.0  # the SDK's offline default


def test_joint_encoders_and_actuators_map_to_the_joint_channels() -> None:
    knee, ankle = Encoder(tag="knee", offline=True), _actuator(gear_ratio=9.0)
    _reads(knee, position=0.5)
    _reads(ankle, motor_position=-0.9)  # output_position = motor / gear ratio = -0.1 rad: plantarflexion
    frame = OSLAdapter(ankle, knee=knee, ankle=ankle).read_frame()
    assert frame["knee_angle_deg"] == pytest.approx(28.64789, abs=1e-5)
    assert frame["ankle_angle_deg"] == pytest.approx(-5.72958, abs=1e-5)
    mapped = OSLMapping(knee=JointMap(sign=-1.0, offset_deg=5.0), ankle=JointMap(offset_deg=30.0))
    frame = OSLAdapter(ankle, knee=knee, ankle=ankle, mapping=mapped).read_frame()
    assert frame["knee_angle_deg"] == pytest.approx(-28.64789 + 5.0, abs=1e-5)
    assert frame["ankle_angle_deg"] == pytest.approx(-5.72958 + 30.0, abs=1e-5)


def test_the_imu_maps_to_its_segments_raw_channels_in_deg_per_s_and_m_per_s2() -> None:
    imu = Imu(tag="imu", offline=True)
    _reads(imu, gyro_x=1.0, gyro_y=-0.5, gyro_z=0.25, acc_x=0.3, acc_y=9.7, acc_z=-0.2)
    frame = OSLAdapter(_actuator(), imu=imu).read_frame()
    deg = math.degrees
    assert frame == pytest.approx({
        "imu_shank_gyro_x_dps": deg(1.0), "imu_shank_gyro_y_dps": deg(-0.5), "imu_shank_gyro_z_dps": deg(0.25),
        "imu_shank_accel_x_m_s2": 0.3, "imu_shank_accel_y_m_s2": 9.7, "imu_shank_accel_z_m_s2": -0.2,
        "commanded_torque_Nm": 0.0,
    })  # fmt: skip
    # mounted turned: the IMU's y is anterior, its -x along the shank toward the knee, on the thigh
    turned = OSLMapping(imu_segment="thigh", imu_axes=("+y", "-x", "+z"))
    frame = OSLAdapter(_actuator(), imu=imu, mapping=turned).read_frame()
    assert frame["imu_thigh_gyro_x_dps"] == pytest.approx(deg(-0.5))
    assert frame["imu_thigh_gyro_y_dps"] == pytest.approx(-deg(1.0))
    assert frame["imu_thigh_accel_x_m_s2"] == pytest.approx(9.7)
    assert frame["imu_thigh_accel_y_m_s2"] == pytest.approx(-0.3)
    assert frame["imu_thigh_accel_z_m_s2"] == pytest.approx(-0.2)


def test_the_loadcell_gives_the_load_contact_and_heel_strikes_with_hysteresis() -> None:
    cell = Loadcell(tag="loadcell", offline=True)
    fz = [0.0]
    _reads(cell, fz=lambda: fz[0])
    leg = OSLAdapter(_actuator(), loadcell=cell)  # on at 50 N, off below 25 N
    seen = []
    for load in (0.0, 30.0, 60.0, 700.0, 40.0, 24.0, 49.0, 26.0, 60.0, -20.0):
        fz[0] = -load  # the SDK's Fz: positive downwards, negative under load
        f = leg.read_frame()
        seen.append((f["foot_force_N"], f["foot_contact"], f["heel_strike"]))
    assert seen == [
        (0.0, False, False), (30.0, False, False), (60.0, True, True), (700.0, True, False), (40.0, True, False),
        (24.0, False, False), (49.0, False, False), (26.0, False, False), (60.0, True, True),
        (0.0, False, False),  # a pull on the loadcell is no load
    ]  # fmt: skip


def test_a_reading_that_is_not_a_number_is_not_sent() -> None:
    knee, cell, imu = Encoder(tag="knee", offline=True), Loadcell(tag="lc", offline=True), Imu(tag="imu", offline=True)
    _reads(knee, position=math.nan)
    _reads(cell, fz=math.inf)
    _reads(imu, gyro_z=math.nan)
    frame = OSLAdapter(_actuator(), knee=knee, imu=imu, loadcell=cell).read_frame()
    assert frame["knee_angle_deg"] is None and frame["imu_shank_gyro_z_dps"] is None
    assert frame["foot_force_N"] is None and frame["foot_contact"] is None and frame["heel_strike"] is False
    assert frame["imu_shank_gyro_x_dps"] == 0.0  # the SDK's offline default


def test_every_channel_is_a_sensor_frame_channel_and_the_frame_validates() -> None:
    knee, ankle, imu, cell = (Encoder(tag="k", offline=True), Encoder(tag="a", offline=True),
                              Imu(tag="i", offline=True), Loadcell(tag="l", offline=True))  # fmt: skip
    _reads(knee, position=0.2)
    _reads(ankle, position=0.1)
    _reads(imu, acc_y=G0)
    _reads(cell, fz=-500.0)
    leg = OSLAdapter(_actuator(), knee=knee, ankle=ankle, imu=imu, loadcell=cell)
    frame = leg.read_frame()
    assert set(frame) == set(leg.channels()) and len(frame) == 2 + 6 + 3 + 1
    assert set(frame) <= set(CHANNELS)
    parsed = SensorFrame.model_validate({"type": "frame", "seq": 1, "t": 0.0, **frame})
    assert parsed.plausible()[1] == 0  # no channel outside its plausible range
    assert (
        parsed.foot_force_N == 500.0 and parsed.heel_strike is True and parsed.knee_angle_deg == frame["knee_angle_deg"]
    )


def test_each_device_is_updated_once_a_frame_and_not_when_the_lab_updates() -> None:
    act, knee, cell = _actuator(), Encoder(tag="knee", offline=True), Loadcell(tag="lc", offline=True)
    OSLAdapter(act, knee=knee, ankle=act, loadcell=cell).read_frame()  # the actuator is also the ankle's source
    assert [n for n, _ in act.calls] == ["update"]
    assert [n for n, _ in knee.calls] == ["update"] and [n for n, _ in cell.calls] == ["update"]
    OSLAdapter(act, knee=knee, update=False).read_frame()
    assert [n for n, _ in act.calls] == ["update"] and [n for n, _ in knee.calls] == ["update"]


def test_the_torque_goes_to_set_output_torque_clamped_signed_and_zero_when_not_a_number() -> None:
    act = _actuator()
    leg = OSLAdapter(act, max_torque_Nm=20.0)
    for torque in (10.0, 20.0, 35.0, -4.0, math.nan, math.inf, -math.inf, 0.0, 7.5):
        leg.apply_torque(torque)
    # N m at the joint; -1: gaitscope's plantarflexion torque is negative on the SDK's ankle (dorsiflexion +)
    assert _torques(act) == [-10.0, -20.0, -20.0, 0.0, 0.0, 0.0, 0.0, 0.0, -7.5]
    assert leg.commanded_Nm == 7.5 and leg.read_frame()["commanded_torque_Nm"] == 7.5
    act2 = _actuator(CONTROL_MODES.TORQUE)
    OSLAdapter(act2, mapping=OSLMapping(torque_sign=1.0), max_torque_Nm=5.0).apply_torque(6.0)
    assert _torques(act2) == [5.0]


def test_an_adapter_that_makes_no_sense_is_refused() -> None:
    with pytest.raises(ValueError, match="IDLE mode"):
        OSLAdapter(_actuator(CONTROL_MODES.IDLE))
    with pytest.raises(ValueError, match="POSITION mode"):
        OSLAdapter(_actuator(CONTROL_MODES.POSITION))
    with pytest.raises(TypeError):
        OSLAdapter(_actuator(), imu=Encoder(tag="k", offline=True))  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        OSLAdapter(SimpleNamespace(mode=CONTROL_MODES.CURRENT))  # type: ignore[arg-type]
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            OSLAdapter(_actuator(), max_torque_Nm=bad)
    for kwargs in (
        {"imu_segment": "head"}, {"imu_axes": ("+x", "+x", "+z")}, {"imu_axes": ("x", "y", "z")},
        {"force_sign": 2.0}, {"torque_sign": 0.0}, {"contact_on_N": 20.0, "contact_off_N": 30.0},
    ):  # fmt: skip
        with pytest.raises(ValueError):
            OSLMapping(**kwargs)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        JointMap(sign=0.5)


def test_from_robot_prefers_the_joint_encoders_and_drives_the_ankle() -> None:
    knee_act, ankle_act = _actuator(), _actuator()
    enc, cell = Encoder(tag="joint_encoder_knee", offline=True), Loadcell(tag="loadcell", offline=True)
    _reads(enc, position=0.3)
    _reads(knee_act, motor_position=9.0)  # 1 rad at the output: not what the knee's angle is read from
    _reads(ankle_act, motor_position=0.9)
    robot = SimpleNamespace(
        actuators={"knee": knee_act, "ankle": ankle_act}, sensors={"joint_encoder_knee": enc, "loadcell": cell}
    )
    leg = OSLAdapter.from_robot(robot)
    assert leg.actuator is ankle_act and leg.knee is enc and leg.ankle is ankle_act and leg.loadcell is cell
    assert leg.imu is None
    frame = leg.read_frame()
    assert frame["knee_angle_deg"] == pytest.approx(math.degrees(0.3))
    assert frame["ankle_angle_deg"] == pytest.approx(math.degrees(0.1))
    with pytest.raises(KeyError):
        OSLAdapter.from_robot(robot, torque_joint="hip")
    imu, other = Imu(tag="imu", offline=True), Imu(tag="thigh_imu", offline=True)
    robot.sensors["imu"] = imu
    assert OSLAdapter.from_robot(robot).imu is imu
    robot.sensors["thigh_imu"] = other
    with pytest.raises(ValueError, match="2 IMUs"):
        OSLAdapter.from_robot(robot)
    assert OSLAdapter.from_robot(robot, imu=other).imu is other


def test_importing_the_adapter_imports_neither_the_server_nor_the_estimators() -> None:
    code = "import sys, gaitscope.sessions.devices.osl; print([m for m in sys.modules if m.startswith('gaitscope')])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=Path.cwd())
    loaded = set(json.loads(out.stdout.strip().replace("'", '"')))
    assert loaded <= {
        "gaitscope", "gaitscope.sessions", "gaitscope.sessions.devices", "gaitscope.sessions.devices.osl",
        "gaitscope.estimators", "gaitscope.estimators.channels",
    }, loaded  # fmt: skip


# --- end to end: a simulated walk through the SDK's offline devices, a real server -------------------------------
RATE = 100.0


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningServer]:
    running = start_server(tmp_path_factory.mktemp("osl-device"), "--no-leg-view", "--no-demo")
    try:
        yield running
    finally:
        running.stop()


def _session(base: str) -> tuple[int, str]:
    sid, token, _ = device_session(base, f"OSL{time.monotonic_ns() % 10**6}", RATE)
    return sid, token


class Walk:
    """A level walk's frames, looped, one a device update: the joint angles a leg's encoders read, a shank IMU
    that reads the shank's rate and gravity (quiet, in its segment axes), and the load: 700 N for the first
    60 % of each stride (from the walk's heel strikes), none in swing."""

    def __init__(self) -> None:
        frames = walk_frames(12, rate_hz=RATE)
        strikes = [i for i, f in enumerate(frames) if f.heel_strike]
        stance = [False] * len(frames)
        for a, b in itertools.pairwise(strikes):
            for i in range(a, a + round(0.6 * (b - a))):
                stance[i] = True
        self.frames, self.stance, self.k = frames[strikes[0] : strikes[-1]], stance[strikes[0] : strikes[-1]], 0

    def step(self) -> None:
        self.k += 1

    def now(self, what: str) -> float:
        f, loaded = self.frames[self.k % len(self.frames)], self.stance[self.k % len(self.frames)]
        shank = math.radians(f.shank_angle_deg)
        return {
            "knee": math.radians(f.thigh_angle_deg - f.shank_angle_deg),  # flexion
            "ankle": math.radians(f.foot_angle_deg - f.shank_angle_deg),  # dorsiflexion
            "gyro_z": math.radians(f.shank_vel_dps),
            "acc_x": G0 * math.sin(shank),
            "acc_y": G0 * math.cos(shank),
            "fz": -700.0 if loaded else 0.0,
        }[what]


@pytest.mark.slow
def test_an_offline_leg_streams_to_a_real_server_and_applies_its_torque_within_bounds(server: RunningServer) -> None:
    sid, token = _session(server.base)
    walk = Walk()
    ankle = _actuator()
    ankle.on_update = walk.step
    knee, imu, cell = Encoder(tag="knee", offline=True), Imu(tag="imu", offline=True), Loadcell(tag="lc", offline=True)
    _reads(knee, position=lambda: walk.now("knee"))
    _reads(ankle, motor_position=lambda: ankle.gear_ratio * walk.now("ankle"))
    _reads(imu, gyro_z=lambda: walk.now("gyro_z"), acc_x=lambda: walk.now("acc_x"), acc_y=lambda: walk.now("acc_y"))
    _reads(cell, fz=lambda: walk.now("fz"))
    leg = OSLAdapter(ankle, knee=knee, ankle=ankle, imu=imu, loadcell=cell, max_torque_Nm=30.0)
    client = DeviceClient(
        f"ws://127.0.0.1:{server.port}/ws/devices/{sid}", token, rate_hz=RATE,
        read_frame=leg.read_frame, apply_torque=leg.apply_torque, max_torque_Nm=leg.max_torque_Nm,
    )  # fmt: skip
    stop = threading.Event()
    thread = threading.Thread(target=client.run, args=(stop,), daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 40.0
        while not any(t < -5.0 for t in _torques(ankle)):  # push-off, past the server's soft start
            assert time.monotonic() < deadline, ("no push-off torque", client.reports[-8:], walk.k)
            time.sleep(0.05)
        time.sleep(2.0)
    finally:
        t_stop = client.clock()
        stop.set()
        thread.join(timeout=10)
    assert not thread.is_alive()
    commanded = _torques(ankle)
    assert all(math.isfinite(t) and -30.0 <= t <= 0.0 for t in commanded), [t for t in commanded if not -30 <= t <= 0]
    assert commanded[-1] == 0.0 and leg.commanded_Nm == 0.0  # stopped: the torque off
    assert walk.k > 3 * RATE  # seconds of frames, one device update each
    # every frame valid (no notice); a trip, which a loaded machine can cause, is the watchdog's business
    kinds = {r.kind for r in client.reports if r.t < t_stop}
    assert "connected" in kinds and not kinds & {"notice", "refused"}, client.reports
