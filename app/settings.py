"""`Settings`: the server's one settings object, read from `ROBOTSLANG_*` environment variables."""

from __future__ import annotations

import ipaddress
import secrets
from pathlib import Path

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from sim.trial.table import Caps


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="ROBOTSLANG_", extra="ignore")

    data_dir: Path = Path("./var")
    database_url: str | None = None  # overrides the SQLite file in data_dir
    benchmark: Path | None = None  # adds the benchmark's mazes to the bundled ones
    seq2seq_checkpoint: Path | None = None  # agent:seq2seq's checkpoint (`train ndh`'s best.pt); None: the shipped one
    ldh_checkpoint: Path | None = None  # the LDH localizer on the watch page (`train ldh`'s best.pt); else `colours`
    cache_dir: Path = Field(default_factory=lambda: Path.home() / ".cache" / "robotslang")
    secret_key: str | None = None  # generated once and kept in data_dir when not set
    move_penalty_s: float = 1.0  # leaderboard: seconds added per executed move
    grace_period_s: float = 120.0  # a disconnected seat may rejoin within this, else the trial aborts
    min_move_interval_s: float = 0.25  # moves closer together than this are refused
    max_message_bytes: int = 4096  # a websocket message larger than this is refused
    # Messages of one seat taken per second beyond a burst (every one but pings, moves executed or
    # refused): a fast typist never reaches it; a flood is dropped (not logged, not
    # relayed), with a `rate_limited` reply.
    seat_message_rate_per_s: float = Field(default=5.0, gt=0)
    seat_message_burst: int = Field(default=20, ge=1)
    # How often the interpreter offers the GIL to another thread (Python's default: 5 ms). The
    # render, JPEG and particle-filter threads would otherwise hold it from the event loop for
    # whole slices: at 200 trials, move-to-frame p99 42-63 ms at 1 ms against 56-83 ms at 5 ms (bench.load).
    gil_switch_interval_s: float = 0.001
    # Processes that draw the simulator's frames (app.backends.render); 0: a thread of the server.
    render_processes: int = Field(default=1, ge=0)
    # Processes that prepare mazes for trials (app.preparation); 0: one per core.
    maze_builders: int = Field(default=0, ge=0)
    # Caps on agents (shown on the experimenter's page; `sim.trial.table.Caps`): on any the agent
    # says so and the trial aborts. Messages: an agent's own, either seat (two may talk in circles).
    agent_moves_per_target: int = Field(default=Caps.moves_per_target, ge=1)
    agent_minutes_per_trial: float = Field(default=15.0, gt=0)  # of the trial clock
    agent_messages_per_target: int = Field(default=Caps.messages_per_target, ge=1)
    # Two agents together move as fast as the simulator answers where False (self-play recording):
    # no person waits on their pace, and no move of theirs is refused as too soon.
    agent_pairs_paced: bool = True
    # The agent Driver says a long plan back in short before carrying it out, to a person Commander.
    agent_read_back: bool = True
    redis_url: str | None = None  # fan-out between processes; in-process when unset
    # Origins (scheme://host[:port]) trusted beside the server's own, for state-changing requests and sockets.
    allowed_origins: list[str] = Field(default_factory=list)
    # Host header names served (DNS rebinding); IP literals always pass, and so do allowed_origins' hosts.
    allowed_hosts: list[str] = Field(default_factory=lambda: ["127.0.0.1", "localhost", "[::1]"])
    join_link_ttl_s: float | None = (
        None  # a join link opens its seat this long after it is shown; None: until the trial ends
    )
    # Wrong passwords for one account from one client address (`limits` notation): the guessing
    # client is locked out, never the account, so an attacker cannot lock a lab out.
    login_limit_per_account: str = "5/minute"
    login_limit_per_address: str = "20/minute"  # login attempts per client address (an IPv6 /64)
    # A study's sign-ups (`limits` notation, `;` between several): consents and lobby joins from
    # one client address (an IPv6 /64), and into one study from everyone (app.study.signups).
    study_consent_limit_per_address: str = "20/minute;100/hour"
    study_consent_limit_per_study: str = "120/minute"
    study_lobby_limit_per_address: str = "60/minute"
    study_lobby_limit_per_study: str = "600/minute"
    # Proxies (addresses or networks) whose X-Forwarded-For and X-Forwarded-Proto are believed; the
    # client is the right-most address they did not add. Empty: the socket's peer is the client.
    trusted_proxies: list[str] = Field(default_factory=list)
    password_check_concurrency: int | None = None  # password hashes computed at once; None: the CPU cores
    overhead_calibration: Path | None = (
        None  # the overhead camera's calibration; default data_dir/overhead_calibration.json
    )
    camera_calibration: Path | None = (
        None  # the rovers' front camera (sim.robot.camera.CameraCalibration); default data_dir/camera_calibration.json
    )

    @field_validator("trusted_proxies")
    @classmethod
    def _proxies_are_addresses(cls, proxies: list[str]) -> list[str]:
        for proxy in proxies:
            try:
                ipaddress.ip_network(proxy)
            except ValueError:
                raise ValueError(
                    f'trusted proxy {proxy!r} is not an address or network (a "*" would let any client name its address)'
                ) from None
        return proxies

    @model_validator(mode="after")
    def _default_paths(self) -> Settings:
        if self.overhead_calibration is None:
            self.overhead_calibration = self.data_dir / "overhead_calibration.json"
        if self.camera_calibration is None:
            self.camera_calibration = self.data_dir / "camera_calibration.json"
        return self

    @property
    def sqlite_path(self) -> Path:
        return self.data_dir / "robotslang.db"

    @property
    def frames_dir(self) -> Path:
        return self.data_dir / "frames"

    @property
    def url(self) -> str:
        return self.database_url or f"sqlite:///{self.sqlite_path.resolve()}"

    def signing_key(self) -> str:
        """`secret_key`, else the key generated at first start and kept in `data_dir/secret_key`."""
        if self.secret_key:
            return self.secret_key
        path = self.data_dir / "secret_key"
        if not path.exists():
            self.data_dir.mkdir(parents=True, exist_ok=True)
            path.write_text(secrets.token_urlsafe(48))
            path.chmod(0o600)
        return path.read_text().strip()
