"""``web/wire.js`` is what ``server/wire.py`` makes of the schema: committed, current, and valid JavaScript."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import typing
from pathlib import Path

import pytest

from gaitscope.server.routes import streams
from gaitscope.server.wire import _LIMIT_KEYS, COMMAND, render
from gaitscope.sessions import registry, schema

WIRE_JS = Path(__file__).resolve().parents[2] / "web" / "wire.js"


def test_committed_wire_js_is_what_the_schema_generates() -> None:
    committed = WIRE_JS.read_text(encoding="utf-8") if WIRE_JS.is_file() else ""
    if committed != render():
        pytest.fail(f"web/wire.js differs from sessions/schema.py: run `{COMMAND}` and commit the result")


def _schemas() -> dict[str, dict]:
    """Every wire class's JSON schema, and those of the classes they refer to, by name."""
    out: dict[str, dict] = {}
    for cls in schema.WIRE:
        sch = cls.model_json_schema()
        out.setdefault(cls.__name__, sch)
        for name, sub in sch.get("$defs", {}).items():
            out.setdefault(name, sub)
    return out


def test_every_wire_class_and_every_class_it_refers_to_is_typed_field_by_field() -> None:
    typedefs = {}
    for block in render().split("/**")[1:]:
        if m := re.search(r"@typedef \{object\} (\w+)", block):
            typedefs[m[1]] = re.findall(r"@property \{([^}]*)\} \[?(\w+)", block)
    schemas = _schemas()
    # FIELD_LIMITS' entry type, not a wire class: one optional property per bound
    assert typedefs.pop("FieldLimit") == [("string" if k == "pattern" else "number", k) for k in _LIMIT_KEYS.values()]
    # ESTIMATORS' entry type, not a wire class: an estimator's descriptor as the browser reads it
    assert [field for _, field in typedefs.pop("EstimatorInfo")] == [
        "label", "outputs", "quantities", "plots", "opt_in", "derives", "learned_model", "fingerprint"
    ]  # fmt: skip
    assert typedefs.pop("PlotHint") == [("string", "key"), ("string", "title"), ("string", "y_label"),
                                        ("Array<string>", "outputs")]  # fmt: skip
    assert set(typedefs) == set(schemas)
    for name, sch in schemas.items():
        assert [field for _, field in typedefs[name]] == list(sch["properties"]), name
        assert all(type_ and "*" not in type_.replace("Object<string, *>", "") for type_, _ in typedefs[name]), name
    sources = "SimulatedSource | ReplaySource | DeviceSource | LslSource | UploadSource"
    assert (sources, "source") in typedefs["SessionCreate"]
    assert ("number | null", "torque_gain") in typedefs["SettingsChange"]
    assert ("Array<GaitState>", "states") in typedefs["StreamBatch"]
    assert ("Object<string, string>", "refused") in typedefs["RerunChoices"]
    assert "@property {number | null} [torque_gain=null] (0..3)" in render()


def test_every_message_a_socket_sends_is_a_wire_class() -> None:
    browser = typing.get_args(streams.BrowserMessage)
    union = " | ".join(cls.__name__ for cls in browser)
    assert f"@typedef {{{union}}} BrowserMessage" in render()  # the type of openSessionStream's messages
    sent = set(browser) | set(typing.get_args(streams.DeviceMessage))
    assert sent == {schema.Hello, schema.StreamBatch, schema.Health, schema.EventMessage, schema.SettingsMessage,
                    schema.TorqueCommand, schema.DeviceNotice}  # fmt: skip
    assert sent <= set(schema.WIRE)
    assert set(typing.get_args(typing.get_args(schema.ServerMessage)[0])) <= sent


def test_setting_bounds_are_stated_once() -> None:
    """``SessionSettings`` and ``SettingsChange`` take their bounds from ``SETTING_LIMITS``."""
    for cls in (schema.SessionSettings, schema.SettingsChange):
        for name, (lo, hi, _) in schema.SETTING_LIMITS.items():
            assert schema.field_bounds(cls, name) == (lo, hi)
    assert set(schema.SETTING_LIMITS) < set(schema.SessionSettings.model_fields)


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_wire_js_is_a_module_whose_constants_are_the_schemas(tmp_path: Path) -> None:
    module = tmp_path / "wire.mjs"
    module.write_text(render(), encoding="utf-8")
    script = (
        f"import * as w from {json.dumps(module.as_uri())};"
        "console.log(JSON.stringify({s: w.SETTING_LIMITS, n: w.SENSOR_LIMITS, d: w.DEFAULT_SETTINGS,"
        " f: w.FIELD_LIMITS, e: w.ESTIMATORS, frozen: Object.isFrozen(w.SETTING_LIMITS.torque_gain)}));"
    )
    done = subprocess.run(
        ["node", "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    assert got["s"] == {k: {"min": lo, "max": hi, "rate": r} for k, (lo, hi, r) in schema.SETTING_LIMITS.items()}
    assert got["n"] == {k: {"min": lo, "max": hi} for k, (lo, hi) in schema.SENSOR_LIMITS.items()}
    assert got["d"] == schema.SessionSettings().model_dump(mode="json")
    assert got["f"]["SubjectCreate"]["leg_length_m"] == {"min": 0.5, "max": 1.3}
    assert got["f"]["ReplaySource"]["speed"] == {"min": 1.0, "max": 50.0}
    assert list(got["e"]) == list(registry.ESTIMATORS)  # the order a stack runs them in
    assert {n: (e["label"], e["outputs"], e["opt_in"]) for n, e in got["e"].items()} == {
        name: (d.label, dict(d.outputs), name in registry.OPT_IN) for name, d in registry.DECLARED.items()
    }
    assert got["e"]["tbe"] == {
        "label": "Timing-based estimate",
        "outputs": {"phase": "1", "phase_rate": "1/s"},
        "quantities": {"phase": "phase", "phase_rate": "phase_rate"},
        "plots": [],
        "opt_in": False,
        "derives": False,
        "learned_model": None,
        "fingerprint": None,
    }
    # what the views read instead of naming an estimator
    gp, intent = got["e"]["gp_ekf"], got["e"]["intent"]
    assert (gp["quantities"]["phase"], gp["learned_model"], gp["opt_in"]) == ("stance_phase", "GP-EKF model", True)
    assert intent["plots"] == [
        {
            "key": "intent",
            "title": "Speed-change intent: desired vs actual speed",
            "y_label": "m/s",
            "outputs": ["desired_speed_m_s", "speed_m_s"],
        }
    ]
    assert {n: e["fingerprint"] for n, e in got["e"].items() if e["fingerprint"]} == {
        "fp_avg": "average",
        "fp_ls": "personal",
        "fp_gf": "online",
    }
    derivers = [n for n in registry.ESTIMATORS if n in registry.DERIVERS]
    assert [n for n, e in got["e"].items() if e["derives"]] == derivers
    assert got["frozen"] is True
