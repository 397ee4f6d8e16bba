"""The gaitscope command line, run in-process and once as the installed console script."""

import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gaitscope.server.cli import main
from gaitscope.sessions import schema
from gaitscope.sessions.formats.locohub import write_table
from gaitscope.sessions.formats.models import load_model
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial


@pytest.fixture(scope="module")
def trial_csv(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pd.DataFrame]:
    sensors, _, _ = sensor_trial([(1.2, 0.0, 8), (1.0, 5.0, 8)])
    path = tmp_path_factory.mktemp("trial") / "trial.csv"
    replay_columns(sensors).to_csv(path, index=False, float_format="%.6f")
    return path, sensors


def test_replay_writes_every_output_column(tmp_path: Path, trial_csv, capsys) -> None:
    src, sensors = trial_csv
    out = tmp_path / "out.csv"
    assert main(["replay", str(src), "--out", str(out), "--leg-length", "0.9"]) == 0
    est = pd.read_csv(out)
    assert tuple(est.columns) == schema.REPLAY_OUTPUT
    assert len(est) == len(sensors)
    assert est["heel_strike"].sum() == sensors["heel_strike"].sum()
    assert est["phase"].between(0, 1).all() and (est["torque_Nm"] >= 0).all()
    assert "heel strikes" in capsys.readouterr().out


def test_replay_detects_heel_strikes_and_uses_a_subset_of_sensors(tmp_path: Path, trial_csv) -> None:
    src, sensors = trial_csv
    reduced = pd.read_csv(src)[["time_s", "foot_angle_deg", "foot_vel_dps", "shank_angle_deg"]]
    path = tmp_path / "reduced.csv"
    reduced.to_csv(path, index=False)
    out = tmp_path / "out.csv"
    assert main(["replay", str(path), "--out", str(out)]) == 0
    est = pd.read_csv(out)
    true_hs = sensors["time_s"].to_numpy()[sensors["heel_strike"].to_numpy() > 0]
    found = est["time_s"].to_numpy()[est["heel_strike"].to_numpy() > 0]
    assert abs(len(found) - len(true_hs)) <= 1
    gaps = np.abs(found[:, None] - true_hs[None, :]).min(axis=1)
    assert np.median(gaps) < 0.06  # within a few samples of the true heel strike


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda f: f.assign(shank_angle_deg=f["shank_angle_deg"].astype(object).where(f.index != 9, "abc")),
            "column 'shank_angle_deg', row 11",
        ),
        (lambda f: f.assign(time_s=np.where(f.index == 20, 0.0, f["time_s"])), "column 'time_s', row 22"),
        (lambda f: f.drop(columns=["time_s"]), "time_s"),
        (lambda f: f.drop(columns=["foot_angle_deg", "shank_angle_deg"]), "angle"),
    ],
)
def test_bad_input_exits_2_naming_the_place_and_leaves_no_output(
    tmp_path: Path, trial_csv, capsys, edit, message
) -> None:
    src, _ = trial_csv
    bad = tmp_path / "bad.csv"
    edit(pd.read_csv(src)).to_csv(bad, index=False)
    out = tmp_path / "out.csv"
    assert main(["replay", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "gaitscope: error: file" in err and message in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--max-torque", "900", "max torque 900.0 N m is outside 0..80 N m"),
        ("--max-torque", "80.5", "max torque 80.5 N m is outside 0..80 N m"),
        ("--torque-gain", "nan", "torque gain nan is outside 0..3"),
        ("--leg-length", "1.4", "leg length 1.4 m is outside 0.5..1.3 m"),
        ("--mass", "300", "mass 300.0 kg is outside 20..250 kg"),
    ],
)
def test_bad_settings_exit_2(tmp_path: Path, trial_csv, capsys, flag: str, value: str, message: str) -> None:
    src, _ = trial_csv
    assert main(["replay", str(src), "--out", str(tmp_path / "o.csv"), flag, value]) == 2
    err = capsys.readouterr().err
    assert message in err and f"file {flag}" in err
    assert not (tmp_path / "o.csv").exists()


def test_pipeline_bounds_are_the_dashboards(capsys) -> None:
    """The replay options are bounded as the dashboard's subjects and settings are (one statement of each)."""
    with pytest.raises(SystemExit):
        main(["replay", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    lo, hi, _ = schema.SETTING_LIMITS["max_torque_Nm"]
    assert f"torque bound, {lo:g}..{hi:g} N m" in text
    lo, hi = schema.field_bounds(schema.SubjectCreate, "leg_length_m")
    assert f"leg length, {lo:g}..{hi:g} m" in text


def test_loadbench_and_wire_commands_are_there(capsys) -> None:
    for command in ("loadbench", "wire", "api-client"):
        with pytest.raises(SystemExit) as done:
            main([command, "--help"])
        assert done.value.code == 0
    out = capsys.readouterr().out
    assert "--soak" in out and "--out" in out


def test_bench_passes_its_options_to_the_bench(monkeypatch: pytest.MonkeyPatch) -> None:
    from gaitscope.sessions.offline import bench

    calls: list[dict[str, object]] = []
    monkeypatch.setattr(bench, "run_bench", lambda **kw: calls.append(kw) or {})
    assert main(["bench", "--skip-crossval"]) == 0
    assert main(["bench", "--reference-samples", "50", "--samples", "200"]) == 0
    assert calls == [
        {"crossval": False, "reference_samples": 3000, "samples": 6000},
        {"crossval": True, "reference_samples": 50, "samples": 200},
    ]


def test_train_from_a_locohub_file(tmp_path: Path, small_cohort: pd.DataFrame) -> None:
    table = tmp_path / "lab.parquet"
    write_table(small_cohort, table)
    out = tmp_path / "model.npz"
    assert main(["train", "--data", str(table), "--out", str(out), "--order", "8"]) == 0
    model, prov = load_model(out)
    assert prov.source == str(table) and prov.fourier_order == 8 and len(prov.subjects) == 3
    assert model.coef.shape == (4, 2, 2, 17)


def test_train_refuses_a_table_without_a_required_column(tmp_path: Path, small_cohort: pd.DataFrame, capsys) -> None:
    table = tmp_path / "lab.csv"
    write_table(small_cohort.drop(columns=[schema.FOOT_ANGLE]).head(450), table)
    assert main(["train", "--data", str(table), "--out", str(tmp_path / "m.npz")]) == 2
    assert schema.FOOT_ANGLE in capsys.readouterr().err
    assert not (tmp_path / "m.npz").exists()


def test_console_script_runs_the_demo(tmp_path: Path) -> None:
    exe = str(Path(sys.executable).with_name("gaitscope"))
    done = subprocess.run([exe, "demo", "--out-dir", str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "phase RMSE EKF" in done.stdout
    est = pd.read_csv(tmp_path / "default_trial_estimates.csv")
    assert len(est) == len(pd.read_csv(tmp_path / "default_trial.csv")) > 10_000


def test_serve_gives_uvicorn_the_websocket_message_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from gaitscope.server.announcing import AnnouncingServer

    calls: list[AnnouncingServer] = []
    monkeypatch.setattr(AnnouncingServer, "run", lambda self, sockets=None: calls.append(self))
    monkeypatch.setenv("GAITSCOPE_WS_MAX_KB", "32")
    assert main(["serve", "--no-demo", "--no-leg-view", "--data-dir", str(tmp_path)]) == 0
    assert calls[0].config.ws_max_size == 32 * 1024  # a longer message closes the socket (1009) before it is read


def test_serve_prints_its_url_once_it_answers_after_saying_it_is_starting(tmp_path: Path) -> None:
    from gaitscope.server.bench.launch import free_port

    port = free_port()
    exe = str(Path(sys.executable).with_name("gaitscope"))
    cmd = [exe, "serve", "--port", str(port), "--data-dir", str(tmp_path), "--no-leg-view"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if "serving on" in line:
                break
        assert any("serving on" in line for line in lines), "".join(lines)
        url = f"http://127.0.0.1:{port}/"
        assert url in lines[-1]
        with urllib.request.urlopen(f"{url}api/health", timeout=5) as resp:  # at once: no retry
            assert resp.status == 200
        said = "".join(lines)
        assert said.index("gaitscope: starting: the estimators' compiled code loads first") < said.index("serving on")
    finally:
        proc.terminate()
        proc.communicate(timeout=30)  # and its output closed
