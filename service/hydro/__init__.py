"""Supervisor of the hydrostatic turbine (seed 003): TS model, sliding mode observer, detection, compensation.

Imports nothing from ``plant_sim`` and no transport; the observers register in ``service.hydro.builtin``.
"""
