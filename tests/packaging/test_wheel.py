"""The wheel gaitscope builds: the folders server/, sessions/, estimators/ and web/ installed as one import
namespace, ``gaitscope.*``, and nothing at the top level of site-packages but ``gaitscope`` (issue #22: a
top-level ``server`` or ``sessions`` would collide with other projects)."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("estimators", "server", "sessions")

#: Builds a wheel (pip fetches setuptools into its isolated build environment): seconds.
pytestmark = pytest.mark.slow


def _listed() -> set[str]:
    return set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])


def test_every_python_package_of_the_folders_is_listed_under_gaitscope() -> None:
    found = {
        "gaitscope." + ".".join(p.parent.relative_to(ROOT).parts)
        for folder in FOLDERS
        for p in (ROOT / folder).rglob("__init__.py")
    }
    assert found <= _listed(), f"add to pyproject.toml's [tool.setuptools] packages: {sorted(found - _listed())}"
    stale = {p for p in _listed() if not (ROOT / Path(*p.split(".")[1:])).is_dir()}
    assert not stale, f"listed in pyproject.toml but no such folder: {sorted(stale)}"


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--wheel-dir", str(out), str(ROOT)],
        check=True,
        capture_output=True,
    )
    (path,) = out.glob("gaitscope-*.whl")
    return path


def test_the_wheel_holds_gaitscope_alone_with_its_data_and_browser_files(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"gaitscope"}, tops
    for needed in (
        "gaitscope/server/cli.py",
        "gaitscope/sessions/schema.py",
        "gaitscope/estimators/protocol.py",
        "gaitscope/sessions/migrations/alembic.ini",
        "gaitscope/web/index.html",
        "gaitscope/web/vendor/uPlot.esm.js",
    ):
        assert needed in names, needed
    shipped_data = {Path(n).name for n in names if n.startswith("gaitscope/sessions/data/")}
    data = ROOT / "sessions" / "data"
    assert shipped_data == {p.name for p in data.iterdir() if p.suffix in (".csv", ".json", ".npz")}
    entry = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith("entry_points.txt"))).decode()
    assert "gaitscope = gaitscope.server.cli:main" in entry


def test_installed_from_the_wheel_it_imports_as_gaitscope_and_not_as_server(wheel: Path, tmp_path: Path) -> None:
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    code = (
        "import importlib.util, gaitscope.estimators.protocol as p, gaitscope.server.app as a;"
        "print(p.__file__); print(a.WEB_DIR.is_dir());"
        "print([n for n in ('server', 'sessions', 'estimators') if importlib.util.find_spec(n)])"
    )
    env = {**os.environ, "PYTHONPATH": str(site)}
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, check=True, capture_output=True, text=True
    ).stdout.split("\n")
    assert out[0].startswith(str(site)), out  # the wheel's copy, not the checkout's
    assert out[1] == "True"  # the server finds the browser files beside it
    assert out[2] == "[]"  # no top-level server, sessions or estimators
