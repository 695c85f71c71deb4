"""Which route a raw path belongs to: metric labels and log lines name the template, never the raw path."""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from starlette.types import Scope

PARAMETER = re.compile(r"\\\{([^/:]+?)(:path)?\\\}")


def _pattern(template: str) -> re.Pattern[str]:
    def parameter(match: re.Match[str]) -> str:
        return ".+" if match.group(2) else "[^/]+"

    return re.compile("^" + PARAMETER.sub(parameter, re.escape(template)) + "$")


class RouteTemplates:
    """The app's path templates (``/faults/{label:path}``) and their patterns, in the order routing tries them."""

    def __init__(self, templates: Iterable[str]):
        self._patterns = [(_pattern(t), t.replace(":path}", "}")) for t in dict.fromkeys(templates)]

    def of(self, scope: Scope) -> str:
        """The template (as in the OpenAPI schema) of the route the request was routed to, or would be; else
        ``unmatched``. A request the guard refused never reached the router: its path is matched here."""
        route = scope.get("route")
        if getattr(route, "path_format", None):
            return route.path_format
        path = scope["path"]
        return next((shown for pattern, shown in self._patterns if pattern.match(path)), "unmatched")


def allowed_methods(app: Any, template: str) -> list[str]:
    """Every method the OpenAPI schema documents for a template (for a 405's ``Allow``)."""
    return sorted({m.upper() for m in app.openapi()["paths"].get(template, {})})
