"""The browser's wire types, generated from :mod:`gaitscope.sessions.schema` (and :mod:`gaitscope.sessions.registry`):
``gaitscope wire --out web/wire.js``.

``web/wire.js`` is the browser's one statement of the schema: a JSDoc ``@typedef`` for every class in
``schema.WIRE`` and every class their JSON schemas refer to (fields and types from
``model_json_schema()``, which ``GET /api/schema`` serves too), and the bounds the browser checks
before the server does (``SETTING_LIMITS``, ``SENSOR_LIMITS``, every field's ``FIELD_LIMITS``) with
the default ``SessionSettings``, the names on screen and units of the settings and of the gait-state
quantities (one table each: ``schema.SETTING_NAMES``, ``descriptor.QUANTITY_NAMES``), and every
registered estimator as its descriptor states it
(:data:`gaitscope.sessions.registry.DESCRIPTORS`: its name on screen, outputs, quantities, plots, tunables and
roles), so that no view names an estimator. The file is committed (the UI has no build step);
``tests/server/test_wire.py`` fails when it differs from what :func:`render` makes of the schema.
"""

from __future__ import annotations

import json
import re
import typing
from pathlib import Path
from typing import Any, Final

from gaitscope.estimators.descriptor import QUANTITY_NAMES, Descriptor
from gaitscope.sessions import registry, schema
from gaitscope.sessions.live.torque_rule import RAISING

__all__ = ["COMMAND", "render", "write"]

#: How to regenerate the file (in its header and in the drift test's message).
COMMAND: Final = "gaitscope wire --out web/wire.js"
#: JSON-schema keywords that bound a value, and their names in ``FIELD_LIMITS``.
_LIMIT_KEYS: Final = {
    "minimum": "min",
    "maximum": "max",
    "exclusiveMinimum": "exclusiveMin",
    "exclusiveMaximum": "exclusiveMax",
    "minLength": "minLength",
    "maxLength": "maxLength",
    "pattern": "pattern",
    "minItems": "minItems",
    "maxItems": "maxItems",
}
_IDENTIFIER: Final = re.compile(r"^[A-Za-z_$][A-Za-z0-9_$]*$")
_WIDTH: Final = 110
#: The largest integer a JavaScript number holds exactly (``Number.MAX_SAFE_INTEGER``).
_SAFE_INTEGER: Final = 2**53 - 1

_HEADER: Final = f"""\
// GENERATED from sessions/schema.py and sessions/registry.py by `{COMMAND}`:
// do not edit by hand. Change them and run the command again; tests/server/test_wire.py fails while this
// file differs from what they generate.
//
// JSDoc types of every wire message (the JSON schemas `GET /api/schema` serves, as types), the
// bounds the browser checks before the server does (the server stays the judge: 422, 409), and the
// registered estimators.
"""


def render() -> str:
    """The text of ``web/wire.js`` for the schema as it is now (deterministic: the same schema, the same text)."""
    classes = _classes()
    parts = [_HEADER]
    parts += [_typedef(name, sch) for name, sch in classes.items()]
    parts.append(_browser_message())
    parts.append(
        "/** Freezes an object and every object in it. */\n"
        "function deepFreeze(o) {\n"
        '  for (const v of Object.values(o)) if (v && typeof v === "object") deepFreeze(v);\n'
        "  return Object.freeze(o);\n"
        "}\n"
    )
    settings = {k: {"min": lo, "max": hi, "rate": rate} for k, (lo, hi, rate) in schema.SETTING_LIMITS.items()}
    parts.append(
        _const(
            "SETTING_LIMITS",
            settings,
            "Bounds of every clinician-adjustable setting (`SETTING_LIMITS`): minimum, maximum, and the largest\n"
            "change per second (the server also spaces two changes of a field by `step / rate` seconds).",
            "Readonly<Record<string, {min: number, max: number, rate: number}>>",
        )
    )
    parts.append(
        _const(
            "TORQUE_RULE",
            {"interval_s": schema.TORQUE_RAISE_INTERVAL_S, "raising": [*RAISING, "primary"]},
            "The rule for a settings change that can raise the torque (`gaitscope.sessions.live.torque_rule`): the\n"
            "settings whose rise (or, the primary, whose switch) asks for a confirmation, and the least time between\n"
            "two such changes (`TORQUE_RAISE_INTERVAL_S`). Lowering never asks and is never held back.",
            "Readonly<{interval_s: number, raising: Array<string>}>",
        )
    )
    sensors = {k: {"min": lo, "max": hi} for k, (lo, hi) in schema.SENSOR_LIMITS.items()}
    parts.append(
        _const(
            "SENSOR_LIMITS",
            sensors,
            "Physically plausible range of each sensor channel (`SENSOR_LIMITS`); a value outside it is treated\n"
            "as missing for that sample.",
            "Readonly<Record<string, {min: number, max: number}>>",
        )
    )
    parts.append(
        _const(
            "SETTING_NAMES",
            {k: {"name": name, "unit": unit} for k, (name, unit) in schema.SETTING_NAMES.items()},
            "The name on screen and the unit (\"\": none) of every field a setting event may change\n"
            "(`SETTING_NAMES`): the settings, the primary estimator, the models.",
            "Readonly<Record<string, {name: string, unit: string}>>",
        )
    )
    parts.append(
        _const(
            "QUANTITY_NAMES",
            {k: {"name": name, "unit": unit} for k, (name, unit) in QUANTITY_NAMES.items()},
            "Each gait-state quantity's name on screen and unit (`estimators/descriptor.py` `QUANTITY_NAMES`;\n"
            "a phase in % of its cycle).",
            "Readonly<Record<string, {name: string, unit: string}>>",
        )
    )
    parts.append(
        _const(
            "DEFAULT_SETTINGS",
            schema.SessionSettings().model_dump(mode="json"),
            "A session's settings when none are given (`SessionSettings()`).",
            "Readonly<SessionSettings>",
        )
    )
    parts.append(
        _comment(
            [
                "A plot a view draws of an estimator's outputs (`PlotHint`): its key in the view, title, y label",
                "and the outputs it draws, a line each.",
                "@typedef {object} PlotHint",
                "@property {string} key",
                "@property {string} title",
                "@property {string} y_label",
                "@property {Array<string>} outputs",
            ]
        )
    )
    parts.append(
        _comment(
            [
                "A registered estimator as its descriptor states it (`estimators/descriptor.py`): its name on",
                "screen, its outputs (name: unit; a re-run's columns are `<name>.<output>`), the gait-state",
                "quantity of some of them (`phase`, `stance_phase`, `stride_length`, ...), the plots a view draws",
                "of them, whether a session runs it only when named and whether it is a front end deriving",
                "channels, the name on screen of a model it learns online (setting events whose field is the",
                "estimator's name carry that model's versions) and its gait-fingerprint variant.",
                "@typedef {object} EstimatorInfo",
                "@property {string} label",
                "@property {Record<string, string>} outputs",
                "@property {Record<string, string>} quantities",
                "@property {Array<PlotHint>} plots",
                "@property {boolean} opt_in",
                "@property {boolean} derives",
                "@property {string | null} learned_model",
                '@property {"average" | "personal" | "online" | null} fingerprint',
            ]
        )
    )
    parts.append(
        _const(
            "ESTIMATORS",
            {name: _estimator(d) for name, d in registry.descriptors().items()},
            "Every registered estimator (`sessions.registry.DESCRIPTORS`), in the order a stack runs them.",
            "Readonly<Record<string, EstimatorInfo>>",
        )
    )
    limits = {name: lim for name, sch in classes.items() if (lim := _field_limits(sch))}
    parts.append(
        _comment(
            [
                "The bounds of one field (`FIELD_LIMITS`); a field has only those its schema states.",
                "@typedef {object} FieldLimit",
                *(
                    f"@property {{{'string' if key == 'pattern' else 'number'}}} [{key}]"
                    for key in _LIMIT_KEYS.values()
                ),
            ]
        )
    )
    parts.append(
        _const(
            "FIELD_LIMITS",
            limits,
            "Bounds of every bounded field, per class: `min`, `max` (inclusive), `exclusiveMin`, `exclusiveMax`,\n"
            "`minLength`, `maxLength`, `pattern` (a regular expression source), `minItems`, `maxItems`.",
            "Readonly<Record<string, Record<string, FieldLimit>>>",
        )
    )
    return "\n".join(parts)


def _estimator(d: Descriptor) -> dict[str, Any]:
    """What the browser knows of a registered estimator (:class:`EstimatorInfo` in ``wire.js``)."""
    return {
        "label": d.label,
        "outputs": dict(d.declared_outputs),
        "quantities": dict(d.quantities),
        "plots": [{"key": p.key, "title": p.title, "y_label": p.y_label, "outputs": list(p.outputs)} for p in d.plots],
        "opt_in": d.opt_in,
        "derives": d.derives,
        "learned_model": d.learned_model,
        "fingerprint": d.fingerprint,
    }


def _browser_message() -> str:
    """The union of the messages a browser's session socket receives (``streams.BrowserMessage``), each
    told apart by its ``type``: the type of ``openSessionStream``'s messages (``web/api.js``)."""
    from gaitscope.server.routes.streams import BrowserMessage  # the socket's own statement of what it sends

    names = " | ".join(cls.__name__ for cls in typing.get_args(BrowserMessage))
    return _comment(
        [
            "A message of a session's stream to the browser (`/ws/sessions/{id}`), told apart by its `type`.",
            f"@typedef {{{names}}} BrowserMessage",
        ]
    )


def write(path: Path) -> bool:
    """Write :func:`render`'s text to ``path``; whether the file changed."""
    return write_generated(path, render())


def write_generated(path: Path, text: str) -> bool:
    """Write a generated file's ``text`` to ``path`` unless it holds that already; whether it changed."""
    if path.is_file() and path.read_text(encoding="utf-8") == text:
        return False
    path.write_text(text, encoding="utf-8")
    return True


def _classes() -> dict[str, dict[str, Any]]:
    """Every class's JSON schema by name: ``schema.WIRE`` in its order, then the classes they refer to by
    name. A class met twice must have the same schema both times."""
    found: dict[str, dict[str, Any]] = {}
    nested: dict[str, dict[str, Any]] = {}

    def add(into: dict[str, dict[str, Any]], name: str, sch: dict[str, Any]) -> None:
        sch = {k: v for k, v in sch.items() if k != "$defs"}
        for seen in (found.get(name), nested.get(name)):
            if seen is not None and seen != sch:
                raise ValueError(f"two different JSON schemas are both called {name}")
        into.setdefault(name, sch)

    for cls in schema.WIRE:
        sch = cls.model_json_schema()
        add(found, cls.__name__, sch)
        for name, sub in sch.get("$defs", {}).items():
            add(nested, name, sub)
    return found | {name: sch for name, sch in sorted(nested.items()) if name not in found}


def _typedef(name: str, sch: dict[str, Any]) -> str:
    lines = [line.rstrip() for line in sch.get("description", "").splitlines()]
    lines.append(f"@typedef {{object}} {name}")
    required = set(sch.get("required", ()))
    for field, prop in sch.get("properties", {}).items():
        label = field if field in required else f"[{field}{_default(prop)}]"
        note = " ".join(p for p in (prop.get("description", ""), _bounds(prop)) if p)
        # TypeScript reads a note that starts with a digit after ``[name]`` as part of a default value ("1x
        # real time": error TS1351); JSDoc's " - " separator says where the note begins.
        sep = " - " if note[:1].isdigit() else " "
        lines.append(f"@property {{{_type(prop)}}} {label}{sep + note if note else ''}")
    return _comment(lines)


def _comment(lines: list[str]) -> str:
    """A JSDoc block of these lines (a ``*/`` in them escaped, so that it cannot end the comment)."""
    body = "\n".join((" * " + line.replace("*/", "*\\/")).rstrip() for line in lines)
    return f"/**\n{body}\n */\n"


def _type(sch: dict[str, Any]) -> str:
    """A JSON schema as a JSDoc (TypeScript-flavoured) type."""
    if "$ref" in sch:
        return str(sch["$ref"]).rsplit("/", 1)[-1]
    if "const" in sch:
        return json.dumps(sch["const"])
    if "enum" in sch:
        return " | ".join(json.dumps(v) for v in sch["enum"])
    for key in ("anyOf", "oneOf"):
        if key in sch:
            return " | ".join(_type(s) for s in sch[key])
    kind = sch.get("type")
    if isinstance(kind, list):
        return " | ".join(_type({**sch, "type": k}) for k in kind)
    if kind == "array":
        if "prefixItems" in sch:
            return "[" + ", ".join(_type(s) for s in sch["prefixItems"]) + "]"
        return f"Array<{_type(sch.get('items', {}))}>"
    if kind == "object":
        extra = sch.get("additionalProperties", True)
        patterns = list(sch.get("patternProperties", {}).values())
        if extra is True and len(patterns) == 1:  # keys of a pattern (``dict[EstimatorName, ...]``)
            extra = patterns[0]
        return f"Object<string, {_type(extra) if isinstance(extra, dict) else '*'}>"
    return {"string": "string", "integer": "number", "number": "number", "boolean": "boolean", "null": "null"}.get(
        str(kind), "*"
    )


def _default(prop: dict[str, Any]) -> str:
    """``=value`` for a scalar default (lists and objects are left to the schema)."""
    if "default" not in prop or isinstance(prop["default"], list | dict):
        return ""
    return "=" + json.dumps(prop["default"])


def _limits(prop: dict[str, Any]) -> dict[str, Any]:
    """A property's bounds; of a nullable property (``anyOf`` with null), those of its other branch."""
    found = {k: v for k, v in prop.items() if k in _LIMIT_KEYS}
    for branch in prop.get("anyOf", ()):
        found |= {k: v for k, v in branch.items() if k in _LIMIT_KEYS}
    return {name: found[k] for k, name in _LIMIT_KEYS.items() if k in found}


def _bounds(prop: dict[str, Any]) -> str:
    """The numeric bounds of a property in words, e.g. ``(0.5..1.3)``, ``(>= 1)``."""
    lim = _limits(prop)
    lo, hi = lim.get("min"), lim.get("max")
    if lo is not None and hi is not None:
        return f"({lo:g}..{hi:g})" if max(abs(lo), abs(hi)) < 1e15 else f"({lo}..{hi})"
    if lo is not None:
        return f"(>= {lo:g})"
    if hi is not None:
        return f"(<= {hi:g})"
    return ""


def _field_limits(sch: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {field: lim for field, prop in sch.get("properties", {}).items() if (lim := _limits(prop))}


def _const(name: str, value: Any, doc: str, type_: str) -> str:
    comment = _comment([*doc.splitlines(), f"@type {{{type_}}}"])
    return f"{comment}export const {name} = deepFreeze({_js(value, 0)});\n"


def _js(value: Any, indent: int) -> str:
    """A JavaScript literal of JSON data: on one line if it fits, else one key per line."""
    if isinstance(value, list):
        return "[" + ", ".join(_js(v, indent) for v in value) + "]"
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > _SAFE_INTEGER:
        # A JavaScript number cannot hold it (int64's maximum as a bound): the double it becomes anyway,
        # written so that the literal says the value the browser holds.
        return repr(float(value))
    if not isinstance(value, dict):
        return json.dumps(value)
    if not value:
        return "{}"
    items = [f"{_key(k)}: {_js(v, indent + 2)}" for k, v in value.items()]
    flat = "{ " + ", ".join(items) + " }"
    if "\n" not in flat and indent + len(flat) <= _WIDTH:
        return flat
    pad = " " * (indent + 2)
    return "{\n" + "".join(f"{pad}{item},\n" for item in items) + " " * indent + "}"


def _key(key: str) -> str:
    return key if _IDENTIFIER.match(key) else json.dumps(key)
