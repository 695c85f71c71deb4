"""Error responses that always serialise, and always as 4xx.

FastAPI's default handlers echo the offending input. Python's JSON parser accepts NaN, infinities and lone UTF-16
surrogates (``"\\udcff"``); echoed back, the first cannot be written as JSON and the second not as UTF-8, and the
error response itself would fail with a 500. Responses here are rendered ASCII-escaped with non-finite numbers
as strings. A body that is not even text (FastAPI's 400 "error parsing the body") is a malformed body: 422. The
offending input itself is never echoed back (a 10 kB name would come back as 10 kB): each item names the field
(``loc``), says what is wrong (``msg``, ``type``) and, where pydantic gives them, the limits (``ctx``).
"""

from __future__ import annotations

import json
import math
from typing import Any

from fastapi import Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException

PARSE_ERROR = "There was an error parsing the body"


def _safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {str(k): _safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_safe(v) for v in value]
    return value


class SafeJSONResponse(JSONResponse):
    """JSON that any input can be rendered into: ASCII-escaped, non-finite floats as strings."""

    def render(self, content: Any) -> bytes:
        return json.dumps(_safe(content), ensure_ascii=True, allow_nan=False, separators=(",", ":")).encode()


async def validation_error(request: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, RequestValidationError)
    items = [{k: v for k, v in item.items() if k != "input"} for item in error.errors()]
    return SafeJSONResponse(status_code=422, content={"detail": jsonable_encoder(items)})


async def http_error(request: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, HTTPException)
    if error.status_code == 400 and error.detail == PARSE_ERROR:
        detail = [{"loc": ["body"], "msg": "the body is not valid JSON text (UTF-8)", "type": "json_invalid"}]
        return SafeJSONResponse(status_code=422, content={"detail": detail})
    return SafeJSONResponse(
        status_code=error.status_code, content={"detail": error.detail}, headers=getattr(error, "headers", None)
    )
