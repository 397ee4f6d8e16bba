"""C3D motion capture: real files that biomdp ships (a Vicon countermovement jump with markers, Vicon's own
model outputs beside it, Kistler plate-only files) and walks this test writes with py-c3d."""

from __future__ import annotations

import csv
import math
import tracemalloc
import warnings
from importlib import resources
from pathlib import Path

import c3d
import numpy as np
import pytest

from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.c3d import PLUG_IN_GAIT, C3DMapping, c3d_frames, inspect_c3d

_DATA = resources.files("biomdp.tests.datasets")
_CMJ = Path(str(_DATA / "vicon_CMJ_kinem_kinet_emg.c3d"))
#: The jump's lab (Spanish labels, right leg only, the model's joint centres as points).
_CMJ_MAPPING = """{"markers": {"RHJC": "RHJC", "RKJC": "RKJC", "RAJC": "RAJC", "RKNE": "Right_KneeExt",
    "RANK": "Right_AnkleExt", "RHEE": "Right_TalonInf", "RTOE": "Right_Meta"}}"""


def _model_outputs() -> dict[str, np.ndarray]:
    """The x column of each of Vicon's model outputs in the CSV export shipped beside the jump's C3D."""
    with open(_CMJ.with_suffix(".csv"), encoding="utf-8-sig", newline="") as fh:
        lines = iter(csv.reader(fh))
        for row in lines:
            if row[:1] == ["Model Outputs"]:
                break
        next(lines)
        head = next(lines)
        next(lines), next(lines)
        rows = [r for r in iter(lambda: next(lines), []) if r]
    out = {}
    for j, label in enumerate(head):
        if label:
            out[label.split(":")[-1]] = np.array([float(r[j]) if r[j] else math.nan for r in rows])
    return out


def _series(frames: list, channel: str) -> np.ndarray:
    return np.array([math.nan if (v := getattr(f, channel)) is None else float(v) for f in frames])


def test_inspect_real_vicon_file() -> None:
    s = inspect_c3d(_CMJ, "cmj.c3d")
    assert (s.point_rate_hz, s.analog_rate_hz, s.frames, s.duration_s, s.units) == (200.0, 2000.0, 1600, 8.0, "mm")
    assert s.force_plates == 2 and len(s.markers) == 42 and s.analog[:3] == ("Force.Fx1", "Force.Fy1", "Force.Fz1")
    assert s.roles_found == {"LASI": "LASI", "LPSI": "LPSI", "RASI": "RASI", "RPSI": "RPSI"}
    assert {"RKNE", "RANK", "RHEE", "RTOE", "LKNE"} <= set(s.roles_missing)
    assert s.channels == ()
    lab = inspect_c3d(_CMJ, "cmj.c3d", C3DMapping.from_json(_CMJ_MAPPING))
    assert lab.roles_found["RKNE"] == "Right_KneeExt"
    assert lab.channels == (
        "foot_angle_deg",
        "shank_angle_deg",
        "heel_forward_m",
        "heel_up_m",
        "thigh_angle_deg",
        "hip_angle_deg",
        "knee_angle_deg",
        "ankle_angle_deg",
        "foot_force_N",
        "foot_contact",
        "heel_strike",
    )


def test_real_jump_matches_vicon_model_outputs() -> None:
    frames = list(c3d_frames(_CMJ, "cmj.c3d", C3DMapping.from_json(_CMJ_MAPPING)))
    assert len(frames) == 1600 and frames[0].seq == 0 and frames[-1].t == pytest.approx(1599 / 200)
    vicon = _model_outputs()
    # The lab's model gives sagittal segment angles from the same joint centres: equal to ours.
    for ours, theirs in (("thigh_angle_deg", "AngSegMUSLO_R"), ("shank_angle_deg", "AngSegPIERNA_R")):
        diff = _series(frames, ours) - vicon[theirs]
        assert np.nanmax(np.abs(diff)) < 0.01
    knee = _series(frames, "knee_angle_deg")  # 3D flexion (Vicon) against our sagittal projection
    assert abs(np.nanmean(knee - vicon["AngArtKnee_R"])) < 0.5 and np.nanstd(knee - vicon["AngArtKnee_R"]) < 1.0
    assert 4 < np.nanmin(knee) < 7 and 100 < np.nanmax(knee) < 104
    force = _series(frames, "foot_force_N")  # both feet on plate 1; only the right leg's markers
    assert 740 < np.mean(force[:200]) < 770  # body weight, standing
    flight = np.flatnonzero(force < 20)
    assert np.all(np.diff(flight) == 1) and len(flight) == 133  # the jump's flight: 0.665 s, one stretch
    strikes = [f.t for f in frames if f.heel_strike]
    assert strikes == [pytest.approx((flight[-1] + 1) / 200)]  # one: the landing (standing at the start is not)


def test_refuses_a_file_without_the_mapping_markers() -> None:
    with pytest.raises(
        DataFormatError,
        match=r"file cmj\.c3d: no gaitscope channel .* markers LTHI, LKNE, LTIB, .* RHEE, RTOE are missing",
    ):
        next(c3d_frames(_CMJ, "cmj.c3d"))
    plates_only = Path(str(_DATA / "kistler_DJ_2plates.c3d"))
    assert inspect_c3d(plates_only, "dj.c3d").force_plates == 2
    with pytest.raises(DataFormatError, match=r"markers SACR, LASI, LPSI, .* file's markers: none"):
        next(c3d_frames(plates_only, "dj.c3d"))


def test_refuses_a_file_that_is_not_c3d(tmp_path: Path) -> None:
    path = tmp_path / "walk.c3d"
    path.write_text("time,knee\n0,1\n")
    with pytest.raises(DataFormatError, match=r"file walk\.c3d: not a C3D file"):
        inspect_c3d(path, "walk.c3d")
    path.write_bytes(b"\x02\x50" + bytes(100))
    with pytest.raises(DataFormatError, match=r"file walk\.c3d: damaged C3D header"):
        next(c3d_frames(path, "walk.c3d"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"analog": {"Accel.X": "imu_shin_accel_x_m_s2"}}', r"unknown IMU channel for analog 'Accel.X' -> 'imu_shin"),
        ('{"analog": {"Accel.X": "knee_angle_deg"}}', "unknown IMU channel"),
        ('{"markers": {"RKNEE": "R_knee"}}', "unknown marker role RKNEE; roles are SACR, LASI"),
        ('{"side": "right"}', "side must be 'R' or 'L'"),
        ('{"forward": "+x"}', "unknown key forward"),
        ('{"forward_axis": "x"}', "forward_axis must be one of"),
        ("{markers: 1}", r"row 1: not JSON"),
    ],
)
def test_mapping_json_refusals(text: str, message: str) -> None:
    with pytest.raises(DataFormatError, match=rf"file lab\.json.*{message}"):
        C3DMapping.from_json(text, name="lab.json")


def test_mapping_json_overrides_plug_in_gait(tmp_path: Path) -> None:
    path = tmp_path / "lab.json"
    path.write_text(
        '{"markers": {"RHEE": "R_heel", "SACR": null}, "side": "L", '
        '"analog": {"G.z": {"channel": "imu_shank_gyro_z_dps", "scale": 57.3}}}'
    )
    m = C3DMapping.load(path)
    assert m.markers["RHEE"] == "R_heel" and m.markers["LKNE"] == "LKNE" and "SACR" not in m.markers
    assert (m.side, m.contra, dict(m.analog)) == ("L", "R", {"G.z": ("imu_shank_gyro_z_dps", 57.3)})
    assert PLUG_IN_GAIT.markers["RASI"] == "RASI" and "RHJC" not in PLUG_IN_GAIT.markers


# -- written walks ------------------------------------------------------------------------------------------

_RATE, _STRIDE_S, _THIGH_M, _SHANK_M, _FOOT_M = 100.0, 1.1, 0.42, 0.40, 0.20
_AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0)}


def _gait(t: float, phase: float) -> tuple[float, float, float]:
    """(thigh, shank, foot) angles (deg) of a leg at ``t`` s."""
    w = 2 * math.pi * (t / _STRIDE_S + phase)
    thigh = 5 + 22 * math.sin(w)
    knee = 30 * (1 - math.cos(w - 0.8)) / 2 + 3
    return thigh, thigh - knee, 12 * math.sin(w + 0.5)


def _walk(
    forward: str,
    seconds: float = 8.0,
    speed: float = 1.2,
    plates: bool = False,
    hjc: bool = True,
    psis_up=0.03,
    half_width=0.09,
):
    """Markers (mm, float32) of a walk along the lab axis ``forward``; ``plates``: in place, on a split treadmill
    centred at the origin."""
    f, u = np.array(_AXES[forward], float), np.array([0.0, 0.0, 1.0])
    right = np.cross(f, u)
    labels = ["LASI", "RASI", "LPSI", "RPSI"] + [f"{s}{r}" for s in "RL" for r in ("KNE", "ANK", "HEE", "TOE")]
    labels += ["RHJC", "LHJC"] if hjc else []
    frames = []
    for i in range(int(seconds * _RATE)):
        t = i / _RATE
        pelvis = (np.zeros(3) if plates else np.array([0.3, -0.2, 0.0]) + speed * t * f) + 0.95 * u
        m = {
            "LASI": pelvis + 0.05 * f - 0.12 * right,
            "RASI": pelvis + 0.05 * f + 0.12 * right,
            "LPSI": pelvis - 0.10 * f - 0.05 * right + psis_up * u,
            "RPSI": pelvis - 0.10 * f + 0.05 * right + psis_up * u,
        }
        for s, phase, sign in (("R", 0.0, 1.0), ("L", 0.5, -1.0)):
            thigh, shank, foot = (math.radians(a) for a in _gait(t, phase))
            hip = pelvis + sign * half_width * right - 0.08 * u
            knee = hip + _THIGH_M * (math.sin(thigh) * f - math.cos(thigh) * u)
            ankle = knee + _SHANK_M * (math.sin(shank) * f - math.cos(shank) * u)
            heel = ankle - 0.05 * f - 0.04 * u
            m |= {f"{s}HJC": hip, f"{s}KNE": knee + sign * 0.05 * right, f"{s}ANK": ankle + sign * 0.04 * right}
            m |= {f"{s}HEE": heel, f"{s}TOE": heel + _FOOT_M * (math.cos(foot) * f + math.sin(foot) * u)}
        frames.append(np.array([m[label] for label in labels]) * 1000.0)
    return labels, np.array(frames, np.float32)


def _write(
    path: Path, labels: list[str], points: np.ndarray, analog: np.ndarray | None = None, plates=None, kind: int = 2
) -> None:
    w = c3d.Writer(point_rate=_RATE, analog_rate=_RATE * 10 if analog is not None else 0.0, point_units="mm  ")
    w.set_point_labels(labels)
    if analog is not None:
        w.set_analog_labels([f"Force.Fz{k + 1}" for k in range(analog.shape[1])])
    data = np.empty((len(points), 2), dtype=object)
    for i, p in enumerate(points):
        block = np.zeros((len(labels), 5), np.float32)
        block[:, :3] = p
        data[i, 0] = block
        data[i, 1] = analog[i] if analog is not None else np.zeros((0, 0), np.float32)
    w.add_frames(data)
    if plates is not None:  # C3D arrays are Fortran ordered: a (plates, 6) array's dimensions are (6, plates)
        g = w.add_group(5, "FORCE_PLATFORM", "plates")
        n = len(plates)
        g.add("USED", "plates", 2, "<h", n)
        g.add("TYPE", "types", 2, None, np.full(n, kind, "<i2").tobytes(), n)
        channel = np.array([[0, 0, k + 1, 0, 0, 0] for k in range(n)], "<i2")
        g.add("CHANNEL", "channels", 2, None, channel.tobytes(), 6, n)
        g.add("CORNERS", "corners (mm)", 4, None, np.array(plates, "<f4").tobytes(), 3, 4, n)
    with warnings.catch_warnings():  # py-c3d's writer warns of a file without analog data
        warnings.simplefilter("ignore", UserWarning)
        with open(path, "wb") as fh:
            w.write(fh)


def _hand(m: dict[str, np.ndarray], f: np.ndarray, s: str) -> dict[str, float]:
    """The sagittal angles of side ``s`` worked out from the stored markers (m, float64)."""
    u = np.array([0.0, 0.0, 1.0])

    def from_vertical(v: np.ndarray) -> float:
        return math.degrees(math.atan2(v @ f, -(v @ u)))

    thigh, shank = from_vertical(m[f"{s}KNE"] - m[f"{s}HJC"]), from_vertical(m[f"{s}ANK"] - m[f"{s}KNE"])
    v = m[f"{s}TOE"] - m[f"{s}HEE"]
    foot = math.degrees(math.atan2(v @ u, v @ f))
    back = (m["LPSI"] + m["RPSI"]) / 2
    a = (m["LASI"] + m["RASI"]) / 2 - back
    tilt = math.degrees(math.atan2(-(a @ u), a @ f))
    return {
        "thigh": thigh,
        "shank": shank,
        "foot": foot,
        "hip": thigh + tilt,
        "knee": thigh - shank,
        "ankle": foot - shank,
    }


@pytest.mark.parametrize("forward", ["+x", "-x", "+y", "-y"])
def test_written_walk_angles_any_direction(tmp_path: Path, forward: str) -> None:
    labels, points = _walk(forward)
    points[50, labels.index("RKNE"), :] = 0.0  # a gap: exactly at the origin
    _write(tmp_path / "walk.c3d", labels, points)
    mapping = C3DMapping.from_json('{"markers": {"RHJC": "RHJC", "LHJC": "LHJC"}}')
    frames = list(c3d_frames(tmp_path / "walk.c3d", "walk.c3d", mapping))
    f = np.array(_AXES[forward], float)
    for k in (0, 37, 200, 555):
        m = {label: points[k, j].astype(float) / 1000.0 for j, label in enumerate(labels)}
        frame = frames[k]
        assert frame.t == pytest.approx(k / _RATE, abs=1e-12)
        for side, suffix in (("R", ""), ("L", "_contra")):
            hand = _hand(m, f, side)
            for joint, value in hand.items():
                assert getattr(frame, f"{joint}_angle{suffix}_deg") == pytest.approx(value, abs=1e-6)
        thigh, shank, foot = _gait(k / _RATE, 0.0)  # and the generating angles, to float32's precision
        assert (frame.thigh_angle_deg, frame.shank_angle_deg) == (
            pytest.approx(thigh, abs=1e-3),
            pytest.approx(shank, abs=1e-3),
        )
        assert frame.foot_angle_deg == pytest.approx(foot, abs=1e-3)
        assert frame.hip_angle_deg == pytest.approx(thigh + math.degrees(math.atan2(0.03, 0.15)), abs=1e-3)
    gap = frames[50]
    assert gap.thigh_angle_deg is None and gap.knee_angle_deg is None and gap.shank_angle_deg is None
    assert gap.foot_angle_deg is not None and gap.thigh_angle_contra_deg is not None
    knee = _series(frames, "knee_angle_deg")
    assert 0 < np.nanmin(knee) and np.nanmax(knee) < 70
    strikes = np.array([fr.t for fr in frames if fr.heel_strike])  # no plates: heel_forward's peaks
    assert len(strikes) == 8 and np.allclose(np.diff(strikes), _STRIDE_S, atol=0.011)
    heel = _series(frames, "heel_forward_m")
    assert all(
        heel[round(t * _RATE)] == np.nanmax(heel[round(t * _RATE) - 10 : round(t * _RATE) + 11]) for t in strikes
    )


def test_hip_joint_centre_from_the_pelvis(tmp_path: Path) -> None:
    labels, points = _walk("+x", seconds=0.5, speed=0.0, hjc=False, psis_up=0.0)
    _write(tmp_path / "still.c3d", labels, points)
    frame = next(c3d_frames(tmp_path / "still.c3d", "still.c3d"))
    m = {label: points[0, j].astype(float) / 1000.0 for j, label in enumerate(labels)}
    # Harrington 2007, PW 0.24 m, PD 0.15 m, the pelvis level and facing +x: anterior +x, up +z, right -y.
    origin = (m["LASI"] + m["RASI"]) / 2
    hjc = origin + np.array([-0.24 * 0.15 - 0.0099, -(0.33 * 0.24 + 0.0073), -0.30 * 0.24 - 0.0109])
    assert frame.heel_forward_m == pytest.approx(m["RHEE"][0] - hjc[0], abs=1e-6)
    assert frame.heel_up_m == pytest.approx(m["RHEE"][2] - hjc[2], abs=1e-6)
    assert frame.hip_angle_deg == pytest.approx(frame.thigh_angle_deg, abs=1e-9)  # a level pelvis: no tilt


@pytest.mark.parametrize("half_width", [0.09, 0.015])  # 0.015: each foot is within the margin of both belts
def test_split_treadmill_plates_give_force_contact_and_strikes(tmp_path: Path, half_width: float) -> None:
    labels, points = _walk("-y", seconds=6.0, plates=True, half_width=half_width)
    n = len(points)
    stance = [((i / _RATE) / _STRIDE_S) % 1.0 < 0.6 for i in range(n)]  # right foot loaded 60 % of a stride
    analog = np.zeros((n, 2, 10), np.float32)
    for i in range(n):
        analog[i, 0, :] = -700.0 if stance[i] else 0.5  # Fz of the right belt's plate
        analog[i, 1, :] = -650.0
    # Walking along -y the subject's right is -x: the right belt is x < 0, the left x > 0.
    plates = [
        [[-800, 1500, 0], [0, 1500, 0], [0, -1500, 0], [-800, -1500, 0]],
        [[0, 1500, 0], [800, 1500, 0], [800, -1500, 0], [0, -1500, 0]],
    ]
    _write(tmp_path / "tread.c3d", labels, points, analog, plates)
    mapping = C3DMapping.from_json(
        '{"markers": {"RHJC": "RHJC", "LHJC": "LHJC"}, "strike_threshold_N": 25,'
        ' "analog": {"Force.Fz2": {"channel": "imu_pelvis_accel_z_m_s2", "scale": 0.01}}}'
    )
    assert inspect_c3d(tmp_path / "tread.c3d", "tread.c3d", mapping).force_plates == 2
    frames = list(c3d_frames(tmp_path / "tread.c3d", "tread.c3d", mapping))
    assert [f.foot_contact for f in frames] == stance
    assert {round(float(f.foot_force_N or 0), 3) for f in frames} == {700.0, 0.5}
    assert {round(float(f.foot_force_contra_N or 0), 3) for f in frames} == {650.0}
    assert {round(float(f.imu_pelvis_accel_z_m_s2 or 0), 6) for f in frames} == {-6.5}  # analog, scaled
    strikes = [f.seq for f in frames if f.heel_strike]
    assert strikes == [i for i in range(1, n) if stance[i] and not stance[i - 1]]
    assert len(strikes) == 5


def test_truncated_file(tmp_path: Path) -> None:
    labels, points = _walk("+x", seconds=2.0)
    _write(tmp_path / "walk.c3d", labels, points)
    data = (tmp_path / "walk.c3d").read_bytes()
    (tmp_path / "cut.c3d").write_bytes(data[: len(data) - 60 * len(labels) * 16])
    with pytest.raises(DataFormatError, match=r"file cut\.c3d, row \d+: the file ends at frame \d+ of 200"):
        list(c3d_frames(tmp_path / "cut.c3d", "cut.c3d"))


def test_streams_in_bounded_memory(tmp_path: Path) -> None:
    labels, points = _walk("+x", seconds=30.0)
    extra = [f"M{k}" for k in range(240)]  # unused markers (py-c3d writes at most 255): a 12 MB file
    wide = np.concatenate([points, np.full((len(points), len(extra), 3), 100.0, np.float32)], axis=1)
    _write(tmp_path / "wide.c3d", labels + extra, wide)
    size = (tmp_path / "wide.c3d").stat().st_size
    mapping = C3DMapping.from_json('{"markers": {"RHJC": "RHJC", "LHJC": "LHJC"}}')
    tracemalloc.start()
    try:
        count = sum(1 for _ in c3d_frames(tmp_path / "wide.c3d", "wide.c3d", mapping))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert count == 3000 and size > 12e6 and peak < 1e6, peak  # about 0.2 MB


def test_refuses_a_plate_that_needs_its_calibration_matrix(tmp_path: Path) -> None:
    labels, points = _walk("+x", seconds=0.5)
    plate = [[[0, 0, 0], [600, 0, 0], [600, 400, 0], [0, 400, 0]]]
    _write(tmp_path / "t4.c3d", labels, points, np.zeros((len(points), 1, 10), np.float32), plate, kind=4)
    with pytest.raises(DataFormatError, match=r"file t4\.c3d: force plate 1 is of type 4 .* force_plates false"):
        inspect_c3d(tmp_path / "t4.c3d", "t4.c3d")
    no_plates = C3DMapping.from_json('{"force_plates": false}')
    assert inspect_c3d(tmp_path / "t4.c3d", "t4.c3d", no_plates).force_plates == 0


def test_an_imu_only_file_gives_its_mapped_analog_channels(tmp_path: Path) -> None:
    analog = np.zeros((50, 1, 10), np.float32)
    analog[:, 0, :] = np.arange(10, dtype=np.float32)  # mean 4.5 in every point frame
    _write(tmp_path / "imu.c3d", ["M0"], np.ones((50, 1, 3), np.float32), analog)
    mapping = C3DMapping.from_json('{"analog": {"Force.Fz1": {"channel": "imu_foot_gyro_z_dps", "scale": 2}}}')
    assert inspect_c3d(tmp_path / "imu.c3d", "imu.c3d", mapping).channels == ("imu_foot_gyro_z_dps",)
    frames = list(c3d_frames(tmp_path / "imu.c3d", "imu.c3d", mapping))
    assert len(frames) == 50 and {f.imu_foot_gyro_z_dps for f in frames} == {9.0}
    assert frames[0].knee_angle_deg is None and frames[0].heel_strike is None
