"""Shipped scenario files (TOML). Load them with ``wwcore.scenario.load_scenario(name)``."""
