"""IOC instance configuration: one YAML file, command-line flags on top.

Errors come back as one `UserError` line naming the file and the key
(`ioc/bl01.yaml:route.password_file: ...`). A route password never appears in
the file: the file names an environment variable or a secret file, and the
password is read only when the route is added, as a `SecretStr`.

Relative paths in a file are relative to that file, always; the default
terminal types are the ones shipped with the package (`shipped`). The file
is read bounded (a path naming /dev/zero fails, it does not eat memory) and
parsed by the same YAML reader as terminal files (nesting limit, duplicate
keys, line numbers). `ioc schema` prints `config_schema()`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Final

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SecretStr,
    ValidationError,
    field_validator,
    model_validator,
)

from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.bounded import (
    MAX_CONFIG_BYTES,
    no_bool_for_number,
    read_text_bounded,
)
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.naming import check_alias, check_prefix
from fastcs_ethercat.ioc.pvlists import ArchiverPolicy
from fastcs_ethercat.shipped import BUILTIN_TERMINALS_DIR
from fastcs_ethercat.terminals.yaml_io import parse_yaml

DEFAULT_ADS_TCP_PORT: Final = 48898
DEFAULT_POLL_RATE_HZ: Final = 10.0
MAX_POLL_RATE_HZ: Final = 1000.0
MAX_PASSWORD_FILE_BYTES: Final = 64 * 1024


class _Strict(BaseModel):
    """Unknown keys are errors. Fields are described with `Field(description=)`:
    pydantic finds attribute docstrings by walking the frames of the import
    and every module loaded (~30 ms at the IOC's start, for `ioc schema`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    _no_bool_for_number = field_validator("*", mode="before")(no_bool_for_number)


class RouteConfig(_Strict):
    """Add a route for this host on the target before connecting (UDP 48899)."""

    user: str = "Administrator"
    password_env: str | None = Field(
        default=None,
        description="Name of the environment variable that holds the password.",
    )
    password_file: Path | None = Field(
        default=None,
        description="File whose first line is the password (relative: to the "
        "config file).",
    )
    route_name: str | None = Field(
        default=None,
        description="Name of the route on the target; default: this host's name.",
    )
    host_address: str | None = Field(
        default=None,
        description="Address the target uses to reach this host; default: its "
        "own guess.",
    )

    @model_validator(mode="after")
    def _one_password_source(self) -> RouteConfig:
        if (self.password_env is None) == (self.password_file is None):
            raise ValueError("give exactly one of password_env and password_file")
        return self

    def password(self) -> SecretStr:
        """Read the password now; never store or log the result."""
        if self.password_env is not None:
            value = os.environ.get(self.password_env)
            if value is None:
                raise UserError(
                    f"environment variable {self.password_env} is not set",
                    where="route.password_env",
                )
            return SecretStr(value)
        assert self.password_file is not None
        text = read_text_bounded(
            self.password_file,
            MAX_PASSWORD_FILE_BYTES,
            what="password file",
            where="route.password_file",
        )
        lines = text.splitlines()
        return SecretStr(lines[0] if lines else "")


class ArchiverConfig(_Strict):
    """What the archiver list (`pv_lists_dir`, `--list-pvs --format archiver`)
    holds beyond the values, states and texts every site archives."""

    raw: bool = Field(
        default=False, description="Also the raw counts beside each scaled value."
    )
    readbacks: bool = Field(
        default=False,
        description="Also each output's _RBV readback (its setpoint always).",
    )
    include: list[str] = Field(
        default_factory=lambda: ["*"],
        description="Globs over the PV names below the prefix "
        "(`ETH1:RIO1:MOD5:*`): only these are archived...",
    )
    exclude: list[str] = Field(
        default_factory=list, description="...except these (globs, as include)."
    )

    def policy(self) -> ArchiverPolicy:
        return ArchiverPolicy(
            self.raw, self.readbacks, tuple(self.include), tuple(self.exclude)
        )


class TransportsConfig(_Strict):
    """Which EPICS protocols to serve; both by default."""

    ca: bool = True
    pva: bool = True

    @model_validator(mode="after")
    def _at_least_one(self) -> TransportsConfig:
        if not (self.ca or self.pva):
            raise ValueError("enable at least one of ca and pva")
        return self


@dataclass(frozen=True)
class SiteDatabase:
    """A site's `.db` file and its macro substitutions."""

    file: Path
    macros: Mapping[str, str] = field(default_factory=dict)

    def substitutions(self) -> str:
        """`A=1,B=2`, as EPICS's dbLoadRecords takes them."""
        return ",".join(f"{name}={value}" for name, value in self.macros.items())


class DatabaseConfig(_Strict):
    """A site's EPICS database file, loaded after the IOC's own records."""

    file: Path = Field(description="The .db file (relative to this file).")
    macros: dict[str, str] = Field(
        default_factory=dict,
        description="Macro substitutions; P is the IOC's prefix unless set here.",
    )


class TerminalConfig(_Strict):
    """Per-terminal settings, keyed by the terminal's TwinCAT name or path."""

    poll_rate_hz: float | None = Field(default=None, gt=0, le=MAX_POLL_RATE_HZ)


class IocConfig(_Strict):
    """Everything one IOC instance needs to know."""

    prefix: str = Field(
        description="PV prefix (at most 22 characters): every PV is "
        "<prefix>:<master>:<coupler>:<terminal>[:<channel>]:<name>."
    )
    target: str = Field(
        description="TwinCAT host (or the simulator), `host` or `host:port` (ADS TCP)."
    )
    ams_net_id: str | None = Field(
        default=None,
        description="AMS NetId of the target; discovered over UDP 48899 when "
        "not given.",
    )
    local_net_id: str | None = Field(
        default=None,
        description="AMS NetId of this host; pyads derives one from the local "
        "IP when unset.",
    )
    route: RouteConfig | None = Field(
        default=None,
        description="Add a route for this host on the target before connecting.",
    )
    poll_rate_hz: float = Field(
        default=DEFAULT_POLL_RATE_HZ,
        gt=0,
        le=MAX_POLL_RATE_HZ,
        description="Sum-read rate of every master (Hz).",
    )
    ads_timeout_ms: int = Field(
        default=1000,
        ge=50,
        le=60_000,
        description="Timeout of every ADS request of the IOC (a slow or distant "
        "PLC may need more; a request that times out fails its poll cycle or "
        "write).",
    )
    terminals: dict[str, TerminalConfig] = Field(
        default_factory=dict,
        description="Per-terminal settings by TwinCAT name or path (names "
        "joined with ^).",
    )
    terminal_dirs: tuple[Path, ...] = Field(
        default_factory=lambda: (BUILTIN_TERMINALS_DIR,),
        description="Directories, files or globs of terminal YAML, searched in "
        "this order; relative to this file. Default: the `chain:` file's own "
        "`terminal_dirs` when it names some (as `init` writes it), else the "
        "terminal types shipped with fastcs-ethercat (a list given here "
        "replaces them).",
    )
    deadbands: dict[str, Annotated[float, Field(ge=0)]] = Field(
        default_factory=dict,
        description="Absolute deadbands, like a record's MDEL: TwinCAT symbol "
        "name pattern (glob, e.g. `*(EL3104).AI Standard Channel *.Value`) -> "
        "the change, in the symbol's units, a number must exceed to be posted "
        "again; the first matching pattern wins.",
    )
    pv_aliases: dict[str, str] = Field(
        default_factory=dict,
        description="Pin a PV segment: TwinCAT path (names joined with ^) -> "
        "PascalCase, different from every other name of the same controller.",
    )
    transports: TransportsConfig = Field(
        default=TransportsConfig(), description="Which EPICS protocols to serve."
    )
    chain: Path | None = Field(
        default=None,
        description="A chain file (the simulator's format, e.g. from "
        "`fastcs-ethercat chain dump`; relative to this file) to serve from "
        "while the target does not answer at start; without it, the chain this "
        "target showed last (kept under $FASTCS_ETHERCAT_RUNTIME_DIR/chains, in "
        "the image /epics/runtime/chains, else under "
        "$XDG_CACHE_HOME/fastcs-ethercat/chains). "
        "`ioc --list-pvs` lists it without contacting the target.",
    )
    pv_lists_dir: Path | None = Field(
        default=None,
        description="Where to write, at every start, the Archiver Appliance list "
        "(`archiver.json`) and the autosave request file (`autosave.req`) of the "
        "PVs served (relative to this file); none when unset.",
    )
    autosave_dir: Path | None = Field(
        default=None,
        description="Where softioc's autosave keeps what operators set on the "
        "records (alarm limits and severities, hysteresis, deadbands, DESC; "
        "never a value), restored at the next start before the IOC serves "
        "(relative to this file; in the chart: /autosave); none when unset.",
    )
    archiver: ArchiverConfig = Field(
        default=ArchiverConfig(),
        description="Which PVs the archiver list holds (policies by kind: "
        "docs/how-to/deploy.md).",
    )
    screens_dir: Path | None = Field(
        default=None,
        description="Where to write Phoebus .bob screens of the chain (relative "
        "to this file; in the image /epics/opi); none when unset.",
    )
    audit_puts: bool = Field(
        default=True,
        description="Log every put through the EPICS database (CA and PVA) once "
        "on stdout: client user@host (PVA: the client's IP), PV.FIELD, old -> new.",
    )
    read_only: bool = Field(
        default=False,
        description="Serve outputs (RxPDO symbols, CoE objects) read-only.",
    )
    databases: list[DatabaseConfig] = Field(
        default_factory=list,
        description="A site's .db files (calc, calcout, alarm summaries linked "
        "to the served PVs), loaded after the IOC's records with their macros "
        "and P=<prefix> (CA served).",
    )
    access_security_file: Path | None = Field(
        default=None,
        description="EPICS access security (ACF) for CA: who may write outputs "
        "(ASG `OUTPUTS`) and CoE parameters (ASG `COE`); see "
        "ioc/access-example.acf.",
    )

    @field_validator("prefix")
    @classmethod
    def _prefix_fits(cls, prefix: str) -> str:
        try:
            check_prefix(prefix)
        except UserError as error:
            raise ValueError(str(error).removeprefix("prefix: ")) from None
        return prefix

    @field_validator("target")
    @classmethod
    def _target_parses(cls, target: str) -> str:
        split_host_port(target)
        return target

    @field_validator("ams_net_id", "local_net_id")
    @classmethod
    def _netid_parses(cls, netid: str | None) -> str | None:
        return None if netid is None else str(AmsNetId.parse(netid))

    @field_validator("pv_aliases")
    @classmethod
    def _aliases_are_segments(cls, aliases: dict[str, str]) -> dict[str, str]:
        for key, segment in aliases.items():
            try:
                check_alias(key, segment)
            except UserError as error:
                raise ValueError(str(error)) from None
        return aliases

    @property
    def target_host(self) -> str:
        return split_host_port(self.target)[0]

    @property
    def target_port(self) -> int:
        return split_host_port(self.target)[1]

    def site_databases(self) -> list[SiteDatabase]:
        """The `databases`, each with P set to the prefix unless given."""
        return [
            SiteDatabase(item.file, {"P": self.prefix, **item.macros})
            for item in self.databases
        ]

    def poll_period(self, *terminal_keys: str) -> float:
        """Seconds between polls of a terminal: its own rate if set, else the IOC's."""
        for key in terminal_keys:
            rate = self.terminals.get(key, TerminalConfig()).poll_rate_hz
            if rate is not None:
                return 1.0 / rate
        return 1.0 / self.poll_rate_hz


def split_host_port(target: str) -> tuple[str, int]:
    """`host` or `host:port` -> (host, port); the ADS TCP port is 48898."""
    host, sep, port = target.strip().rpartition(":")
    if not sep:
        host, port = target.strip(), str(DEFAULT_ADS_TCP_PORT)
    if not host or not port.isdecimal() or not 0 < int(port) < 65536:
        raise ValueError(f"target must be host or host:port, got {target!r}")
    return host, int(port)


def load_ioc_config(
    path: Path | None, overrides: Mapping[str, Any] | None = None
) -> IocConfig:
    """Load the YAML file (if any), apply flags (dotted keys; None: not given).

    Relative paths in the file are taken relative to the file's directory.
    """
    raw: dict[str, Any] = {}
    places: dict[tuple[Any, ...], tuple[int, int]] = {}
    if path is not None:
        raw, places = _read_yaml(path)
        _resolve_paths(raw, path.parent)
    given = {
        key: value for key, value in (overrides or {}).items() if value is not None
    }
    for dotted, value in given.items():
        _set_dotted(raw, dotted, value)
    _chain_terminal_dirs(raw)
    try:
        return IocConfig.model_validate(raw)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "(top level)"
        message = first["msg"].removeprefix("Value error, ")
        if first["type"] == "extra_forbidden":
            message = "unknown key"
        if where in given:
            where = f"{where} (command line)"
        elif tuple(first["loc"]) in places:  # the key's line in the file
            line, column = places[tuple(first["loc"])]
            message, where = f"{where}: {message}", f"{line}:{column}"
        raise UserError(message, path=path, where=where) from None


def config_schema() -> dict[str, Any]:
    """The JSON schema of an IOC configuration file (for editors and CI)."""
    schema = IocConfig.model_json_schema()
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "fastcs-ethercat IOC configuration",
        **{key: value for key, value in schema.items() if key != "title"},
    }


def config_schema_text() -> str:
    """`config_schema()` as the text `ioc schema` prints and the repo keeps."""
    return json.dumps(config_schema(), indent=2) + "\n"


def _read_yaml(path: Path) -> tuple[dict[str, Any], dict[tuple[Any, ...], Any]]:
    """The settings and the line:column of each key."""
    text = read_text_bounded(path, MAX_CONFIG_BYTES)
    located = parse_yaml(text, path)
    if located.data is None:
        return {}, {}
    if not isinstance(located.data, dict):
        raise UserError("expected a mapping of settings at the top", path=path)
    return located.data, located.places


def _resolve_paths(raw: dict[str, Any], base: Path) -> None:
    def resolve(value: Any) -> Any:
        return str(base / value) if isinstance(value, str) else value

    if isinstance(raw.get("terminal_dirs"), list):
        raw["terminal_dirs"] = [resolve(item) for item in raw["terminal_dirs"]]
    for key in (
        "screens_dir",
        "access_security_file",
        "chain",
        "pv_lists_dir",
        "autosave_dir",
    ):
        if key in raw:
            raw[key] = resolve(raw[key])
    for item in raw.get("databases") or ():
        if isinstance(item, dict) and "file" in item:
            item["file"] = resolve(item["file"])
    route = raw.get("route")
    if isinstance(route, dict) and "password_file" in route:
        route["password_file"] = resolve(route["password_file"])


def _chain_terminal_dirs(raw: dict[str, Any]) -> None:
    """Without `terminal_dirs` of its own, the config serves the YAML its
    `chain:` file names (`chain.file`): the chain and its types stay one."""
    chain = raw.get("chain")
    if "terminal_dirs" in raw or not isinstance(chain, str):
        return
    from fastcs_ethercat.chain.file import load_chain

    sources = load_chain(chain).terminal_sources()
    if sources is not None:
        raw["terminal_dirs"] = [str(path) for path in sources]


def _set_dotted(raw: dict[str, Any], dotted: str, value: Any) -> None:
    *parents, last = dotted.split(".")
    node = raw
    for part in parents:
        child = node.get(part)
        if not isinstance(child, dict):
            child = {}
            node[part] = child
        node = child
    node[last] = value
