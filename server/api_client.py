"""The browser's REST client, generated from the app's OpenAPI document: ``gaitscope api-client --out
web/api_client.js``.

``web/api_client.js`` has one function per operation of :func:`gaitscope.server.app.create_app`'s
``openapi()`` (named after its route function, camelCase: ``GET /api/trials/{trial_id}`` is
``getTrial(trialId)``), and one ``<name>Url`` function per operation that builds its address (for links,
downloads and the few requests that need their own ``fetch``). Arguments: the path parameters in the
path's order, then the JSON body (or the raw bytes of an ``application/octet-stream`` body), then the query
parameters as one object (``null`` and ``undefined`` values left out). Types are JSDoc: bodies and answers
name the typedefs of ``web/wire.js``, so that TypeScript's check of ``web/`` checks every call. Transport
(CSRF header, 401, plain-words errors) stays in ``web/api.js``. The file is committed (the UI has no build
step); ``tests/server/test_api_client.py`` fails when it differs from what :func:`render` makes of the app.
"""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path
from typing import Any, Final

from gaitscope.server import wire

__all__ = ["COMMAND", "Operation", "operations", "render", "write"]

#: How to regenerate the file (in its header and in the drift test's message).
COMMAND: Final = "gaitscope api-client --out web/api_client.js"
_METHODS: Final = ("get", "put", "post", "patch", "delete")
_TYPEDEF: Final = re.compile(r"@typedef \{object\} (\w+)")

_HEADER: Final = f"""\
// GENERATED from the app's OpenAPI document (gaitscope.server.app.create_app().openapi()) by
// `{COMMAND}`: do not edit by hand. Change the routes and run the command
// again; tests/server/test_api_client.py fails while this file differs from what they generate.
//
// One function per REST operation (its path parameters, then its body, then its query parameters as one
// object), each returning the operation's JSON answer (null for 204), and one `<name>Url` per operation: its
// address. Errors are web/api.js's ApiError.
"""


class Operation:
    """One operation of the OpenAPI document, as the client calls it."""

    def __init__(self, path: str, method: str, op: dict[str, Any]) -> None:
        self.path = path
        self.method = method.upper()
        self.op = op
        self.name = _camel(_route_name(op["operationId"], path, method))
        params = op.get("parameters", [])
        self.path_params = [p for p in params if p["in"] == "path"]
        self.query_params = [p for p in params if p["in"] == "query"]
        request: dict[str, Any] = op.get("requestBody", {})
        content: dict[str, Any] = request.get("content", {})
        self.body_kind = "json" if "application/json" in content else "bytes" if content else None
        first: dict[str, Any] = next(iter(content.values()), {})
        self.body_schema: dict[str, Any] = first.get("schema", {})
        self.body_required = bool(request.get("required", False))
        ok = sorted(code for code in op.get("responses", {}) if code.startswith("2"))
        answer = op["responses"][ok[0]] if ok else {}
        self.status = ok[0] if ok else ""
        self.answer_schema: dict[str, Any] | None = answer.get("content", {}).get("application/json", {}).get("schema")


def operations(doc: dict[str, Any]) -> list[Operation]:
    """Every operation of the document, in its order (paths, then the methods of each)."""
    ops = [Operation(path, m, item[m]) for path, item in doc["paths"].items() for m in _METHODS if m in item]
    seen: dict[str, str] = {}
    for o in ops:
        if o.name in seen:
            raise ValueError(f"two operations are both called {o.name}: {seen[o.name]} and {o.method} {o.path}")
        seen[o.name] = f"{o.method} {o.path}"
    return ops


def render(doc: dict[str, Any] | None = None) -> str:
    """The text of ``web/api_client.js`` for the app's routes as they are now (deterministic)."""
    if doc is None:
        from gaitscope.server.app import create_app

        doc = create_app().openapi()
    typed = set(_TYPEDEF.findall(wire.render()))
    ops = operations(doc)
    used: set[str] = set()
    blocks = [_operation(o, typed, used) for o in ops]
    imports = 'import { api, apiBytes, query } from "./api.js";\n'
    typedefs = "".join(f'/** @typedef {{import("./wire.js").{n}}} {n} */\n' for n in sorted(used))
    helper = (
        "/** A path parameter as it goes in the address. @param {string | number} v */\n"
        "const _p = (v) => encodeURIComponent(String(v));\n"
    )
    return "\n".join([_HEADER, imports, typedefs, helper, *blocks])


def write(path: Path) -> bool:
    """Write :func:`render`'s text to ``path``; whether the file changed."""
    return wire.write_generated(path, render())


def _route_name(operation_id: str, path: str, method: str) -> str:
    """The route function's name: FastAPI's operation id is ``<name><path>_<method>`` with non-word characters
    as ``_``."""
    suffix = re.sub(r"\W", "_", path) + "_" + method.lower()
    if not operation_id.endswith(suffix):
        raise ValueError(f"operation id {operation_id!r} is not FastAPI's default for {method.upper()} {path}")
    return operation_id[: -len(suffix)]


def _camel(snake: str) -> str:
    head, *rest = snake.split("_")
    return head + "".join(w[:1].upper() + w[1:] for w in rest)


def _type(sch: dict[str, Any] | None, typed: set[str], used: set[str]) -> str:
    """A JSON schema as a JSDoc type; a class that ``web/wire.js`` types is named, others are ``object``."""
    if not sch:
        return "*"
    if "$ref" in sch:
        name = str(sch["$ref"]).rsplit("/", 1)[-1]
        if name in typed:
            used.add(name)
            return name
        return "object"
    for key in ("anyOf", "oneOf"):
        if key in sch:
            return " | ".join(_type(s, typed, used) for s in sch[key])
    if sch.get("type") == "array":
        return f"Array<{_type(sch.get('items'), typed, used)}>"
    if sch.get("type") == "object" and isinstance(sch.get("additionalProperties"), dict):
        return f"Object<string, {_type(sch['additionalProperties'], typed, used)}>"
    if sch.get("type") == "string" and sch.get("format") == "binary":
        return "Blob"
    return wire._type(sch)


def _operation(o: Operation, typed: set[str], used: set[str]) -> str:
    names = [_camel(p["name"]) for p in o.path_params]
    address = re.sub(r"\{(\w+)\}", lambda m: "${_p(" + _camel(m[1]) + ")}", o.path)
    doc = textwrap.wrap(f"`{o.method} {o.path}`" + (f": {_summary(o.op)}" if _summary(o.op) else ""), 105)
    url_doc = [f"The address of `{o.method} {o.path}`."]
    params: list[tuple[str, str, str]] = []  # (JSDoc type, name as documented, argument in the signature)
    for p, name in zip(o.path_params, names, strict=True):
        params.append((_type(p.get("schema"), typed, used), name, name))
    body: list[tuple[str, str, str]] = []
    if o.body_kind is not None:
        kind = _type(o.body_schema, typed, used)
        body.append((kind, "body" if o.body_required else "[body]", "body"))
    query_args: list[tuple[str, str, str]] = []
    if o.query_params:
        fields = ", ".join(
            f"{p['name']}{'' if p.get('required') else '?'}: {_type(p.get('schema'), typed, used)}"
            for p in o.query_params
        )
        needed = any(p.get("required") for p in o.query_params)
        query_args.append((f"{{{fields}}}", "params" if needed else "[params]", "params" if needed else "params = {}"))
    tail = "${query(params)}" if o.query_params else ""
    url_args = params + query_args
    url_fn = (
        _comment(url_doc + [f"@param {{{t}}} {n}" for t, n, _ in url_args] + ["@returns {string}"])
        + f"export function {o.name}Url({', '.join(a for _, _, a in url_args)}) {{\n"
        + f"  return {_template(address + tail)};\n}}\n"
    )
    answer = "null" if o.status == "204" else _type(o.answer_schema, typed, used)
    call_args = params + body + query_args
    url_call = f"{o.name}Url({', '.join([*names, *(['params'] if o.query_params else [])])})"
    if o.body_kind == "bytes":
        send = f"apiBytes({json.dumps(o.method)}, {url_call}, body)"
    else:
        send = f"api({json.dumps(o.method)}, {url_call}{', body' if o.body_kind else ''})"
    call_fn = (
        _comment(doc + [f"@param {{{t}}} {n}" for t, n, _ in call_args] + [f"@returns {{Promise<{answer}>}}"])
        + f"export function {o.name}({', '.join(a for _, _, a in call_args)}) {{\n"
        + f"  return {send};\n}}\n"
    )
    return url_fn + "\n" + call_fn


def _template(text: str) -> str:
    """A JavaScript string literal of ``text``: a template literal when it substitutes, else a plain one."""
    return f"`{text}`" if "${" in text else json.dumps(text)


def _summary(op: dict[str, Any]) -> str:
    """The first sentence of the route's docstring (FastAPI's ``description``), on one line."""
    text = " ".join(op.get("description", "").split("\n\n", 1)[0].split())
    return text


def _comment(lines: list[str]) -> str:
    body = "\n".join((" * " + line.replace("*/", "*\\/")).rstrip() for line in lines)
    return f"/**\n{body}\n */\n"
