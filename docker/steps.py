"""Turn ``docker/Dockerfile`` into a bash script that runs its steps outside a container.

CI has no Docker daemon, so the image cannot be built there. What can be checked is that its steps work:
this module reads the Dockerfile and writes, for one temporary folder ``root`` standing in for the image's
file system, the same steps as shell commands: each ``COPY`` as a copy from the repository, each ``RUN`` as
it is written, each ``ENV`` exported, then the final stage's ``CMD`` started with its ``ENV`` and its
``HEALTHCHECK`` command polled until the server answers, as Docker would. ``docker/steps.sh`` runs it; with
``--print`` it only shows it. The script is generated from the Dockerfile on every run, so the two cannot
drift apart; an instruction or option this module does not know is an error, never silently skipped.

What differs from the image, each on purpose and listed in the script's comments:

- Container paths (:data:`MAPPED`) live under ``root``; any other absolute path on a ``RUN``, ``ENV``,
  ``COPY``, ``WORKDIR`` or ``VOLUME`` line is refused (:func:`check_paths`), so a new one must be mapped.
- ``python`` is the host's CPython 3.11 (``$PYTHON``; ``steps.sh`` checks the version) instead of the base image's.
- Commands that need root inside the image (:data:`IMAGE_ONLY`: creating the user, ``chown``) are left out,
  and ``USER`` is not switched: the steps run as whoever runs the script.
- ``--no-cache-dir`` is dropped, so that pip reuses the host's download cache (the image must not keep one).
- The server binds 127.0.0.1 on free ports (:data:`OVERRIDES`) and uses a SQLite database in ``root``
  (no ``GAITSCOPE_DATABASE_URL``); the image's own environment, ``0.0.0.0`` included, is checked against
  ``gaitscope.server.settings.Settings`` first, so that a container the server would refuse fails here too.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import socket
import sys
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["IMAGE_ONLY", "MAPPED", "DockerfileError", "Instruction", "check_paths", "generate", "main", "parse"]

#: Folders of the image that the script keeps under its temporary ``root``.
MAPPED: tuple[str, ...] = ("/src", "/wheels", "/opt/gaitscope", "/var/lib/gaitscope", "/var/cache/gaitscope")
#: Absolute paths a Dockerfile line may name without mapping: the base image's own.
SYSTEM_PATHS: tuple[str, ...] = ("/usr/sbin/nologin",)
#: Programs of a ``RUN`` that only make sense as root inside the image; left out of the script.
IMAGE_ONLY: frozenset[str] = frozenset({"groupadd", "useradd", "chown"})
#: Settings the script overrides when it starts the server (and only then): loopback, free ports.
OVERRIDES: tuple[str, ...] = ("GAITSCOPE_HOST", "GAITSCOPE_PORT", "GAITSCOPE_VISER_PORT")
#: Options of ``pip`` dropped outside the image.
DROPPED_OPTIONS: tuple[str, ...] = ("--no-cache-dir",)
#: Seconds Docker waits after SIGTERM before it kills a container (``docker stop``'s default).
STOP_GRACE_S = 10

_PATH_RE = re.compile(r"(?<![\w./:-])(/[\w.-]+(?:/[\w.*-]+)*)")
_COPY_IGNORE = ("__pycache__", "*.pyc", "*.egg-info", "build")


@dataclass
class Instruction:
    """One Dockerfile instruction: ``keyword`` upper-case, ``flags`` (``--name=value``), the rest as text."""

    keyword: str
    flags: dict[str, str]
    args: str
    line: int


@dataclass
class Stage:
    """The instructions of one ``FROM`` up to the next."""

    name: str
    base: str
    instructions: list[Instruction] = field(default_factory=list)


class DockerfileError(ValueError):
    """The Dockerfile uses something this module does not translate; names the line."""


def parse(text: str) -> list[Stage]:
    """Split a Dockerfile into stages of instructions (continuation lines joined, comments dropped).

    Raises:
        DockerfileError: an instruction before the first ``FROM``, or a line that is no instruction.
    """
    stages: list[Stage] = []
    logical: list[tuple[int, str]] = []
    buf: list[str] = []
    start = 0
    for number, raw in enumerate(text.splitlines(), 1):
        stripped = raw.strip()
        if not buf and (not stripped or stripped.startswith("#")):
            continue
        if buf and stripped.startswith("#"):
            continue  # a comment inside a continued instruction
        if not buf:
            start = number
        if stripped.endswith("\\"):
            buf.append(stripped[:-1].strip())
            continue
        buf.append(stripped)
        logical.append((start, " ".join(part for part in buf if part)))
        buf = []
    if buf:
        raise DockerfileError(f"Dockerfile line {start}: continued past the end of the file")
    for number, line in logical:
        keyword, _, rest = line.partition(" ")
        keyword = keyword.upper()
        flags: dict[str, str] = {}
        rest = rest.strip()
        while rest.startswith("--"):
            flag, _, rest = rest.partition(" ")
            name, _, value = flag[2:].partition("=")
            flags[name] = value
            rest = rest.strip()
        ins = Instruction(keyword, flags, rest, number)
        if keyword == "FROM":
            base, _, alias = rest.partition(" AS ")
            if not alias and " as " in rest:
                base, _, alias = rest.partition(" as ")
            stages.append(Stage(name=alias.strip() or str(len(stages)), base=base.strip()))
        elif not stages:
            raise DockerfileError(f"Dockerfile line {number}: {keyword} before the first FROM")
        else:
            stages[-1].instructions.append(ins)
    if not stages:
        raise DockerfileError("Dockerfile: no FROM")
    return stages


def check_paths(stages: list[Stage]) -> list[str]:
    """Every absolute path the steps would touch that is neither mapped nor a base-image path.

    Returns one ``"line N: /path"`` per offender (empty when the Dockerfile is fine). URLs and paths inside
    a HEALTHCHECK or CMD's own strings (such as ``/api/health``) are not file paths and are not checked.
    """
    bad: list[str] = []
    for stage in stages:
        for ins in stage.instructions:
            if ins.keyword not in {"RUN", "ENV", "COPY", "WORKDIR", "VOLUME"}:
                continue
            text = ins.args + " " + " ".join(ins.flags.values())
            for path in _PATH_RE.findall(text):
                if _mapped_prefix(path) is None and not path.startswith(SYSTEM_PATHS):
                    bad.append(f"line {ins.line}: {path}")
    return bad


def _mapped_prefix(path: str) -> str | None:
    for prefix in MAPPED:
        if path == prefix or path.startswith(prefix + "/"):
            return prefix
    return None


def _map(text: str, root: Path) -> str:
    """``text`` with every mapped container path moved under ``root``."""

    def repl(m: re.Match[str]) -> str:
        path = m.group(1)
        return f"{root}{path}" if _mapped_prefix(path) else path

    return _PATH_RE.sub(repl, text)


def _exec_form(ins: Instruction) -> list[str]:
    """The argv of an exec-form (JSON array) ``CMD`` or ``HEALTHCHECK CMD``."""
    text = ins.args.removeprefix("CMD").strip() if ins.keyword == "HEALTHCHECK" else ins.args
    try:
        argv = json.loads(text)
    except json.JSONDecodeError as e:
        raise DockerfileError(f"Dockerfile line {ins.line}: {ins.keyword} must be an exec-form JSON array: {e}") from e
    if not (isinstance(argv, list) and argv and all(isinstance(a, str) for a in argv)):
        raise DockerfileError(f"Dockerfile line {ins.line}: {ins.keyword} must be a non-empty list of strings")
    return argv


def _env_pairs(ins: Instruction) -> list[tuple[str, str]]:
    """``ENV a=1 b=2`` as pairs (values shell-unquoted); the legacy ``ENV a 1`` form is refused."""
    pairs = []
    for word in shlex.split(ins.args, posix=True):
        name, eq, value = word.partition("=")
        if not eq:
            raise DockerfileError(f"Dockerfile line {ins.line}: ENV must be written name=value, got {word!r}")
        pairs.append((name, value))
    return pairs


def _shell_value(value: str) -> str:
    """``value`` for ``export NAME=...``: quoted, except that ``$NAME`` still expands (as ENV expands it)."""
    return '"' + value.replace("\\", "\\\\").replace('"', '\\"').replace("`", "\\`") + '"'


def _duration_s(text: str, line: int) -> float:
    m = re.fullmatch(r"(\d+(?:\.\d+)?)(ms|s|m)", text)
    if not m:
        raise DockerfileError(f"Dockerfile line {line}: cannot read the duration {text!r}")
    return float(m.group(1)) * {"ms": 0.001, "s": 1.0, "m": 60.0}[m.group(2)]


def _run_commands(ins: Instruction, root: Path) -> list[str]:
    """The shell lines of one RUN: top-level ``&&`` parts, image-only ones as comments."""
    for name, value in ins.flags.items():
        if name != "mount":
            raise DockerfileError(f"Dockerfile line {ins.line}: RUN --{name} is not translated")
        opts = dict(part.partition("=")[::2] for part in value.split(","))
        if opts.get("type") != "bind" or _map(opts.get("source", ""), root) != _map(opts.get("target", ""), root):
            raise DockerfileError(
                f"Dockerfile line {ins.line}: only a bind mount of a stage's folder at the same path is translated"
            )
    lines = []
    for part in ins.args.split(" && "):
        words = part.split()
        if words and words[0] in IMAGE_ONLY:
            lines.append(f"# in the image only (needs root there): {part}")
            continue
        mapped = _map(part, root)
        for option in DROPPED_OPTIONS:
            mapped = mapped.replace(f" {option}", "")
        lines.append(mapped)
    return lines


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now (the kernel's choice)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def generate(dockerfile: Path, context: Path, root: Path, python: str, ports: tuple[int, int]) -> str:
    """The bash script that runs ``dockerfile``'s steps under ``root``, with ``context`` as build context.

    Args:
        dockerfile: the Dockerfile to translate.
        context: the build context (the repository root), where ``COPY`` sources are read.
        root: an empty folder standing in for the image's file system.
        python: the host's CPython 3.11 that stands in for the base image's ``python``.
        ports: free loopback ports for ``GAITSCOPE_PORT`` and ``GAITSCOPE_VISER_PORT``.

    Raises:
        DockerfileError: an unmapped path, or an instruction or option not translated (names the line).
    """
    stages = parse(dockerfile.read_text())
    if bad := check_paths(stages):
        raise DockerfileError(f"{dockerfile}: unmapped absolute paths (add them to steps.MAPPED): {', '.join(bad)}")
    q = shlex.quote
    out = [
        "#!/usr/bin/env bash",
        f"# Generated by docker/steps.py from {dockerfile.name}: its steps outside a container, under {root}.",
        "set -euo pipefail",
        f"mkdir -p {q(str(root / 'bin'))}",
        f"ln -sf {q(python)} {q(str(root / 'bin' / 'python'))}  # the base image's python",
        f"export PATH={q(str(root / 'bin'))}:\"$PATH\"",
    ]
    final = stages[-1]
    for stage in stages:
        out += ["", f"# ---- stage {stage.name} (FROM {stage.base}) ----", "("]
        out.append(f"cd {q(str(root))}")
        health: Instruction | None = None
        cmd: Instruction | None = None
        for ins in stage.instructions:
            k = ins.keyword
            if k in {"LABEL", "EXPOSE", "ARG", "STOPSIGNAL"}:
                out.append(f"# {k} {ins.args}  (image metadata)")
            elif k == "WORKDIR":
                path = _map(ins.args, root)
                out += [f"mkdir -p {q(path)}", f"cd {q(path)}"]
            elif k == "COPY":
                out += _copy_lines(ins, context, root)
            elif k == "RUN":
                out += _run_commands(ins, root)
            elif k == "ENV":
                out += [f"export {name}={_shell_value(_map(value, root))}" for name, value in _env_pairs(ins)]
            elif k == "USER":
                out.append(f"# USER {ins.args}: not switched, the steps run as whoever runs this script")
            elif k == "VOLUME":
                for path in json.loads(ins.args) if ins.args.startswith("[") else ins.args.split():
                    out.append(f"mkdir -p {q(_map(path, root))}  # VOLUME")
            elif k == "HEALTHCHECK":
                health = ins
            elif k == "CMD":
                cmd = ins
            else:
                raise DockerfileError(f"Dockerfile line {ins.line}: {k} is not translated")
        if stage is final:
            if cmd is None or health is None:
                raise DockerfileError(f"{dockerfile}: the final stage needs a CMD and a HEALTHCHECK")
            out += _serve_lines(cmd, health, root, ports)
        out.append(")")
    out += ["", "echo 'steps: every step of the Dockerfile ran'"]
    return "\n".join(out) + "\n"


def _copy_lines(ins: Instruction, context: Path, root: Path) -> list[str]:
    unknown = set(ins.flags) - {"from", "chown", "chmod"}
    if unknown:
        raise DockerfileError(f"Dockerfile line {ins.line}: COPY --{sorted(unknown)[0]} is not translated")
    *sources, dest = ins.args.split()
    q = shlex.quote
    if "from" in ins.flags:  # from another stage: that stage's folder is already under root
        return [f"cp -a {q(_map(s, root))} {q(_map(dest, root))}" for s in sources if _map(s, root) != _map(dest, root)]
    ignore = " ".join(f"--exclude={q(p)}" for p in _COPY_IGNORE)
    lines = []
    for s in sources:
        if not (context / s).exists():
            raise DockerfileError(f"Dockerfile line {ins.line}: COPY source {s} is not in the build context")
        # rsync-like copy with excludes, by tar (always there): a folder's contents, or one file.
        into = _map(dest, root) if dest.startswith("/") else dest
        source = q(str(context / s))
        if (context / s).is_dir():
            lines.append(f"mkdir -p {q(into)} && tar -C {source} {ignore} -cf - . | tar -C {q(into)} -xf -")
        else:
            folder = into if into.endswith("/") else str(Path(into).parent)
            lines.append(f"mkdir -p {q(folder)} && cp {source} {q(into)}")
    return lines


def _serve_lines(cmd: Instruction, health: Instruction, root: Path, ports: tuple[int, int]) -> list[str]:
    """Check the image's settings, start CMD on loopback, poll HEALTHCHECK as Docker does, then stop it."""
    q = shlex.quote
    interval = _duration_s(health.flags.get("interval", "30s"), health.line)
    start_period = _duration_s(health.flags.get("start-period", "0s"), health.line)
    timeout = _duration_s(health.flags.get("timeout", "30s"), health.line)
    retries = int(health.flags.get("retries", "3"))
    if not health.args.startswith("CMD"):
        raise DockerfileError(f"Dockerfile line {health.line}: HEALTHCHECK must be HEALTHCHECK [options] CMD [...]")
    probe = " ".join(q(_map(a, root)) for a in _exec_form(health))
    serve = " ".join(q(_map(a, root)) for a in _exec_form(cmd))
    deadline = start_period + retries * interval
    overrides = f"GAITSCOPE_HOST=127.0.0.1 GAITSCOPE_PORT={ports[0]} GAITSCOPE_VISER_PORT={ports[1]}"
    log = q(str(root / "server.log"))
    check_settings = (
        "from gaitscope.server.settings import Settings; s = Settings(); "
        "print(f'steps: the image environment is accepted: host {s.host}, environment {s.environment}')"
    )
    return [
        "",
        "# ---- the container: its environment, then CMD and HEALTHCHECK ----",
        "# The image's environment as it is (0.0.0.0 included) must be accepted by the server's settings.",
        f"python -c {q(check_settings)}",
        f"# CMD, on loopback and free ports ({', '.join(OVERRIDES)} overridden), SQLite in the data folder.",
        f"env {overrides} {serve} > {log} 2>&1 &",
        "server=$!",
        "started=$SECONDS",
        "trap 'kill $server 2>/dev/null || true' EXIT",
        f"export {overrides}",
        f"# HEALTHCHECK: Docker probes every {interval:g} s after a {start_period:g} s start period and gives up",
        f"# after {retries} failures; here the probe runs every second until {deadline:g} s have passed.",
        "healthy=0",
        f"for _ in $(seq 1 {int(deadline)}); do",
        f"    if timeout {timeout:g} {probe} 2>/dev/null; then healthy=1; break; fi",
        "    if ! kill -0 $server 2>/dev/null; then break; fi",
        "    sleep 1",
        "done",
        'if [ "$healthy" != 1 ]; then',
        f"    echo 'steps: HEALTHCHECK never passed; the server said:' >&2; tail -n 40 {log} >&2; exit 1",
        "fi",
        f'echo "steps: HEALTHCHECK passed $((SECONDS - started)) s after the server started'
        f' (start period {start_period:g} s)"',
        "# The dashboard's browser files are served (the image copies web/ beside the installed packages).",
        "python -c "
        + q(
            "import urllib.request; "
            f"r = urllib.request.urlopen('http://127.0.0.1:{ports[0]}/', timeout=10); body = r.read(); "
            "assert r.status == 200 and b'<html' in body.lower(), (r.status, body[:200]); "
            "print('steps: the dashboard page is served:', r.geturl())"
        ),
        f"# docker stop: SIGTERM, then SIGKILL after {STOP_GRACE_S} s.",
        "kill -TERM $server",
        f"for _ in $(seq 1 {STOP_GRACE_S * 10}); do kill -0 $server 2>/dev/null || break; sleep 0.1; done",
        "if kill -0 $server 2>/dev/null; then",
        f"    echo 'steps: the server did not stop within {STOP_GRACE_S} s of SIGTERM' >&2; exit 1",
        "fi",
        "status=0; wait $server || status=$?",
        "trap - EXIT",
        "# uvicorn shuts down cleanly, then re-raises the signal: 143 (128 + SIGTERM) is a clean stop, as for Docker.",
        f"clean=0; grep -q 'Application shutdown complete' {log} && clean=1",
        'if [ "$status" = 0 ] || { [ "$status" = 143 ] && [ "$clean" = 1 ]; }; then',
        "    echo \"steps: the server stopped cleanly on SIGTERM (exit status $status)\"",
        "else",
        f"    echo \"steps: the server did not stop cleanly (exit status $status)\" >&2; tail -n 40 {log} >&2; exit 1",
        "fi",
    ]


def main(argv: list[str] | None = None) -> int:
    """``python docker/steps.py --root DIR [--print]``: write (or print) the script for ``DIR``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    here = Path(__file__).resolve().parent
    p.add_argument("--dockerfile", type=Path, default=here / "Dockerfile")
    p.add_argument("--context", type=Path, default=here.parent, help="build context (default: the repository)")
    p.add_argument("--root", type=Path, required=True, help="empty folder standing in for the image's file system")
    p.add_argument("--python", default=sys.executable, help="CPython 3.11 standing in for the image's python")
    p.add_argument("--out", type=Path, help="write the script here (default: standard output)")
    a = p.parse_args(argv)
    try:
        script = generate(a.dockerfile, a.context.resolve(), a.root.resolve(), a.python, (free_port(), free_port()))
    except (DockerfileError, OSError) as e:
        print(f"steps: error: {e}", file=sys.stderr)
        return 2
    if a.out is None:
        sys.stdout.write(script)
    else:
        a.out.write_text(script)
    return 0


if __name__ == "__main__":
    sys.exit(main())
