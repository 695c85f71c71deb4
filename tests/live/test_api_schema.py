"""Property-based run of the OpenAPI schema (schemathesis): no request, valid or not, gets a 500, and every
response conforms to the schema. Requests go through the app's lifespan to a live run on loopback."""

from __future__ import annotations

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings

from api.main import create_app
from api.settings import ApiSettings
from tests.live.helpers import LiveNodes, scenario, wait_for
from windwarden.live.router import free_port, open_router

TOKEN = "schema-token"
ENDPOINT = f"tcp/127.0.0.1:{free_port()}"
APP = create_app(ApiSettings(connect=ENDPOINT, api_token=TOKEN, api_rate_per_s=1000.0, api_rate_burst=1000))
schema = schemathesis.openapi.from_dict(APP.openapi())
RUN = """
name = "schema-test"
duration_s = 3600.0
[plant]
kind = "hydro"
[wind]
mean = [[0.0, 7.5]]
"""


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("schema") / "run"
    with (
        open_router([ENDPOINT]),
        LiveNodes(ENDPOINT, scenario(RUN), run_dir, mode="realtime", speed=1.0),
        TestClient(APP) as c,
    ):
        assert wait_for(lambda: c.get("/health").json()["supervisor"], 30)
        yield c


@schema.parametrize()
@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
def test_no_500_and_responses_conform(case, client):
    response = client.request(**case.as_transport_kwargs(headers={"Authorization": f"Bearer {TOKEN}"}))
    assert response.status_code < 500 or response.status_code in (502, 503, 504), response.text
    case.validate_response(response, excluded_checks=[schemathesis.checks.positive_data_acceptance])
