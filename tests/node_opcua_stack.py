"""node-opcua, a JavaScript OPC UA stack that shares no code with asyncua, installed for the tests
from tests/node_opcua's pinned package-lock.json (`npm ci`) into `.cache/node_opcua/<lock's hash>`,
once: later sessions find it there. Its scripts write JSON to a file; the tests assert on it.

Node.js and npm are Debian packages (`apt-get install nodejs npm`, .ci/run). Without them the
tests skip, saying why, except under CI=true, where they fail.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent / "node_opcua"
ROOT = HERE.parents[1]
INSTALL_TIMEOUT = 600.0  # s: npm ci downloads about 30 MB (9 s here); a slow mirror gets minutes
SCRIPT_TIMEOUT = 90.0  # s: any one node script, on a busy machine; each also stops itself sooner


def unavailable(reason: str):
    if os.environ.get("CI") == "true":
        pytest.fail(f"{reason}; CI=true requires the node-opcua tests to run")
    pytest.skip(reason)


def install() -> tuple[Path, float]:
    """The node_modules folder of the pinned node-opcua, installed if not yet; the seconds the
    install took (0 when found installed)."""
    for tool in ("node", "npm"):
        if shutil.which(tool) is None:
            unavailable(f"no {tool} on PATH (apt-get install --no-install-recommends nodejs npm)")
    lock = (HERE / "package-lock.json").read_bytes()
    target = ROOT / ".cache" / "node_opcua" / hashlib.sha256(lock).hexdigest()[:16]
    if (target / "installed").is_file():
        return target / "node_modules", 0.0
    building = target.with_name(f"{target.name}.{os.getpid()}")
    shutil.rmtree(building, ignore_errors=True)
    building.mkdir(parents=True)
    for name in ("package.json", "package-lock.json"):
        shutil.copy(HERE / name, building / name)
    started = time.monotonic()
    done = subprocess.run(["npm", "ci", "--no-audit", "--no-fund", "--cache", str(building.parent / "npm-cache")],
                          cwd=building, capture_output=True, text=True, timeout=INSTALL_TIMEOUT, check=False)
    if done.returncode != 0:
        shutil.rmtree(building, ignore_errors=True)
        pytest.fail(f"npm ci of node-opcua failed ({done.returncode}): {done.stderr[-2000:]}")
    (building / "installed").write_text(f"{time.monotonic() - started:.1f} s\n")
    try:
        building.rename(target)  # another session may have finished first: then its copy serves
    except OSError:
        shutil.rmtree(building, ignore_errors=True)
    return target / "node_modules", time.monotonic() - started


def run_script(modules: Path, script: str, *arguments: str, out: Path, environment: dict | None = None,
               timeout: float = SCRIPT_TIMEOUT) -> dict:
    """Run tests/node_opcua/`script` with node on `arguments` (and `environment` added); the JSON
    it wrote to `out`."""
    done = subprocess.run(["node", str(HERE / script), *arguments, str(out)], cwd=HERE,
                          env={**os.environ, **(environment or {}), "NODE_PATH": str(modules)}, capture_output=True,
                          text=True, timeout=timeout, check=False)
    assert done.returncode == 0, f"node {script}: {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return json.loads(out.read_text())
