"""windwarden core: what every other package shares.

Physical parameters, the project's own aerodynamic model, channel names, the scenario schema and the wire
contract. Pure numpy/pydantic: this package imports nothing from the rest of windwarden and no transport
(Zenoh, Rerun, FastAPI). See ``docs/architecture.md`` for the layering rule.
"""
