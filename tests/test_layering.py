"""The numerical core imports no transport: every module of wwcore, plant_sim and service, imported in a fresh
interpreter, leaves zenoh, rerun and fastapi unloaded (docs/architecture.md, the layering rule)."""

from __future__ import annotations

import json
import subprocess
import sys

CORE = ("wwcore", "plant_sim", "service")
EDGES = ("zenoh", "rerun", "fastapi", "uvicorn", "starlette")

PROBE = """
import importlib, json, pkgutil, sys
names = []
for package in {core!r}:
    root = importlib.import_module(package)
    names.append(package)
    for info in pkgutil.walk_packages(root.__path__, package + "."):
        importlib.import_module(info.name)
        names.append(info.name)
loaded = sorted(m for m in sys.modules if m.split(".")[0] in {edges!r})
print(json.dumps({{"modules": names, "edges": loaded}}))
"""


def test_core_imports_no_transport():
    code = PROBE.format(core=CORE, edges=EDGES)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert "wwcore.wire" in result["modules"] and "plant_sim.turbine.plant" in result["modules"]
    assert len(result["modules"]) > 30
    assert result["edges"] == [], f"the core loaded {result['edges']}"
