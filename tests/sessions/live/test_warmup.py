"""The server's start-up warm-up (:mod:`gaitscope.sessions.live.warmup`) compiles every numba kernel a session calls:
in a fresh process, after :func:`warm_up`, sessions of every feedable estimator (opt-in ones included) over
realistic walks compile nothing more, and it returns each estimator's time per sample. Run in a subprocess, since
this process may have compiled kernels already; numba's on-disk cache may serve the compiled code (a cache load
counts as compiled)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

SCRIPT = textwrap.dedent(
    """
    import json

    from gaitscope.sessions.estimation import FrameEstimator
    from gaitscope.sessions.formats.models import default_model_path, load_model
    from gaitscope.sessions.live.sources import frames_from_table
    from gaitscope.sessions.live.warmup import warm_up
    from gaitscope.sessions.offline.warm import compiled
    from gaitscope.sessions.registry import channels_of, feeds
    from gaitscope.sessions.schema import SessionSettings
    from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
    from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_walk
    from gaitscope.sessions.synth.trials import sensor_trial

    def counts():
        return {k: len(sigs) for k, sigs in compiled().items()}

    model = load_model(default_model_path())[0]
    cold = counts()
    costs = warm_up(model)
    warm = counts()
    sensors, _, _ = sensor_trial([(1.0, 0.0, 6), (0.6, 5.0, 4)], rate_hz=200.0)
    speeds = speed_walk(make_subjects(CohortSpec())[0], SpeedProtocol(walk_s=12.0, standing_s=1.0, rate_hz=200.0))
    ran = set()
    for table in (sensors, speeds):
        frames = frames_from_table(table)
        channels = channels_of(frames)
        names = [n for n, feed in feeds(channels).items() if not feed.missing and n not in ("fp_ls",)]
        for primary in ("phase_ekf", "gp_ekf"):
            if primary not in names:
                continue
            est = FrameEstimator(model, 0.9, 75.0, SessionSettings(primary=primary), 0.005,
                                 estimators=names, channels=channels)
            ran.update(est.stack.names)
            for k, frame in enumerate(frames):
                if k % 97 == 0:  # a dropout now and then: the missing-channel branches
                    frame = frame.model_copy(update={c: None for c in ("foot_angle_deg", "knee_angle_deg")})
                est.step(frame, 0)
    print(json.dumps({"cold": cold, "warm": warm, "after": counts(), "ran": sorted(ran), "costs": costs}))
    """
)


def test_after_the_warm_up_a_session_compiles_nothing() -> None:
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=900, check=False
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    # the sessions ran the opt-in estimators, the joint-encoder GP-EKF and the IMU front ends among them
    assert {"phase_ekf", "tbe", "gp_ekf", "sdre_knee", "imu_shank", "fp_gf", "com_kin", "intent"} <= set(got["ran"])
    assert sum(got["warm"].values()) > sum(got["cold"].values())  # it compiled (or loaded) something
    late = {k: (got["warm"][k], n) for k, n in got["after"].items() if n != got["warm"][k]}
    assert not late, f"compiled during a session, after the warm-up (kernel: signatures then, now): {late}"
    # and it timed each estimator it built, compiled: a positive time per sample (us), well under 50 ms
    assert set(got["ran"]) <= set(got["costs"])
    assert all(0.0 < us < 50_000.0 for us in got["costs"].values()), got["costs"]
