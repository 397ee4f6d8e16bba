"""Every function of the dashboard's hand-written modules (``web/*.js``) is under 200 lines (issue #22: a view is
split into components). Node measures them with TypeScript's parser (the type check's, from node_modules)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
WEB = ROOT / "web"
TYPESCRIPT = ROOT / "node_modules" / "typescript"
GENERATED = ("wire.js", "api_client.js")  # written by the server's generators, one function per message or route
MAX_LINES = 200

# Prints [lines, file, first line, name] for every function-like node with a body (declarations, expressions,
# arrows, methods, constructors, accessors) of the files given as JSON on argv.
SCRIPT = """
const ts = require(process.argv[1]);
const fs = require("fs");
const out = [];
for (const file of JSON.parse(process.argv[2])) {
  const src = ts.createSourceFile(file, fs.readFileSync(file, "utf8"), ts.ScriptTarget.Latest, true);
  const visit = (n) => {
    if (ts.isFunctionLike(n) && n.body) {
      const a = src.getLineAndCharacterOfPosition(n.getStart(src)).line;
      const b = src.getLineAndCharacterOfPosition(n.end).line;
      out.push([b - a + 1, file.split("/").pop(), a + 1, n.name ? n.name.getText(src) : "(anonymous)"]);
    }
    ts.forEachChild(n, visit);
  };
  visit(src);
}
console.log(JSON.stringify(out));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
@pytest.mark.skipif(not TYPESCRIPT.is_dir(), reason="node_modules is not installed (npm ci)")
def test_no_web_function_reaches_200_lines() -> None:
    files = sorted(str(p) for p in WEB.glob("*.js") if p.name not in GENERATED)
    done = subprocess.run(
        ["node", "-e", SCRIPT, str(TYPESCRIPT), json.dumps(files)],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    assert len(found) > 500  # the parser saw the modules' functions
    assert any(name == "mountLive" for _, _, _, name in found)
    long = [f"{file}:{line} {name}: {n} lines" for n, file, line, name in found if n >= MAX_LINES]
    assert not long, "split these into components: " + "; ".join(long)
