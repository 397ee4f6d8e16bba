"""An open-source leg as a gaitscope device: the ``opensourceleg`` SDK's sensors in, its actuator's torque out.

Labs write their prosthesis and exoskeleton controllers on the ``opensourceleg`` SDK (3.5; actuators, joint
encoders, IMUs and loadcells behind abstract bases, each with an offline mode). :class:`OSLAdapter` turns
those objects into the two functions :class:`~gaitscope.sessions.devices.client.DeviceClient` takes::

    from opensourceleg.actuators.base import CONTROL_MODES
    from gaitscope.sessions.devices.client import DeviceClient
    from gaitscope.sessions.devices.osl import OSLAdapter

    with osl:  # an opensourceleg.robots.osl.OpenSourceLeg, homed, its ankle in current mode with its gains
        leg = OSLAdapter.from_robot(osl, max_torque_Nm=30.0)
        client = DeviceClient(url, token, rate_hz=200.0, read_frame=leg.read_frame,
                              apply_torque=leg.apply_torque, max_torque_Nm=leg.max_torque_Nm)
        client.run(stop)

:meth:`OSLAdapter.read_frame` calls each object's ``update()`` once and reads it into ``SensorFrame`` channels
(:class:`OSLMapping` says how: units, signs, offsets, the IMU's segment and axes, the contact thresholds);
:meth:`OSLAdapter.apply_torque` clamps the torque to ``[0, max_torque_Nm]`` (not a finite number: 0) and
commands it with the actuator's ``set_output_torque`` (N m at the joint, the SDK's unit). The client calls the
two from different threads; one lock keeps the SDK's objects, which are not thread-safe, to one caller at a time.

The SDK's units (its base classes' docstrings): joint positions in rad (``EncoderBase.position``,
``ActuatorBase.output_position``), IMU rates in rad/s and accelerations in m/s^2 (``IMUBase``), loadcell
forces in N (``LoadcellBase``). The ``imu_*`` channels are raw readings, specific force included: the
BNO055's accelerations are; the SDK's ``LordMicrostrainIMU`` reports an estimated linear acceleration (gravity
removed) and 0 for every gyro axis, so it should not be mapped (pass ``imu=None``).

Requires ``opensourceleg`` (``pip install --no-deps opensourceleg==3.5.0``: the package pins numpy < 2, but the
parts used here, its abstract bases and offline mode, run on numpy 2; ``tests/sessions/devices/test_osl.py``
runs them). Imports nothing of gaitscope but the channel table.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final, TypeAlias

from opensourceleg.actuators.base import CONTROL_MODES, ActuatorBase
from opensourceleg.sensors.base import EncoderBase, IMUBase, LoadcellBase, SensorBase

from gaitscope.estimators.channels import IMU_SEGMENTS, LIMITS

__all__ = ["TORQUE_MODES", "JointMap", "OSLAdapter", "OSLMapping"]

#: The actuator's control modes in which the SDK accepts ``set_output_torque``.
TORQUE_MODES: Final = frozenset({CONTROL_MODES.CURRENT, CONTROL_MODES.TORQUE})
_AXES: Final = ("x", "y", "z")

Frame = dict[str, float | bool | None]
#: Where a joint angle comes from: a joint encoder (``position``) or an actuator (``output_position``).
JointSource: TypeAlias = "EncoderBase | ActuatorBase"


@dataclass(frozen=True)
class JointMap:
    """One joint's angle in gaitscope's convention: ``deg = sign * degrees(rad) + offset_deg``.

    Attributes:
        sign: +1 when the SDK's positive direction is gaitscope's (knee flexion, ankle dorsiflexion), else -1.
        offset_deg: the gaitscope angle (deg) where the SDK reads 0 (its home).
    """

    sign: float = 1.0
    offset_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.sign not in (1.0, -1.0):
            raise ValueError(f"sign must be +1 or -1, got {self.sign}")
        if not math.isfinite(self.offset_deg):
            raise ValueError(f"offset_deg must be finite, got {self.offset_deg}")

    def degrees(self, rad: float) -> float:
        return self.sign * math.degrees(rad) + self.offset_deg


@dataclass(frozen=True)
class OSLMapping:
    """How an open-source leg's readings become ``SensorFrame`` channels, and gaitscope's torque its command.

    The defaults are the SDK's own conventions, from its walking example
    (``examples/fsm_walking_python_controller.py``) and its loadcell's docstring:

    Attributes:
        knee: ``knee_angle_deg`` from the knee's radians. Default +1, 0: the example's knee targets are
            positive in flexion (5 deg in stance, 60 deg in swing) from 0 at full extension, gaitscope's.
        ankle: ``ankle_angle_deg``. Default +1, 0: the example's ankle is negative in plantarflexion (-20 deg at
            push-off) and positive in dorsiflexion (25 deg in swing) from 0 at neutral, gaitscope's.
        imu_segment: the segment the IMU sits on (:data:`~gaitscope.estimators.channels.IMU_SEGMENTS`); its six
            channels are ``imu_{segment}_gyro_{x,y,z}_dps`` and ``imu_{segment}_accel_{x,y,z}_m_s2``. Default
            ``shank``: the leg's frame below the knee, where a prosthesis carries its IMU.
        imu_axes: which signed SDK axis is gaitscope's x (anterior), y (along the segment toward proximal) and z
            (to the subject's right), e.g. ``("-y", "+x", "+z")``. Default identity: no mounting is standard,
            so a lab states its own (the server's front end reports a flipped axis in ``imu_code``).
        force_sign: ``foot_force_N = force_sign * Fz``. Default -1: the SDK's loadcell ``fz`` is "positive
            downwards ... in quiet standing, a negative Fz value is expected", and its example's stance
            thresholds are negative (-0.25 body weight); ``foot_force_N`` is the load, >= 0.
        contact_on_N: ``foot_contact`` turns on when the load reaches it, and ``heel_strike`` is true at that
            sample. Default 50 N, under 10 % of an adult's weight: first contact, before the example's own
            stance thresholds (15 to 40 % of body weight), which mark later events.
        contact_off_N: ``foot_contact`` turns off below it. Default 25 N: the hysteresis keeps a load that
            hovers at the threshold from counting one heel strike many times.
        torque_sign: ``set_output_torque(torque_sign * torque_Nm)``. Default -1: gaitscope's torque is
            plantarflexion assistance (>= 0) and the SDK's ankle is positive in dorsiflexion.
    """

    knee: JointMap = field(default_factory=JointMap)
    ankle: JointMap = field(default_factory=JointMap)
    imu_segment: str = "shank"
    imu_axes: tuple[str, str, str] = ("+x", "+y", "+z")
    force_sign: float = -1.0
    contact_on_N: float = 50.0
    contact_off_N: float = 25.0
    torque_sign: float = -1.0

    def __post_init__(self) -> None:
        if self.imu_segment not in IMU_SEGMENTS:
            raise ValueError(f"imu_segment must be one of {IMU_SEGMENTS}, got {self.imu_segment!r}")
        axes = [a[-1:] for a in self.imu_axes]
        ok = len(self.imu_axes) == 3 and all(len(a) == 2 and a[0] in "+-" for a in self.imu_axes)
        if not ok or sorted(axes) != list(_AXES):
            raise ValueError(f"imu_axes must be x, y and z once each, signed ('+x', '-z', ...), got {self.imu_axes}")
        for name in ("force_sign", "torque_sign"):
            if getattr(self, name) not in (1.0, -1.0):
                raise ValueError(f"{name} must be +1 or -1, got {getattr(self, name)}")
        top = LIMITS["foot_force_N"][1]
        if not (0.0 <= self.contact_off_N < self.contact_on_N <= top):
            raise ValueError(
                f"need 0 <= contact_off_N < contact_on_N <= {top:g}, got {self.contact_off_N}, {self.contact_on_N}"
            )

    def imu_channels(self) -> tuple[tuple[str, str, float], ...]:
        """``(channel, SDK attribute, sign)`` for the six IMU channels, gyro then accelerometer, x, y, z."""
        rows = []
        for kind, sdk, unit in (("gyro", "gyro", "dps"), ("accel", "acc", "m_s2")):
            for axis, signed in zip(_AXES, self.imu_axes, strict=True):
                sign = -1.0 if signed[0] == "-" else 1.0
                rows.append((f"imu_{self.imu_segment}_{kind}_{axis}_{unit}", f"{sdk}_{signed[1]}", sign))
        return tuple(rows)


class OSLAdapter:
    """See the module docstring.

    Args:
        actuator: the actuator gaitscope's torque goes to, in current or torque mode (:data:`TORQUE_MODES`).
        knee, ankle: the joints' angle sources: a joint encoder (``position``) or an actuator
            (``output_position``, which ignores a series elastic's compliance); None: not measured.
        imu: the IMU (None: not measured). See the module docstring on which ones to map.
        loadcell: the loadcell (None: no foot force, contact or heel strike).
        mapping: units, signs and thresholds (:class:`OSLMapping`).
        max_torque_Nm: the adapter's limit: every command is clamped to ``[0, max_torque_Nm]``. Pass the same
            to ``DeviceClient``. Default 30 N m, a session's default bound on the torque.
        update: whether :meth:`read_frame` calls ``update()`` on each object (False: the lab's own loop does,
            holding :attr:`lock` while it does).

    Attributes:
        lock: held while the SDK's objects are used.
        commanded_Nm: the last torque commanded (gaitscope's sign, N m), sent as ``commanded_torque_Nm``.
    """

    def __init__(
        self,
        actuator: ActuatorBase,
        *,
        knee: JointSource | None = None,
        ankle: JointSource | None = None,
        imu: IMUBase | None = None,
        loadcell: LoadcellBase | None = None,
        mapping: OSLMapping | None = None,
        max_torque_Nm: float = 30.0,
        update: bool = True,
    ):
        if not isinstance(actuator, ActuatorBase):
            raise TypeError(f"actuator must be an opensourceleg ActuatorBase, got {type(actuator).__name__}")
        if actuator.mode not in TORQUE_MODES:
            raise ValueError(
                f"actuator {actuator.tag!r} is in {actuator.mode.name} mode; set_output_torque needs CURRENT or "
                "TORQUE: call actuator.set_control_mode(CONTROL_MODES.CURRENT) and set its current gains first"
            )
        for name, source, kinds in (
            ("knee", knee, (EncoderBase, ActuatorBase)),
            ("ankle", ankle, (EncoderBase, ActuatorBase)),
            ("imu", imu, (IMUBase,)),
            ("loadcell", loadcell, (LoadcellBase,)),
        ):
            if source is not None and not isinstance(source, kinds):
                raise TypeError(f"{name} must be one of {[k.__name__ for k in kinds]}, got {type(source).__name__}")
        if not (math.isfinite(max_torque_Nm) and max_torque_Nm > 0):
            raise ValueError(f"max_torque_Nm must be a number > 0, got {max_torque_Nm}")
        self.actuator, self.knee, self.ankle, self.imu, self.loadcell = actuator, knee, ankle, imu, loadcell
        self.mapping = mapping if mapping is not None else OSLMapping()
        self.max_torque_Nm = float(max_torque_Nm)
        self._update = update
        self.lock = threading.Lock()
        self.commanded_Nm = 0.0
        self._contact = False
        objects: list[ActuatorBase | SensorBase] = [actuator]
        for o in (knee, ankle, imu, loadcell):
            if o is not None and all(o is not p for p in objects):
                objects.append(o)
        self._objects = tuple(objects)
        self._imu_channels = self.mapping.imu_channels()

    @classmethod
    def from_robot(
        cls,
        robot: Any,
        *,
        torque_joint: str = "ankle",
        imu: IMUBase | None = None,
        mapping: OSLMapping | None = None,
        max_torque_Nm: float = 30.0,
    ) -> OSLAdapter:
        """An adapter for an SDK robot (``OpenSourceLeg``, any ``RobotBase``): its ``actuators[torque_joint]``
        takes the torque; each joint's angle comes from its joint encoder (``sensors["joint_encoder_knee"]``,
        ``..._ankle``) when it has one, else from its actuator; ``sensors["loadcell"]`` is the loadcell; the IMU
        is ``imu``, else the robot's one ``IMUBase`` sensor (more than one: name it)."""
        actuators: Mapping[str, ActuatorBase] = robot.actuators
        sensors: Mapping[str, SensorBase] = robot.sensors
        if torque_joint not in actuators:
            raise KeyError(f"the robot has no actuator {torque_joint!r} (it has {sorted(actuators)})")

        def joint(name: str) -> JointSource | None:
            encoder = sensors.get(f"joint_encoder_{name}")
            return encoder if isinstance(encoder, EncoderBase) else actuators.get(name)

        loadcell = sensors.get("loadcell")
        if imu is None:
            imus = [s for s in sensors.values() if isinstance(s, IMUBase)]
            if len(imus) > 1:
                raise ValueError(f"the robot has {len(imus)} IMUs: pass the one to map as imu=")
            imu = imus[0] if imus else None
        return cls(
            actuators[torque_joint],
            knee=joint("knee"),
            ankle=joint("ankle"),
            imu=imu,
            loadcell=loadcell if isinstance(loadcell, LoadcellBase) else None,
            mapping=mapping,
            max_torque_Nm=max_torque_Nm,
        )

    def channels(self) -> list[str]:
        """The channels :meth:`read_frame` fills (those of absent sensors left out)."""
        out = [n for n, s in (("knee_angle_deg", self.knee), ("ankle_angle_deg", self.ankle)) if s is not None]
        if self.imu is not None:
            out += [c for c, _, _ in self._imu_channels]
        if self.loadcell is not None:
            out += ["foot_force_N", "foot_contact", "heel_strike"]
        return [*out, "commanded_torque_Nm"]

    def read_frame(self) -> Frame:
        """The sensors now, as ``SensorFrame`` channels (a reading that is not a finite number is None)."""
        m = self.mapping
        frame: Frame = {}
        with self.lock:
            if self._update:
                for o in self._objects:
                    o.update()
            for name, source, jm in (("knee_angle_deg", self.knee, m.knee), ("ankle_angle_deg", self.ankle, m.ankle)):
                if source is not None:
                    rad = _finite(source.position if isinstance(source, EncoderBase) else source.output_position)
                    frame[name] = None if rad is None else jm.degrees(rad)
            if self.imu is not None:
                for channel, attr, sign in self._imu_channels:
                    v = _finite(getattr(self.imu, attr))
                    frame[channel] = None if v is None else sign * (math.degrees(v) if "_gyro_" in channel else v)
            if self.loadcell is not None:
                fz = _finite(self.loadcell.fz)
                force = None if fz is None else max(0.0, m.force_sign * fz)
                frame["foot_force_N"] = force
                was = self._contact
                if force is not None:
                    self._contact = force >= m.contact_on_N or (was and force >= m.contact_off_N)
                frame["foot_contact"] = self._contact if force is not None else None
                frame["heel_strike"] = self._contact and not was
            frame["commanded_torque_Nm"] = self.commanded_Nm
        return frame

    def apply_torque(self, torque_Nm: float) -> None:
        """Command ``torque_Nm`` (gaitscope's sign, N m), clamped to ``[0, max_torque_Nm]``; a torque that is not
        a finite number (NaN, infinite) commands 0."""
        t = float(torque_Nm)
        t = min(max(t, 0.0), self.max_torque_Nm) if math.isfinite(t) else 0.0
        with self.lock:
            self.actuator.set_output_torque(self.mapping.torque_sign * t)
            self.commanded_Nm = t


def _finite(value: Any) -> float | None:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None
