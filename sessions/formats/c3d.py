"""Read C3D motion-capture files (Vicon, Qualisys, Motion Analysis, ...) into sensor frames (issue #25).

The reader is py-c3d (PyPI ``c3d``): pure Python over numpy, it reads one frame at a time from the open
file, so a 1 GB capture streams in bounded memory (ezc3d reads a file whole). :func:`inspect_c3d` reads the
parameter section only; :func:`c3d_frames` yields one :class:`~gaitscope.sessions.schema.SensorFrame` per
point frame, ``seq`` its index from 0 and ``t = seq / point rate`` (s, session time from 0).

What is computed, in the sagittal plane of the lab (channel conventions: :mod:`gaitscope.estimators.channels`):

- Axes. Up is the mapping's ``up_axis``, else the file's ``POINT:Y_SCREEN`` (Vicon writes ``+Z``), else
  ``+z``. Forward is the mapping's ``forward_axis``, else detected once per file: the lab horizontal axis
  (with its sign) nearest the mean direction from the PSIS (or SACR) to the ASIS midpoint over the first
  frames that show the pelvis (at most 2 s; the feet's heel-to-toe direction when no pelvis is seen). The
  pelvis's facing, not its travel, so that treadmill and standing trials work, and the angles follow the
  conventions whichever way the subject walks along the lab axis; one axis per file (a subject who turns
  round mid-file gets mirrored angles after the turn: cut such files).
- Hip joint centre: the mapping's ``RHJC`` / ``LHJC`` marker (a model output) when present, else
  Harrington et al. (2007, J Biomech 40:595, Table 3) from the pelvis markers: in the pelvis frame (origin
  the ASIS midpoint, x anterior, y superior, z right) ``(-0.24 PD - 9.9, -0.30 PW - 10.9, +/-(0.33 PW + 7.3))``
  mm, PW the inter-ASIS and PD the ASIS-to-PSIS midpoint distance. Knee and ankle centres: the ``KJC`` /
  ``AJC`` markers when mapped and present, else the lateral KNE and ANK markers (their lateral offset does
  not change a sagittal angle).
- Segment angles (deg): thigh HJC->knee and shank knee->ankle from vertical, (+) distal end forward; foot
  HEE->TOE from horizontal, (+) toes up. Joints: hip = thigh + pelvic tilt (the ASIS-PSIS line's
  inclination, (+) ASIS low: anterior tilt), knee = thigh - shank, ankle = foot - shank (0 standing with the
  shank vertical and HEE and TOE at one height, as Plug-in Gait places them). ``heel_forward_m`` /
  ``heel_up_m``: the heel marker relative to the ipsilateral hip joint centre. ``_contra``: the other side.
- Gaps: a marker whose residual is negative, or that is exactly at (0, 0, 0), is missing in that frame,
  and so is every channel that needs it (None).
- Force plates (``FORCE_PLATFORM``, types 1 to 3; a type 4 to 7 plate, whose channels need its calibration
  matrix, is refused): vertical force |Fz| (channel 3; for type 3, the sum of the four Fz channels), the
  analog samples of a point frame averaged. A foot is over a plate when its heel or toe marker is within
  the plate's corners (2 cm margin); a plate goes to the foot whose heel or toe is deepest inside it
  (farthest from its nearest edge: near a split treadmill's midline a foot is over both belts, and deeper
  in its own). A foot's ``foot_force_N`` is the sum of its plates, ``foot_contact`` that sum >=
  ``strike_threshold_N``; a foot with no plate has neither (None). With only one leg's markers mapped,
  that leg gets the plates' whole force.
- ``heel_strike``: the first frame of each ipsilateral plate contact; where the foot is over no plate, the
  peak of ``heel_forward_m`` (Zeni et al. 2008, Gait Posture 27:710: heel strike is the heel's most
  forward position relative to the pelvis), a peak over +/-0.1 s and at least 0.3 s after the last strike.
  This delays the frames by 0.1 s of lookahead, not more memory.
- Analog channels the mapping names (e.g. an IMU's) become their gaitscope channel: the mean of the
  frame's samples times the mapping's scale. Angular velocities are not computed here.

Checked on a Vicon split-treadmill walk with Plug-in Gait's own outputs (gaitalytics' test file, 12 s):
knee flexion r 0.999, difference -0.05 +/- 0.97 deg; hip 3.4 deg below Plug-in Gait's (its pelvis frame
is not the ASIS-PSIS line), ankle 0.7 +/- 2.2 deg; the 11 plate heel strikes within 0.04 s of the file's
Foot Strike events (heel_forward peaks, plates off: 0.03-0.04 s early, as Zeni reports).
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections import deque
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import c3d as _c3d
import numpy as np

from gaitscope.estimators import channels
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError

__all__ = ["PLUG_IN_GAIT", "ROLES", "C3DMapping", "C3DSummary", "c3d_frames", "inspect_c3d", "rig_of", "to_json"]

#: Per-side roles: Plug-in Gait lower-body markers, then optional joint centres a lab's model may output.
_SIDE_ROLES: Final = ("ASI", "PSI", "THI", "KNE", "TIB", "ANK", "HEE", "TOE", "HJC", "KJC", "AJC")
#: Every marker role a mapping may name, by its Plug-in Gait label (``SACR`` replaces the two PSIS).
ROLES: Final = ("SACR", *(f"{s}{r}" for s in "LR" for r in _SIDE_ROLES))
_OPTIONAL: Final = ("HJC", "KJC", "AJC")
_UNITS: Final = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
_AXES: Final = ("+x", "-x", "+y", "-y", "+z", "-z")
_MARGIN_M: Final = 0.02
_LOOKAHEAD_S: Final = 0.1
_REFRACTORY_S: Final = 0.3
_DETECT_S: Final = 2.0


@dataclass(frozen=True)
class C3DMapping:
    """Which markers and analog channels of a lab's C3D files give which gaitscope channels.

    Attributes:
        markers: role (one of :data:`ROLES`) -> the file's point label.
        side: the ipsilateral leg, ``"R"`` or ``"L"``; the other is ``_contra``.
        analog: analog label -> (gaitscope channel of the ``imu`` group, scale to its unit).
        force_plates: whether to read ``FORCE_PLATFORM`` for foot force, contact and heel strikes.
        strike_threshold_N: vertical force at or above which a foot on a plate is in contact.
        forward_axis: the lab's walking direction (``"+x"``, ``"-y"``, ...); None: detected (module doc).
        up_axis: the lab's vertical; None: ``POINT:Y_SCREEN``, else ``"+z"``.
    """

    markers: Mapping[str, str]
    side: str = "R"
    analog: Mapping[str, tuple[str, float]] = field(default_factory=dict)
    force_plates: bool = True
    strike_threshold_N: float = 20.0
    forward_axis: str | None = None
    up_axis: str | None = None

    def __post_init__(self) -> None:
        unknown = [r for r in self.markers if r not in ROLES]
        if unknown:
            raise ValueError(f"unknown marker role {', '.join(unknown)}; roles are {', '.join(ROLES)}")
        if self.side not in ("R", "L"):
            raise ValueError(f"side must be 'R' or 'L', not {self.side!r}")
        imu = [n for n, c in channels.CHANNELS.items() if c.group == "imu"]
        bad = [f"{label!r} -> {ch!r}" for label, (ch, _) in self.analog.items() if ch not in imu]
        if bad:
            raise ValueError(
                f"unknown IMU channel for analog {', '.join(bad)}; channels are imu_<segment>_gyro_x_dps ..."
            )
        for name, axis in (("forward_axis", self.forward_axis), ("up_axis", self.up_axis)):
            if axis is not None and axis not in _AXES:
                raise ValueError(f"{name} must be one of {', '.join(_AXES)}, not {axis!r}")
        if not self.strike_threshold_N > 0:
            raise ValueError(f"strike_threshold_N must be > 0, not {self.strike_threshold_N}")

    @property
    def contra(self) -> str:
        """The contralateral side's letter."""
        return "L" if self.side == "R" else "R"

    @classmethod
    def from_json(cls, text: str, name: str = "mapping.json") -> C3DMapping:
        """A lab's mapping from JSON: ``{"markers": {role: label | null}, "side": "R", "analog": {label:
        channel | {"channel": ..., "scale": ...}}, "force_plates": true, "strike_threshold_N": 20,
        "forward_axis": "+x", "up_axis": "+z"}``, every key optional. ``markers`` overrides the Plug-in Gait
        labels of :data:`PLUG_IN_GAIT` (null drops a role).

        Raises:
            DataFormatError: not JSON, an unknown key, role or channel, or a bad value (named, in ``name``).
        """
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as e:
            raise DataFormatError(f"not JSON: {e.msg}", file=name, row=e.lineno) from None
        if not isinstance(doc, dict):
            raise DataFormatError("a C3D mapping is a JSON object", file=name)
        keys = ("markers", "side", "analog", "force_plates", "strike_threshold_N", "forward_axis", "up_axis")
        extra = [k for k in doc if k not in keys]
        if extra:
            raise DataFormatError(f"unknown key {', '.join(extra)}; keys are {', '.join(keys)}", file=name)
        try:
            markers = dict(PLUG_IN_GAIT.markers)
            for role, label in dict(doc.get("markers", {})).items():
                if label is None:
                    markers.pop(role, None)
                else:
                    markers[role] = str(label)
            analog = {}
            for label, spec in dict(doc.get("analog", {})).items():
                spec = {"channel": spec} if isinstance(spec, str) else dict(spec)
                analog[str(label)] = (str(spec["channel"]), float(spec.get("scale", 1.0)))
            return cls(
                markers=markers,
                side=doc.get("side", "R"),
                analog=analog,
                force_plates=bool(doc.get("force_plates", True)),
                strike_threshold_N=float(doc.get("strike_threshold_N", 20.0)),
                forward_axis=doc.get("forward_axis"),
                up_axis=doc.get("up_axis"),
            )
        except (ValueError, TypeError, KeyError) as e:
            raise DataFormatError(f"C3D mapping: {e}", file=name) from None

    @classmethod
    def load(cls, path: str | Path) -> C3DMapping:
        """:meth:`from_json` of the file at ``path`` (UTF-8)."""
        p = Path(path)
        return cls.from_json(p.read_text(encoding="utf-8"), name=p.name)


#: The Plug-in Gait lower-body marker set, right leg ipsilateral, plates used, axes detected.
PLUG_IN_GAIT: Final = C3DMapping(markers={r: r for r in ROLES if r[1:] not in _OPTIONAL})


@dataclass(frozen=True)
class C3DSummary:
    """What :func:`inspect_c3d` tells of a file without reading its frames.

    Attributes:
        roles_found: role -> the label it was found under; roles_missing: mapped roles not in the file.
        channels: the gaitscope channels :func:`c3d_frames` can give from this file with the mapping.
    """

    point_rate_hz: float
    analog_rate_hz: float
    frames: int
    duration_s: float
    units: str
    markers: tuple[str, ...]
    analog: tuple[str, ...]
    force_plates: int
    roles_found: dict[str, str]
    roles_missing: tuple[str, ...]
    channels: tuple[str, ...]


class _File:
    """An open C3D file's parameters, refused with a :class:`DataFormatError` when unusable."""

    def __init__(self, path: str | Path, name: str, mapping: C3DMapping):
        self.name = name
        self.handle = open(path, "rb")  # closed by close(), in the callers' finally
        try:
            head = self.handle.read(2)
            if len(head) < 2 or head[1] != 0x50:
                raise DataFormatError("not a C3D file (a C3D file's second byte is 0x50)", file=name)
            self.handle.seek(0)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    self.reader = _c3d.Reader(self.handle)
            except Exception as e:  # py-c3d raises struct.error, ValueError, ... on a damaged header
                raise DataFormatError(f"damaged C3D header or parameters ({e})", file=name) from None
            r = self.reader
            self.rate = float(r.point_rate)
            if not self.rate > 0:
                raise DataFormatError(f"point rate {self.rate} Hz (POINT:RATE) is not positive", file=name)
            # Over 255 labels go on in LABELS2 (C3D.org's user guide), which py-c3d's point_labels leaves out.
            self.labels = (_strings(r, "POINT:LABELS") + _strings(r, "POINT:LABELS2"))[: r.point_used]
            self.analog_labels = (_strings(r, "ANALOG:LABELS") + _strings(r, "ANALOG:LABELS2"))[: r.analog_used]
            unit = (_strings(r, "POINT:UNITS") or ["mm"])[0].lower()
            if unit not in _UNITS:
                raise DataFormatError(f"POINT:UNITS {unit!r} is none of {', '.join(_UNITS)}", file=name)
            self.unit, self.to_m = unit, _UNITS[unit]
            self.frames = int(r.frame_count) if r.point_used or r.analog_used else 0
            self.plates = self._plates() if mapping.force_plates else []
            index = {_bare(label): i for i, label in enumerate(self.labels)}
            self.roles = {role: index[_bare(label)] for role, label in mapping.markers.items() if _bare(label) in index}
            aindex = {_bare(label): i for i, label in enumerate(self.analog_labels)}
            self.analog = {
                ch: (aindex[_bare(lb)], sc) for lb, (ch, sc) in mapping.analog.items() if _bare(lb) in aindex
            }
        except BaseException:
            self.handle.close()
            raise

    def _plates(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per plate: the analog rows whose sum is its Fz, and its corners (4 x 3, m)."""
        r = self.reader
        used = r.get("FORCE_PLATFORM:USED")
        if used is None or not r.analog_used:
            return []
        n = int(used.int16_value)
        try:
            kinds = np.atleast_1d(r.get("FORCE_PLATFORM:TYPE").int16_array)
            chans = np.atleast_2d(r.get("FORCE_PLATFORM:CHANNEL").int16_array)
            corners = np.asarray(r.get("FORCE_PLATFORM:CORNERS").float_array, float).reshape(-1, 4, 3)
        except (AttributeError, AssertionError, ValueError):
            raise DataFormatError(
                "FORCE_PLATFORM: TYPE, CHANNEL or CORNERS missing or damaged", file=self.name
            ) from None
        out = []
        for k in range(min(n, len(kinds), len(chans), len(corners))):
            if kinds[k] not in (1, 2, 3):
                raise DataFormatError(
                    f"force plate {k + 1} is of type {kinds[k]} (raw channels and a calibration matrix), which is"
                    " not read here: give the mapping force_plates false, or export the plate as type 2",
                    file=self.name,
                )
            fz = chans[k][4:8] if kinds[k] == 3 else chans[k][2:3]
            rows = np.asarray(fz, int) - 1
            if len(rows) == 0 or rows.min() < 0 or rows.max() >= r.analog_used:
                raise DataFormatError(
                    f"FORCE_PLATFORM:CHANNEL of plate {k + 1} names no analog channel", file=self.name
                )
            out.append((rows, corners[k] * self.to_m))
        return out

    def iter_points(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(points n x 4: x, y, z in m and residual; analog channels x samples) per frame, from the first."""
        frames = self.reader.read_frames(copy=False)
        while True:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                item = next(frames, None)
            if item is None:
                return
            _, points, analog = item
            p = points[:, :4].astype(float)
            p[:, :3] *= self.to_m
            n = self.reader.analog_used
            yield p, np.asarray(analog, float).reshape(n, -1) if n else np.zeros((0, 0))

    def close(self) -> None:
        self.handle.close()


def _strings(reader: Any, key: str) -> list[str]:
    param = reader.get(key)
    if param is None:
        return []
    values = param.string_array if param.dimensions and len(param.dimensions) > 1 else [param.string_value]
    return [str(v).replace("\x00", " ").strip() for v in np.ravel(values)]


def _bare(label: str) -> str:
    """A label without its subject prefix (Nexus writes ``Subject:RASI``), upper case."""
    return label.rsplit(":", 1)[-1].strip().upper()


def _channels(roles: Mapping[str, Any], mapping: C3DMapping, plates: int, analog: Mapping[str, Any]) -> list[str]:
    """The channels the found ``roles`` give (the frame's channel order)."""
    have = set(roles)
    pelvis = {"LASI", "RASI"} <= have and ({"LPSI", "RPSI"} <= have or "SACR" in have)
    out: set[str] = set(analog)
    for side, suffix in ((mapping.side, ""), (mapping.contra, "_contra")):
        hip = pelvis or f"{side}HJC" in have
        knee = f"{side}KNE" in have or f"{side}KJC" in have
        ankle = f"{side}ANK" in have or f"{side}AJC" in have
        foot = {f"{side}HEE", f"{side}TOE"} <= have
        out |= {f"thigh_angle{suffix}_deg"} if hip and knee else set()
        out |= {f"shank_angle{suffix}_deg"} if knee and ankle else set()
        out |= {f"foot_angle{suffix}_deg"} if foot else set()
        out |= {f"hip_angle{suffix}_deg"} if hip and knee and pelvis else set()
        out |= {f"knee_angle{suffix}_deg"} if hip and knee and ankle else set()
        out |= {f"ankle_angle{suffix}_deg"} if knee and ankle and foot else set()
        if not suffix and hip and f"{side}HEE" in have:
            out |= {"heel_forward_m", "heel_up_m", "heel_strike"}
        if plates and (f"{side}HEE" in have or f"{side}TOE" in have):
            out |= {f"foot_force{suffix}_N", f"foot_contact{suffix}", *(("heel_strike",) if not suffix else ())}
    return [c for c in schema.CHANNELS if c in out]


def to_json(mapping: C3DMapping) -> str:
    """``mapping`` as :meth:`C3DMapping.from_json` reads it back (every role named: its label, or null)."""
    doc = {
        "markers": {r: mapping.markers.get(r) for r in ROLES},
        "side": mapping.side,
        "analog": {label: {"channel": c, "scale": k} for label, (c, k) in mapping.analog.items()},
        "force_plates": mapping.force_plates,
        "strike_threshold_N": mapping.strike_threshold_N,
        "forward_axis": mapping.forward_axis,
        "up_axis": mapping.up_axis,
    }
    return json.dumps(doc, indent=1)


def rig_of(summary: C3DSummary) -> str:
    """The rig of a C3D file: ``c3d-`` and a hash (16 hex digits) of its sorted marker and analog labels, the
    same for every file of one lab's marker set and amplifiers, so a saved mapping is found for the next one."""
    text = json.dumps([sorted(summary.markers), sorted(summary.analog)])
    return "c3d-" + hashlib.sha256(text.encode()).hexdigest()[:16]


def inspect_c3d(path: str | Path, name: str, mapping: C3DMapping = PLUG_IN_GAIT) -> C3DSummary:
    """The header facts of the C3D file at ``path`` (``name``: the user's name for it, in errors), read from
    its parameter section only.

    Raises:
        DataFormatError: not a C3D file, or one whose header or parameters are unusable.
    """
    f = _File(path, name, mapping)
    try:
        labels = {_bare(lb): lb for lb in f.labels}
        return C3DSummary(
            point_rate_hz=f.rate,
            analog_rate_hz=float(f.reader.analog_rate) if f.reader.analog_used else 0.0,
            frames=f.frames,
            duration_s=f.frames / f.rate,
            units=f.unit,
            markers=tuple(f.labels),
            analog=tuple(f.analog_labels),
            force_plates=len(f.plates),
            roles_found={r: labels[_bare(mapping.markers[r])] for r in f.roles},
            roles_missing=tuple(r for r in mapping.markers if r not in f.roles),
            channels=tuple(_channels(f.roles, mapping, len(f.plates), f.analog)),
        )
    finally:
        f.close()


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else None


def _axis(name: str) -> np.ndarray:
    v = np.zeros(3)
    v["xyz".index(name[1])] = 1.0 if name[0] == "+" else -1.0
    return v


def _seen(p: np.ndarray, roles: Mapping[str, int]) -> dict[str, np.ndarray]:
    """Role -> position (m) of the roles seen in a frame's points (residual >= 0, not at the origin)."""
    return {r: p[i, :3] for r, i in roles.items() if p[i, 3] >= 0 and p[i, :3].any()}


def _pelvis(m: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float] | None:
    """(origin, 3 x 3 rows x anterior, y superior, z right, ASIS-to-back vector, PW, PD) or None."""
    if "LASI" not in m or "RASI" not in m:
        return None
    back = (m["LPSI"] + m["RPSI"]) / 2 if "LPSI" in m and "RPSI" in m else m.get("SACR")
    if back is None:
        return None
    origin = (m["LASI"] + m["RASI"]) / 2
    z, xt = _unit(m["RASI"] - m["LASI"]), origin - back
    y = _unit(np.cross(z, xt)) if z is not None else None
    if z is None or y is None:
        return None
    return (
        origin,
        np.array([np.cross(y, z), y, z]),
        xt,
        float(np.linalg.norm(m["RASI"] - m["LASI"])),
        float(np.linalg.norm(xt)),
    )


def _forward(f: _File, up: np.ndarray, mapping: C3DMapping) -> np.ndarray:
    """The lab's forward unit vector: the mapping's, else detected (module doc)."""
    if mapping.forward_axis is not None:
        return _axis(mapping.forward_axis)
    total, feet = np.zeros(3), np.zeros(3)
    for k, (p, _) in enumerate(f.iter_points()):
        if k >= _DETECT_S * f.rate:
            break
        m = _seen(p, f.roles)
        if (pel := _pelvis(m)) is not None:
            total += pel[2]
        for s in "LR":
            if f"{s}HEE" in m and f"{s}TOE" in m:
                feet += m[f"{s}TOE"] - m[f"{s}HEE"]
    for v in (total, feet):
        v = v - (v @ up) * up
        if np.linalg.norm(v) > 0:
            i = int(np.argmax(np.abs(v)))
            return np.sign(v[i]) * np.eye(3)[i]
    missing = [r for r in ("LASI", "RASI", "LPSI", "RPSI", "LHEE", "LTOE", "RHEE", "RTOE") if r not in f.roles]
    raise DataFormatError(
        f"cannot tell which way the subject faces: no pelvis or heel and toe markers in the first {_DETECT_S:g} s"
        f" (missing roles: {', '.join(missing) or 'none, but not seen'}); give forward_axis in the mapping",
        file=f.name,
    )


def _angle(v: np.ndarray, fwd: np.ndarray, up: np.ndarray, from_vertical: bool) -> float:
    """Sagittal angle (deg) of ``v``: from the downward vertical, (+) toward forward; or from forward, (+) up."""
    a, b = float(v @ fwd), float(v @ up)
    return math.degrees(math.atan2(a, -b) if from_vertical else math.atan2(b, a))


def _leg(m: Mapping[str, np.ndarray], s: str, pel: Any, fwd: np.ndarray, up: np.ndarray) -> dict[str, float]:
    """The sagittal channels of side ``s`` (unsuffixed names) from the seen markers ``m``."""
    out: dict[str, float] = {}
    hip = m.get(f"{s}HJC")
    if hip is None and pel is not None:
        origin, axes, _, pw, pd = pel
        lateral = (0.33 * pw + 0.0073) * (1.0 if s == "R" else -1.0)
        hip = origin + np.array([-0.24 * pd - 0.0099, -0.30 * pw - 0.0109, lateral]) @ axes
    knee = m.get(f"{s}KJC", m.get(f"{s}KNE"))
    ankle = m.get(f"{s}AJC", m.get(f"{s}ANK"))
    heel, toe = m.get(f"{s}HEE"), m.get(f"{s}TOE")
    if hip is not None and knee is not None:
        out["thigh_angle_deg"] = _angle(knee - hip, fwd, up, True)
        if pel is not None:
            tilt = -_angle(pel[2], fwd, up, False)  # (+) ASIS below the PSIS: anterior tilt
            out["hip_angle_deg"] = out["thigh_angle_deg"] + tilt
    if knee is not None and ankle is not None:
        out["shank_angle_deg"] = _angle(ankle - knee, fwd, up, True)
        if "thigh_angle_deg" in out:
            out["knee_angle_deg"] = out["thigh_angle_deg"] - out["shank_angle_deg"]
    if heel is not None and toe is not None:
        out["foot_angle_deg"] = _angle(toe - heel, fwd, up, False)
        if "shank_angle_deg" in out:
            out["ankle_angle_deg"] = out["foot_angle_deg"] - out["shank_angle_deg"]
    if hip is not None and heel is not None:
        out["heel_forward_m"], out["heel_up_m"] = float((heel - hip) @ fwd), float((heel - hip) @ up)
    return out


def _feet(
    m: Mapping[str, np.ndarray], analog: np.ndarray, f: _File, mapping: C3DMapping, up: np.ndarray
) -> dict[str, float | bool]:
    """Foot force and contact per side (module doc)."""
    flat = np.eye(3)[np.argsort(np.abs(up))[:2]]  # the two horizontal lab axes
    owner: dict[int, tuple[float, str]] = {}  # plate -> (depth, side) of the foot deepest over it
    for side in (mapping.side, mapping.contra):
        points = [m[r] @ flat.T for r in (f"{side}HEE", f"{side}TOE") if r in m]
        for k, (_, corners) in enumerate(f.plates):
            c = corners @ flat.T
            lo, hi = c.min(axis=0), c.max(axis=0)
            depth = max((float(min((q - lo).min(), (hi - q).min())) for q in points), default=-math.inf)
            if depth >= -_MARGIN_M and depth > owner.get(k, (-math.inf, side))[0]:
                owner[k] = (depth, side)
    out: dict[str, float | bool] = {}
    for side, suffix in ((mapping.side, ""), (mapping.contra, "_contra")):
        mine = [k for k, (_, s) in owner.items() if s == side]
        if mine:
            force = sum(abs(float(analog[f.plates[k][0]].mean(axis=1).sum())) for k in mine)
            out[f"foot_force{suffix}_N"] = force
            out[f"foot_contact{suffix}"] = force >= mapping.strike_threshold_N
    return out


def c3d_frames(path: str | Path, name: str, mapping: C3DMapping = PLUG_IN_GAIT) -> Iterator[schema.SensorFrame]:
    """Stream the C3D file at ``path`` as sensor frames, one per point frame (module doc), in bounded memory.

    Args:
        name: the user's name for the file, in errors.

    Raises:
        DataFormatError: not a C3D file, damaged, no channel computable with ``mapping`` (the message names the
            missing roles), the walking direction not detectable, or the file ending before its last frame.
    """
    f = _File(path, name, mapping)
    try:
        names = _channels(f.roles, mapping, len(f.plates), f.analog)
        if not [c for c in names if c != "heel_strike"]:
            psis = {"LPSI", "RPSI"} <= set(f.roles)
            missing = [
                r for r in mapping.markers if r not in f.roles and r[1:] not in _OPTIONAL and not (psis and r == "SACR")
            ]
            seen = ", ".join(f.labels[:12]) + (" ..." if len(f.labels) > 12 else "") or "none"
            raise DataFormatError(
                f"no gaitscope channel can be computed: the mapping's markers {', '.join(missing)} are missing"
                f" (the file's markers: {seen}); give a mapping for this marker set (C3DMapping.from_json)",
                file=name,
            )
        up_name = mapping.up_axis or (_strings(f.reader, "POINT:Y_SCREEN") or ["+z"])[0].lower()
        up = _axis(up_name if up_name in _AXES else "+z")
        fwd = _forward(f, up, mapping) if f.roles else up  # no marker: only analog channels, no direction
        yield from _stream(f, mapping, names, fwd, up)
    finally:
        f.close()


def _stream(
    f: _File, mapping: C3DMapping, names: list[str], fwd: np.ndarray, up: np.ndarray
) -> Iterator[schema.SensorFrame]:
    want = set(names)
    lookahead = max(1, round(_LOOKAHEAD_S * f.rate))
    pending: deque[dict[str, Any]] = deque()
    past: deque[float | None] = deque(maxlen=lookahead)
    last_strike = -math.inf
    previous_contact: bool | None = None
    count = 0

    def decide(rec: dict[str, Any], future: list[dict[str, Any]]) -> schema.SensorFrame:
        nonlocal last_strike
        seq = rec["seq"]
        if rec.get("heel_strike"):
            last_strike = seq
        elif "heel_forward_m" in want and (h := rec.get("heel_forward_m")) is not None:
            window = [*past, *(r.get("heel_forward_m") for r in future)]
            on_plates = any(r.get("foot_contact") is not None for r in (rec, *future))
            peak = all(v is None or v < h for v in window[: len(past)]) and all(
                v is None or v <= h for v in window[len(past) :]
            )
            if peak and not on_plates and seq - last_strike >= _REFRACTORY_S * f.rate and len(past) == lookahead:
                rec["heel_strike"] = True
                last_strike = seq
        past.append(rec.get("heel_forward_m"))
        if "heel_strike" in want:
            rec.setdefault("heel_strike", False)
        values = {k: v for k, v in rec.items() if (k in want and v is not None) or k in ("seq", "t")}
        return schema.SensorFrame(**values)

    for p, analog in f.iter_points():
        m = _seen(p, f.roles)
        pel = _pelvis(m)
        rec: dict[str, Any] = {"seq": count, "t": count / f.rate}
        rec.update(_leg(m, mapping.side, pel, fwd, up))
        rec.update(
            {
                f"{k[: k.rfind('_')]}_contra_{k[k.rfind('_') + 1 :]}": v
                for k, v in _leg(m, mapping.contra, pel, fwd, up).items()
                if not k.startswith("heel")
            }
        )
        for ch, (i, scale) in f.analog.items():
            rec[ch] = float(analog[i].mean()) * scale
        if f.plates:
            rec.update(_feet(m, analog, f, mapping, up))
            contact = rec.get("foot_contact")
            if contact and previous_contact is False:
                rec["heel_strike"] = True
            previous_contact = contact
        count += 1
        pending.append(rec)
        if len(pending) > lookahead:
            yield decide(pending.popleft(), list(pending))
    while pending:
        yield decide(pending.popleft(), list(pending))
    if count < f.frames:
        raise DataFormatError(f"the file ends at frame {count} of {f.frames}: truncated?", file=f.name, row=count + 1)
