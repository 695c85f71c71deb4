"""The REST API (FastAPI): health, run status, faults (list, inject, clear), supervisor status, events, metrics,
and the OpenAPI pages (served from local assets).

Thin: every request passes ``api.guard`` (rate limit, token, body size and time, concurrency) and is written to
the access log (``api.accesslog``); a route validates, then asks the plant and the supervisor over Zenoh
(``api.bridge``); it never touches a plant or a supervisor object. ``api.main.create_app`` builds the app;
``windwarden api`` serves it.
"""
