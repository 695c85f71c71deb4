"""The supervisory service: observers, fault detection and isolation, and dispatch.

Pure numpy/scipy: nothing here imports a transport. The Zenoh edge of the supervisor process is
``windwarden.live.supervisor_node``. See ``docs/architecture.md``.
"""
