"""The supervisory service: observers, fault detection and isolation, and dispatch.

The numerical core of this package is pure numpy/scipy and imports no transport; only ``service.node`` (the
Zenoh edge) does. See ``docs/architecture.md``.
"""
