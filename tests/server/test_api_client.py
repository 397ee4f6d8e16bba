"""``web/api_client.js`` is what ``server/api_client.py`` makes of the app's OpenAPI document: committed, current,
one function per operation, and calling each operation as the document says."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from gaitscope.server.api_client import COMMAND, operations, render
from gaitscope.server.app import create_app

WEB = Path(__file__).resolve().parents[2] / "web"
CLIENT_JS = WEB / "api_client.js"


def test_committed_api_client_js_is_what_the_routes_generate() -> None:
    committed = CLIENT_JS.read_text(encoding="utf-8") if CLIENT_JS.is_file() else ""
    if committed != render():
        pytest.fail(f"web/api_client.js differs from the app's routes: run `{COMMAND}` and commit the result")


def test_every_operation_has_a_function_and_an_address() -> None:
    doc = create_app().openapi()
    text = render(doc)
    exported = re.findall(r"^export function (\w+)\(", text, flags=re.M)
    ops = operations(doc)
    count = sum(
        len([m for m in item if m in ("get", "put", "post", "patch", "delete")]) for item in doc["paths"].values()
    )
    assert len(ops) == count > 50
    assert exported == [name for o in ops for name in (f"{o.name}Url", o.name)]
    assert "export function getTrial(trialId) {" in text
    assert "export function rerun(trialId, body, params = {}) {" in text
    assert "export function uploadChunk(uploadId, body, params) {" in text  # offset is required
    assert " * @returns {Promise<Array<Session>>}\n */\nexport function listSessions(params = {}) {" in text


def test_no_web_file_types_a_rest_address_by_hand() -> None:
    """Every REST call and address of the dashboard goes through the generated client."""
    for path in sorted(WEB.glob("*.js")):
        if path.name in ("api_client.js", "api.js", "wire.js"):
            continue
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"""["'`]/api/""", text), f"{path.name} names a REST address"
        assert not re.search(r"\bapi\(\s*\"", text), f"{path.name} calls api() by hand"


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_generated_functions_send_what_the_document_says() -> None:
    """Node imports the committed module with a recording ``fetch``: method, address, headers, body, answer."""
    script = (
        f"const c = await import({json.dumps(CLIENT_JS.as_uri())});"
        "const sent = [];"
        "globalThis.fetch = async (url, init) => {"
        "  sent.push({url, method: init.method, headers: init.headers,"
        "    body: init.body instanceof Blob ? 'blob:' + (await init.body.text()) : init.body ?? null});"
        "  const status = init.method === 'DELETE' ? 204 : 200;"
        "  return new Response(status === 204 ? null : JSON.stringify({ok: url}), {status});"
        "};"
        "const got = [];"
        "got.push(await c.getTrial(7));"
        "got.push(await c.rerun(3, {estimators: ['tbe']}, {max_points: 10, t0: null}));"
        "got.push(await c.uploadChunk('a b', new Blob(['xyz']), {offset: 5}));"
        "got.push(await c.deleteAnnotation(4, 9));"
        "got.push(await c.listTrials());"
        "got.push(c.downloadUrl(12));"
        "console.log(JSON.stringify({sent, got}));"
    )
    done = subprocess.run(
        ["node", "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    json_get = {"Accept": "application/json"}
    json_post = {"Accept": "application/json", "Content-Type": "application/json"}
    assert out["sent"] == [
        {"url": "/api/trials/7", "method": "GET", "headers": json_get, "body": None},
        {"url": "/api/trials/3/rerun?max_points=10", "method": "POST", "headers": json_post,
         "body": '{"estimators":["tbe"]}'},
        {"url": "/api/uploads/a%20b?offset=5", "method": "PUT",
         "headers": {"Accept": "application/json", "Content-Type": "application/octet-stream"}, "body": "blob:xyz"},
        {"url": "/api/trials/4/annotations/9", "method": "DELETE", "headers": json_get, "body": None},
        {"url": "/api/trials", "method": "GET", "headers": json_get, "body": None},
    ]  # fmt: skip
    assert out["got"] == [
        {"ok": "/api/trials/7"},
        {"ok": "/api/trials/3/rerun?max_points=10"},
        {"ok": "/api/uploads/a%20b?offset=5"},
        None,
        {"ok": "/api/trials"},
        "/api/trials/12/download",
    ]
