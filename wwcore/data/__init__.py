"""Reference data the project ships (layout files)."""
