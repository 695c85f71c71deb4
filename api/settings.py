"""The API's settings: ``WINDWARDEN_*`` environment variables (pydantic-settings).

``ApiSettings`` is the process's own (token, bind address, Zenoh, run folder: ``windwarden.live.config``) plus the
limits it puts on HTTP clients (``ApiLimits``, every name prefixed ``WINDWARDEN_API_``).
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from windwarden.live.config import ApiSettings as ApiProcessSettings

ACCESS_LOG = "api-access.jsonl"  # in the run folder
MAX_INJECTIONS = 300  # a run's fault list (every fault ever injected) must fit in one Zenoh reply: see the tests


class ApiLimits(BaseSettings):
    """What one HTTP client, or all of them together, may ask of the API."""

    model_config = SettingsConfigDict(env_prefix="WINDWARDEN_", extra="ignore")

    api_max_body_bytes: int = Field(
        default=16_384, ge=1024, le=1_048_576, description="bytes; a larger request body is refused (413) unread"
    )
    api_body_timeout_s: float = Field(
        default=10.0, gt=0.0, le=600.0, description="s; a body that has not all come by then is refused (408)"
    )
    api_rate_per_s: float = Field(
        default=2.0, gt=0.0, le=10_000.0, description="mutating requests per second per client (token refill rate)"
    )
    api_rate_burst: int = Field(
        default=10, ge=1, le=100_000, description="mutating requests a client may make at once (bucket size)"
    )
    api_rate_clients: int = Field(
        default=4096, ge=16, le=1_000_000, description="clients whose buckets are remembered (least recent forgotten)"
    )
    api_max_concurrent: int = Field(
        default=64, ge=1, le=10_000, description="requests in progress at once; beyond: 503 with Retry-After"
    )
    api_max_faults_per_turbine: int = Field(
        default=8, ge=1, le=64, description="active and pending faults one turbine may have; an injection beyond: 409"
    )
    api_max_faults: int = Field(
        default=32, ge=1, le=256, description="active and pending faults over all turbines; an injection beyond: 409"
    )
    api_max_injections: int = Field(
        default=MAX_INJECTIONS,
        ge=1,
        le=MAX_INJECTIONS,
        description="faults the API may inject in one run, cleared or not; an injection beyond: 409",
    )
    api_access_log: Path | None = Field(
        default=None, description=f"JSON-lines access log; default <run folder>/{ACCESS_LOG}, none without one"
    )
    api_access_log_max_bytes: int = Field(
        default=64 * 2**20, ge=4096, description="bytes; a full access log is renamed to <name>.1 (replacing it)"
    )


class ApiSettings(ApiProcessSettings, ApiLimits):
    """``windwarden api``: everything from the environment, flags over it."""

    def access_log_path(self) -> Path | None:
        if self.api_access_log is not None:
            return self.api_access_log
        return self.run_dir / ACCESS_LOG if self.run_dir is not None else None


__all__ = ["ACCESS_LOG", "MAX_INJECTIONS", "ApiLimits", "ApiProcessSettings", "ApiSettings"]
