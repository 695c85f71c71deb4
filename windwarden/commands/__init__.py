"""The subcommands of ``windwarden`` (the top layer: it may import every package below it)."""
