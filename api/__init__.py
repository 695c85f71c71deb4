"""The REST API (FastAPI): health, run status, faults (list, inject, clear), supervisor status, events, metrics.

Thin: it validates, then asks the plant and the supervisor over Zenoh (``api.bridge``); it never touches a plant
or a supervisor object. ``api.main.create_app`` builds the app; ``windwarden api`` serves it.
"""
