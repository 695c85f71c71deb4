"""Process settings from the environment (prefix ``WINDWARDEN_``) and flags, one class per service.

Flags win over the environment, the environment over the defaults: ``PlantSettings(**flags)`` with the unset flags
left out. Endpoints are comma-separated Zenoh locators, e.g. ``WINDWARDEN_CONNECT=tcp/127.0.0.1:7447``.
"""

from __future__ import annotations

import secrets
import time
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from windwarden.live.access import read_password
from wwcore.keys import KeyTree

TimingMode = Literal["realtime", "lockstep"]


class ZenohSettings(BaseSettings):
    """How a process joins the Zenoh network."""

    model_config = SettingsConfigDict(env_prefix="WINDWARDEN_", extra="ignore")

    connect: str = Field(default="", description="comma-separated endpoints to connect to, e.g. tcp/127.0.0.1:7447")
    listen: str = Field(default="", description="comma-separated endpoints to listen on")
    zenoh_mode: Literal["client", "peer", "router"] = Field(default="client", description="Zenoh session mode")
    farm: str = Field(default="default", description="farm id: the second chunk of every key expression")
    lease_ms: int = Field(default=800, ge=100, le=60_000, description="ms without traffic before a peer is gone")
    multicast: bool = Field(default=False, description="multicast scouting (off: explicit endpoints only)")
    connect_timeout_s: float = Field(default=10.0, ge=-1.0, description="s to keep trying the endpoints; -1: for ever")
    zenoh_user: str | None = Field(default=None, description="user name for the router (the role: plant, api, …)")
    zenoh_password: SecretStr | None = Field(default=None, description="its password (prefer zenoh_password_file)")
    zenoh_password_file: Path | None = Field(default=None, description="a secret file holding the password")
    zenoh_tls_ca: Path | None = Field(default=None, description="CA certificate (PEM) of the router's tls/ endpoint")
    zenoh_tls_cert: Path | None = Field(default=None, description="client certificate (PEM), common name = role")
    zenoh_tls_key: Path | None = Field(default=None, description="the client certificate's private key (PEM)")

    @field_validator("farm")
    @classmethod
    def _farm_is_a_chunk(cls, farm: str) -> str:
        KeyTree(farm)
        return farm

    def credentials(self) -> tuple[str, str] | None:
        """(user, password) for the router's authentication, or None; the password file is read here, so a
        rotated secret is picked up by the next session."""
        if not self.zenoh_user:
            return None
        if self.zenoh_password is not None:
            return self.zenoh_user, self.zenoh_password.get_secret_value()
        if self.zenoh_password_file is not None:
            return self.zenoh_user, read_password(self.zenoh_password_file)
        raise ValueError(f"zenoh user {self.zenoh_user!r} has no password (set WINDWARDEN_ZENOH_PASSWORD_FILE)")

    @property
    def connect_endpoints(self) -> list[str]:
        return [e.strip() for e in self.connect.split(",") if e.strip()]

    @property
    def listen_endpoints(self) -> list[str]:
        return [e.strip() for e in self.listen.split(",") if e.strip()]

    @property
    def keys(self) -> KeyTree:
        return KeyTree(self.farm)


class RunPlacement(BaseSettings):
    """Where the run folder is: ``run_dir`` if given, else ``runs_root/run_id``."""

    model_config = SettingsConfigDict(env_prefix="WINDWARDEN_", extra="ignore")

    runs_root: Path = Field(default=Path("runs"), description="folder holding one folder per run")
    run_id: str | None = Field(default=None, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$", description="run id")
    run_dir: Path | None = Field(default=None, description="the run folder itself (overrides runs_root/run_id)")
    rerun_url: str | None = Field(default=None, description="Rerun gRPC proxy to log to, rerun+http://host:port/proxy")

    def folder(self, run_id: str) -> Path:
        return self.run_dir if self.run_dir is not None else self.runs_root / run_id


class RealTimeSettings(BaseSettings):
    """Scheduling of the two real-time processes (plant, supervisor)."""

    model_config = SettingsConfigDict(env_prefix="WINDWARDEN_", extra="ignore")

    nice: int | None = Field(
        default=None, ge=-20, le=19, description="niceness to run at (negative needs CAP_SYS_NICE); None leaves it"
    )


class PlantSettings(ZenohSettings, RunPlacement, RealTimeSettings):
    """``windwarden plant``."""

    scenario: str = Field(default="demo", description="shipped scenario name or path to a scenario file")
    seed: int = Field(default=0, description="master seed (run 0 of ``windwarden eval --seed``)")
    mode: TimingMode = Field(default="realtime", description="realtime (paced) or lockstep (waits for refs)")
    speed: float = Field(default=1.0, gt=0.0, le=1000.0, description="realtime speed-up ×k")
    duration_s: float | None = Field(default=None, gt=0.0, description="s, stop earlier than the scenario")
    supervisor_wait_s: float = Field(default=60.0, ge=0.0, description="s to wait for a supervisor before tick 0")
    lockstep_timeout_s: float = Field(default=2.0, gt=0.0, description="s to wait for refs before falling back")
    max_ref_age: int = Field(default=10, ge=1, description="ticks after which refs count as stale")
    stale_event_ticks: int = Field(default=50, ge=1, description="stale ticks in a row before it is logged as an event")
    display_every: int = Field(default=10, ge=1, description="ticks between truth samples and Rerun rows (10 Hz)")
    status_every_s: float = Field(default=0.5, gt=0.0, description="s of wall time between status messages")


class SupervisorSettings(ZenohSettings, RunPlacement, RealTimeSettings):
    """``windwarden supervise``."""

    plant_wait_s: float = Field(default=0.0, ge=0.0, description="s to wait for a plant; 0 waits for ever")
    stale_after_s: float = Field(default=0.5, gt=0.0, description="s without sensors before the stream is stale")
    max_gap_ticks: int = Field(default=50, ge=1, description="a larger gap in ticks restarts the observers")
    max_backlog_ticks: int = Field(default=300, ge=1, description="frames queued behind: drop them, restart observers")
    display_every: int = Field(default=10, ge=1, description="ticks between Rerun rows")
    status_every_s: float = Field(default=0.5, gt=0.0, description="s of wall time between status messages")
    exit_with_run: bool = Field(default=False, description="exit when the plant announces the end of its run")


class ApiSettings(ZenohSettings, RunPlacement):
    """``windwarden api``."""

    api_token: SecretStr | None = Field(default=None, description="bearer token for the mutating routes")
    host: str = Field(default="127.0.0.1", description="address to bind")
    port: int = Field(default=8000, ge=0, le=65535, description="port to bind")
    query_timeout_s: float = Field(default=2.0, gt=0.0, description="s to wait for the plant or supervisor")
    events_kept: int = Field(default=100_000, ge=100, description="events kept in memory for /events")


def new_run_id(scenario: str) -> str:
    """``YYYYmmdd-HHMMSS-<scenario>-<4 hex>``: sortable, unique enough, a valid Rerun recording id."""
    return f"{time.strftime('%Y%m%d-%H%M%S')}-{scenario}-{secrets.token_hex(2)}"


def settings_from_flags(cls: type[BaseSettings], flags: dict[str, Any]) -> Any:
    """Settings with the given flags over the environment; flags that were not given (None) are left out."""
    return cls(**{k: v for k, v in flags.items() if v is not None})
