"""The one channel table: every sensor channel a device or a source may send, by its wire name.

Each channel has a unit, a meaning, a plausible range and a group. Everything else reads this table:
``gaitscope.sessions.schema`` builds the ``SensorFrame`` fields, ``CHANNELS`` and ``SENSOR_LIMITS`` from
it, the estimators name their inputs by its names (``Estimator.inputs``) and take their bounds from it
(:func:`limits`). Pure data at the bottom of the layers: no imports from the rest of gaitscope.

Names end in their unit (``_deg``, ``_dps`` for deg/s, ``_m``, ``_m_s``, ``_m_s2``, ``_N``, ``_A``,
``_Nm``; a flag has none). Sign conventions: sagittal angles are seen from the subject's right with
forward to the right and counter-clockwise positive; thigh and shank from vertical ((+) distal end ahead
of proximal), foot from horizontal ((+) toes up); hip and knee (+) in flexion, ankle (+) in
dorsiflexion; ``_contra`` channels are the other leg's, same conventions. IMU axes are the segment's
(ISB, OpenSim): x anterior, y along the segment toward proximal (for the foot: up when flat), z to the
subject's right, so a (+) sagittal rotation is (+) about z; accelerometers read specific force (+9.81
m/s^2 on an axis pointing up at rest). The stance foot is the foot that touched down last;
centre-of-mass channels are a lab's measurement (motion capture), when it has one.

Plausible ranges: angles +/-180 deg; angular rates +/-4000 deg/s (the largest full scale of common MEMS
gyros, e.g. ICM-42688 and BMI088 reach +/-2000, ADIS16 parts +/-4000); accelerations +/-157 m/s^2 (16 g,
the largest common MEMS full scale); positions +/-3 m; forces 0..5000 N. A value outside its range, or
non-finite, is treated as missing for that sample.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final, NamedTuple

__all__ = ["CHANNELS", "GROUPS", "IMU_SEGMENTS", "LIMITS", "Channel", "limits", "positions", "span", "symmetric_bound"]


class Channel(NamedTuple):
    """One sensor channel.

    Attributes:
        unit: ``deg``, ``deg/s``, ``m``, ``m/s``, ``m/s^2``, ``N``, ``A``, ``N m``; ``bool`` for a flag.
        description: what it is (the field description on the wire).
        group: one of :data:`GROUPS`.
        limits: plausible ``(low, high)`` range, bounds included; None for a flag.
    """

    unit: str
    description: str
    group: str
    limits: tuple[float, float] | None = None


#: The groups of :attr:`Channel.group`.
GROUPS: Final = ("segment", "heel", "joint", "imu", "foot", "event", "device", "treadmill", "step", "com")
#: Segments that carry an IMU; ``_contra`` ones are on the contralateral leg.
IMU_SEGMENTS: Final = ("pelvis", "thigh", "shank", "foot", "thigh_contra", "shank_contra", "foot_contra")

_ANGLE, _RATE, _ACCEL, _POSITION = (-180.0, 180.0), (-4000.0, 4000.0), (-157.0, 157.0), (-3.0, 3.0)
_SIDES: Final = (("", "ipsilateral"), ("_contra", "contralateral"))
_SEGMENT_ANGLE: Final = {"foot": "from horizontal, (+) toes up", "shank": "from vertical", "thigh": "from vertical"}
#: Where each IMU sits, for the descriptions.
_IMU_PLACE: Final = {
    "pelvis": "pelvis (sacrum)",
    **{f"{seg}{side}": f"{who} {seg}" for seg in ("thigh", "shank", "foot") for side, who in _SIDES},
}


def _segment(seg: str, side: str, who: str) -> dict[str, Channel]:
    how = _SEGMENT_ANGLE[seg]
    return {
        f"{seg}_angle{side}_deg": Channel("deg", f"{who} {seg} angle {how}", "segment", _ANGLE),
        f"{seg}_vel{side}_dps": Channel("deg/s", f"{who} {seg} angular velocity", "segment", _RATE),
    }


def _table() -> dict[str, Channel]:
    """Every channel, in the order of the ``SensorFrame`` fields: the version 1 channels first (foot,
    shank, heel, thigh), the other leg, joint encoders, raw IMUs, feet, device, treadmill, lab."""
    t: dict[str, Channel] = {**_segment("foot", "", "ipsilateral"), **_segment("shank", "", "ipsilateral")}
    t["heel_forward_m"] = Channel("m", "ipsilateral heel forward of the hip, raw (not high-passed)", "heel", _POSITION)
    t["heel_up_m"] = Channel("m", "ipsilateral heel above the hip, raw (not high-passed)", "heel", _POSITION)
    t.update(_segment("thigh", "", "ipsilateral"))
    for seg in _SEGMENT_ANGLE:
        t.update(_segment(seg, "_contra", "contralateral"))
    for side, who in _SIDES:
        for joint, how in (("hip", "flexion"), ("knee", "flexion"), ("ankle", "dorsiflexion")):
            t[f"{joint}_angle{side}_deg"] = Channel("deg", f"{who} {joint} {how} (joint encoder)", "joint", _ANGLE)
    for seg in IMU_SEGMENTS:
        place = _IMU_PLACE[seg]
        for axis in "xyz":
            t[f"imu_{seg}_gyro_{axis}_dps"] = Channel("deg/s", f"{place} IMU, rate about {axis}", "imu", _RATE)
        for axis in "xyz":
            what = f"{place} IMU, specific force along {axis}"
            t[f"imu_{seg}_accel_{axis}_m_s2"] = Channel("m/s^2", what, "imu", _ACCEL)
    for side, who in _SIDES:
        t[f"foot_force{side}_N"] = Channel("N", f"vertical force under the {who} foot", "foot", (0.0, 5000.0))
    for side, who in _SIDES:
        t[f"foot_contact{side}"] = Channel("bool", f"{who} foot on the ground", "foot")
    t["heel_strike"] = Channel("bool", "an ipsilateral heel strike at this sample", "event")
    t["motor_current_A"] = Channel("A", "device motor current, (+) toward (+) torque", "device", (-60.0, 60.0))
    t["commanded_torque_Nm"] = Channel(
        "N m", "torque the device commands, signed as torque_Nm", "device", (-200.0, 200.0)
    )
    t["belt_speed_m_s"] = Channel("m/s", "treadmill belt speed, when known", "treadmill", (0.0, 5.0))
    t["step_length_m"] = Channel(
        "m", "last step: forward distance between the feet at the last touchdown", "step", (0.0, 3.0)
    )
    directions = (("forward", "forward"), ("lateral", "(+) to the subject's right"), ("up", "up"))
    for axis, how in directions:
        t[f"com_{axis}_m"] = Channel("m", f"centre of mass relative to the stance foot, {how}", "com", _POSITION)
    for axis, how in directions:
        what = f"centre-of-mass velocity relative to the stance foot, {how}"
        t[f"com_{axis}_vel_m_s"] = Channel("m/s", what, "com", (-10.0, 10.0))
    return t


#: Every sensor channel by name, in wire order.
CHANNELS: Final[dict[str, Channel]] = _table()
#: The plausible range of every numeric channel (flags have none), in wire order.
LIMITS: Final[dict[str, tuple[float, float]]] = {n: c.limits for n, c in CHANNELS.items() if c.limits is not None}


def limits(names: Sequence[str]) -> tuple[tuple[float, float], ...]:
    """The plausible ranges of ``names``, in their order.

    Raises:
        KeyError: a name is not a numeric channel of :data:`CHANNELS`.
    """
    return tuple(LIMITS[n] for n in names)


def symmetric_bound(*names: str) -> float:
    """The bound ``b`` of channels whose plausible ranges are all ``(-b, b)``, for estimators that test
    ``abs(value) <= b`` (e.g. in compiled code).

    Raises:
        KeyError: a name is not a numeric channel of :data:`CHANNELS`.
        ValueError: no names, or ranges that are not one symmetric range.
    """
    ranges = set(limits(names))
    if len(ranges) != 1 or (r := ranges.pop())[0] != -r[1]:
        raise ValueError(f"{names} do not share one range symmetric about 0")
    return r[1]


def positions(order: Sequence[str], *names: str) -> tuple[int, ...]:
    """Where each of ``names`` sits in ``order`` (an estimator's ``inputs`` then ``optional_inputs``: the
    order of ``z`` in ``Estimator.step``), so that an estimator reads ``z`` by name rather than by number.

    Raises:
        KeyError: a name is not a channel of :data:`CHANNELS`.
        ValueError: a name is not in ``order``.
    """
    for n in names:
        if n not in CHANNELS:
            raise KeyError(f"unknown sensor channel {n!r}")
    return tuple(list(order).index(n) for n in names)


def span(order: Sequence[str], *names: str) -> slice:
    """The slice of ``order`` that holds ``names``, one after the other (as :func:`positions`), so that an
    estimator takes a block of ``z`` by name without copying it element by element.

    Raises:
        KeyError: a name is not a channel of :data:`CHANNELS`.
        ValueError: no names, a name not in ``order``, or names not consecutive there in this order.
    """
    at = positions(order, *names)
    if not at or at != tuple(range(at[0], at[0] + len(at))):
        raise ValueError(f"{names} are not consecutive in {tuple(order)}")
    return slice(at[0], at[0] + len(at))
