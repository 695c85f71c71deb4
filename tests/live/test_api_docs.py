"""The OpenAPI pages work offline: headless Chromium (Debian's ``chromium``) opens ``/docs`` and ``/redoc`` with every
host but loopback unresolvable, and each operation of the schema must be rendered in the page.

A control page, FastAPI's stock Swagger UI (its assets on a CDN), must render nothing under the same browser
flags: the check would catch a page that needs the internet. `.ci/run` installs chromium; without it the browser
tests skip, except under CI, where they fail.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.testclient import TestClient

from api.main import create_app
from api.settings import ApiSettings
from tests.live.api_server import serve
from tests.live.helpers import router

CHROMIUM = Path("/usr/bin/chromium")
BROWSER_TIMEOUT_S = 180


def need_chromium() -> None:
    if CHROMIUM.exists():
        return
    reason = f"{CHROMIUM} is missing: `apt-get install chromium` (.ci/run does it) to open /docs in a browser"
    if os.environ.get("CI"):
        pytest.fail(reason)
    pytest.skip(reason)


def rendered_dom(url: str, profile: Path) -> str:
    """The page's DOM after its scripts ran (virtual time), with no host but 127.0.0.1 resolvable."""
    command = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-extensions",
        "--no-first-run",
        "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",
        f"--user-data-dir={profile}",
        "--virtual-time-budget=20000",
        "--dump-dom",
        url,
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.fixture(scope="module")
def app():
    with router() as endpoint:
        yield create_app(ApiSettings(connect=endpoint, api_token="docs-token"))


@pytest.fixture(scope="module")
def base_url(app):
    with serve(app) as url:
        yield url


def operations(app: FastAPI) -> list[tuple[str, str, str, str]]:
    """(method, path, tag, operationId) of every documented operation."""
    return [
        (method, path, op["tags"][0], op["operationId"])
        for path, ops in app.openapi()["paths"].items()
        for method, op in ops.items()
    ]


def test_the_pages_load_nothing_from_elsewhere(app):
    with TestClient(app) as client:
        for page in ("/docs", "/redoc"):
            response = client.get(page)
            assert response.status_code == 200
            urls = re.findall(r"""(?:src|href|spec-url)\s*=\s*["']([^"']+)["']""", response.text)
            urls += re.findall(r"""url:\s*'([^']+)'""", response.text)
            assert urls and all(u.startswith("/") and not u.startswith("//") for u in urls), urls
            for asset in (u for u in urls if u.startswith("/docs/assets/")):
                assert client.get(asset).status_code == 200, asset
        assert "validatorUrl" in client.get("/docs").text  # Swagger UI's online validator is off


def test_swagger_ui_renders_every_route_offline(app, base_url, tmp_path):
    need_chromium()
    dom = rendered_dom(f"{base_url}/docs", tmp_path)
    missing = [
        (method, path)
        for method, path, tag, operation_id in operations(app)
        if f'data-path="{path}"' not in dom or f'id="operations-{tag}-{operation_id}"' not in dom
    ]
    assert not missing, f"not rendered in /docs: {missing}"


def test_redoc_renders_every_route_offline(app, base_url, tmp_path):
    need_chromium()
    dom = rendered_dom(f"{base_url}/redoc", tmp_path)
    missing = [
        (method, path)
        for method, path, _, _ in operations(app)
        if not re.search(rf'http-verb {method}">{method}</span><span[^>]*>{re.escape(path)}</span>', dom)
    ]
    assert not missing, f"not rendered in /redoc: {missing}"


def test_control_a_page_that_needs_a_cdn_renders_nothing(tmp_path):
    """FastAPI's stock page, same browser flags: no route may show (else the offline check proves nothing)."""
    need_chromium()
    stock = FastAPI(docs_url=None)

    @stock.get("/ping")
    def ping() -> dict:
        return {}

    @stock.get("/stock-docs", include_in_schema=False)
    def stock_docs() -> HTMLResponse:
        return get_swagger_ui_html(openapi_url="/openapi.json", title="stock")

    with serve(stock) as url:
        dom = rendered_dom(f"{url}/stock-docs", tmp_path)
    assert 'id="swagger-ui"' in dom and 'data-path="/ping"' not in dom
