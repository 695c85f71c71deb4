"""The API's settings: ``WINDWARDEN_*`` environment variables (pydantic-settings), see ``ApiSettings``."""

from windwarden.live.config import ApiSettings

__all__ = ["ApiSettings"]
