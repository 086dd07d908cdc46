"""The chain description: which TwinCAT system a chain file describes (the
simulator plays it, the IOC boots from it, `chain dump` writes it).

A chain file names the system's AMS NetId, its EtherCAT masters and, per
master, the slaves (couplers and terminals) in bus order, each with its type
(a terminal YAML's), optionally its TwinCAT name, revision, active PDO group,
oversampling factor and signal generators. Everything else (addresses,
NetIds, names) defaults the way TwinCAT assigns it. It may name where the
YAML of its types is (`terminal_dirs`), so that it plays alone.

```yaml
terminal_dirs: [terminals]     # the YAML of its types, relative to this file
system:
  net_id: 127.0.0.1.1.1        # the system's AMS NetId (I/O server: port 300)
  task_cycle_ms: 10            # cycle of the task that moves the inputs
  max_sum_items: 500           # sub-commands one sum request may carry
  sum_write_on_device_port: false  # real TwinCAT: 0xF081 there answers 0x701
masters:
- name: Device 1 (EtherCAT)    # default "Device <n> (EtherCAT)"
  net_id: 127.0.0.1.2.1        # default: the system NetId, 5th byte = n + 1
  info_data: false             # TwinCAT option: InfoData.State/AdsAddr symbols
  slaves:                      # bus order; addresses 1001, 1002, ...
  - type: EK1100               # default name "Term <k> (EK1100)"
  - type: EL3104
    name: Term 5 (EL3104)      # the TwinCAT name (no dots)
    revision: 0x00110000       # reported identity (default: the YAML's)
    serial: 0
    al_state: OP               # EtherCAT state at start (and after clear)
    pdo_group: Compact         # default: the terminal YAML's selected group
    signal: {kind: sine, period_s: 2.0}    # every input of this terminal
    signals:                   # per symbol, member or element below it
      AI Compact Channel 2: {kind: ramp, minimum: 0, maximum: 1000}
  - type: EL3702
    oversampling: 10           # samples per cycle, one of the YAML's factors
  - type: EL9410               # a type without terminal YAML: identity only,
    product_code: 0x24c23052   # no process data, no CoE
```

`terminal_dirs` (directories, files or globs of terminal YAML, relative to
the chain file) replaces the shipped types, as the IOC config's key of that
name does: `sim --chain FILE` plays the chain from them, every revision in
them as its own, unless `--terminals` names a directory; an IOC whose config
names this chain (`chain:`) and no `terminal_dirs` of its own serves them.
`fastcs-ethercat init` writes `terminal_dirs: [terminals]` into its
`chain.yaml`; `chain dump` writes none (the shipped types then play it).

A `revision` other than the YAML's is played from the YAML of that revision
when the simulator is given one (in `terminal_dirs`, or `sim --revisions
DIR`: files of other revisions, e.g. from `terminals generate TYPE
--revision REV`); otherwise the YAML's process data is played and the
simulator says so once at start. `fastcs-ethercat chain dump` writes this
format from a live target.

Signal kinds: constant (`value`), counter (`start`, `step` per cycle), ramp
(`minimum`..`maximum` over `period_s`), sine (`amplitude`, `offset`,
`period_s`, `phase_deg`), random_bits (new draw every `hold_cycles`).

`load_chain` turns every problem into one `UserError` naming file and line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    field_validator,
)

from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.bounded import (
    MAX_CHAIN_BYTES,
    no_bool_for_number,
    read_text_bounded,
)
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.yaml_io import (
    Loc,
    LocatedYaml,
    format_loc,
    parse_yaml,
    validation_error,
)

SignalKind = Literal["constant", "counter", "ramp", "sine", "random_bits"]
AlStateName = Literal["INIT", "PREOP", "BOOT", "SAFEOP", "OP"]


class _Model(BaseModel):
    """Unknown keys are errors: a typo must not silently become a default."""

    model_config = ConfigDict(extra="forbid")
    _no_bool_for_number = field_validator("*", mode="before")(no_bool_for_number)


def _net_id(value: Any) -> str:
    """Accept "a.b.c.d.e.f" only; keep the text (parsed where it is used)."""
    if not isinstance(value, str):
        raise ValueError(f"an AMS NetId is text like 127.0.0.1.1.1, got {value!r}")
    try:
        return str(AmsNetId.parse(value))
    except AdsCodecError as error:
        raise ValueError(str(error)) from None


def _twincat_name(value: Any) -> Any:
    """TwinCAT names travel in Windows-1252 and may not contain dots (a dot
    separates a symbol's parts)."""
    if value is None:
        return value
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"a name is non-empty text, got {value!r}")
    if "." in value:
        raise ValueError(f"a TwinCAT name has no dots, got {value!r}")
    try:
        value.encode("windows-1252")
    except UnicodeEncodeError:
        raise ValueError(f"{value!r} is not representable in Windows-1252") from None
    return value


def _number(value: Any) -> Any:
    """Accept ints written as ESI-style text too ("#x00120000", "0x10")."""
    if isinstance(value, str):
        text = value.strip().lower().replace("#x", "0x")
        try:
            return int(text, 0)
        except ValueError:
            raise ValueError(f"expected a number, got {value!r}") from None
    return value


class SignalSpec(_Model):
    """A deterministic signal generator for input values (seeded per leaf).

    Values are functions of the task cycle count, so they do not depend on
    when the simulator happens to be polled.
    """

    kind: SignalKind = Field(description="constant, counter, ramp, sine or random_bits")
    value: float = Field(default=0.0, description="constant: the value.")
    start: float = Field(default=0.0, description="counter: first value.")
    step: float = Field(default=1.0, description="counter: increment per cycle.")
    minimum: float | None = Field(
        default=None, description="ramp: low end (default: the type's minimum)."
    )
    maximum: float | None = Field(
        default=None, description="ramp: high end (default: the type's maximum)."
    )
    period_s: float = Field(default=1.0, gt=0, description="ramp / sine period.")
    amplitude: float | None = Field(
        default=None, description="sine: amplitude (default: 80% of the range)."
    )
    offset: float = Field(default=0.0, description="sine: centre value.")
    phase_deg: float | None = Field(
        default=None, description="sine: phase (default: drawn from the seed)."
    )
    hold_cycles: int = Field(
        default=1, ge=1, description="random_bits: cycles each draw is held."
    )


class SlaveSpec(_Model):
    """One EtherCAT slave (coupler or terminal), in bus order."""

    type: str = Field(description="Terminal type, as in terminals/<type>.yaml.")
    name: str | None = Field(
        default=None, description='TwinCAT name; default "Term <k> (<type>)".'
    )
    revision: int | None = Field(
        default=None,
        description="Revision it reports (default: the YAML's); its process "
        "data follows the YAML of that revision where one is given "
        "(`sim --revisions DIR`).",
    )
    vendor_id: int | None = Field(
        default=None,
        description="Only for a type without terminal YAML: the vendor it "
        "reports (default 2, Beckhoff).",
    )
    product_code: int | None = Field(
        default=None,
        description="Only for a type without terminal YAML: the product code "
        "it reports; it is played with no process data and no CoE.",
    )
    serial: int = Field(default=0, ge=0, description="Serial number it reports.")
    pdo_group: str | None = Field(
        default=None, description="Active PDO group (default: the YAML's)."
    )
    oversampling: int | None = Field(
        default=None, ge=1, description="Oversampling factor (default: the YAML's)."
    )
    al_state: AlStateName = Field(default="OP", description="EtherCAT state at start.")
    signal: SignalSpec | None = Field(
        default=None, description="Generator for every input of this terminal."
    )
    signals: dict[str, SignalSpec] = Field(
        default_factory=dict,
        description="Generators by symbol or member name below the terminal.",
    )

    @field_validator("revision", "vendor_id", "product_code", mode="before")
    @classmethod
    def _revision_number(cls, value: Any) -> Any:
        return _number(value)

    @field_validator("name", mode="before")
    @classmethod
    def _slave_name(cls, value: Any) -> Any:
        return _twincat_name(value)


class MasterSpec(_Model):
    """One EtherCAT master (an I/O device of TwinCAT) with its slaves."""

    name: str | None = Field(
        default=None, description='Device name; default "Device <n> (EtherCAT)".'
    )
    net_id: str | None = Field(default=None, description="The device's own AMS NetId.")
    info_data: bool = Field(
        default=False,
        description="Add InfoData.State / InfoData.AdsAddr per slave (TwinCAT "
        "option, off by default).",
    )
    slaves: list[SlaveSpec] = Field(description="Slaves in bus order.")

    @field_validator("net_id", mode="before")
    @classmethod
    def _net_id_text(cls, value: Any) -> str | None:
        return None if value is None else _net_id(value)

    @field_validator("name", mode="before")
    @classmethod
    def _master_name(cls, value: Any) -> Any:
        return _twincat_name(value)


class SystemSpec(_Model):
    """The TwinCAT system as a whole."""

    net_id: str = Field(default="127.0.0.1.1.1", description="The system NetId.")
    task_cycle_ms: float = Field(
        default=10.0, gt=0, description="Cycle of the I/O task (inputs move)."
    )
    max_sum_items: int = Field(
        default=500,
        ge=1,
        le=1000,
        description="Sub-commands one sum request may carry (Beckhoff: 500).",
    )
    sum_write_on_device_port: bool = Field(
        default=False,
        description="Serve 0xF081 on the device port; real TwinCAT answers "
        "0x701 there (pyads issue #456).",
    )
    symbol_version_on_device_port: bool = Field(
        default=True,
        description="Answer the symbol version (0xF008) on the device port; "
        "whether a real one does is unconfirmed, so clients must not rely on it.",
    )
    upload_info_2: bool = Field(
        default=True,
        description="Answer 0xF00F (24 bytes); older TwinCAT answers only "
        "0xF00C (8 bytes: symbol count and table size).",
    )

    @field_validator("net_id", mode="before")
    @classmethod
    def _net_id_text(cls, value: Any) -> str:
        return _net_id(value)


class Chain(_Model):
    """A whole simulated system: masters and their slaves in bus order."""

    terminal_dirs: tuple[str, ...] | None = Field(
        default=None,
        description="Directories, files or globs of the terminal YAML of this "
        "chain's types, relative to this file; they replace the shipped types "
        "(default: the shipped types, or what `--terminals` names).",
    )
    system: SystemSpec = Field(default_factory=SystemSpec)
    masters: list[MasterSpec] = Field(min_length=1, description="EtherCAT masters.")

    _located: LocatedYaml | None = PrivateAttr(default=None)

    @field_validator("terminal_dirs", mode="before")
    @classmethod
    def _terminal_dirs(cls, value: Any) -> Any:
        """A list of non-empty paths (one path alone is a list of one)."""
        entries = [value] if isinstance(value, str) else value
        if not isinstance(entries, list) or not entries:
            raise ValueError(f"a list of folders of terminal YAML, got {value!r}")
        for entry in entries:
            if not isinstance(entry, str) or not entry.strip():
                raise ValueError(f"a folder of terminal YAML is a path, got {entry!r}")
        return entries

    @property
    def source(self) -> Path | str | None:
        """The file this chain was read from, if any."""
        return None if self._located is None else self._located.path

    def terminal_sources(self) -> tuple[Path, ...] | None:
        """`terminal_dirs` relative to the chain file's folder (None: the
        chain names none)."""
        if self.terminal_dirs is None:
            return None
        source = self.source
        base = source.parent if isinstance(source, Path) else Path()
        return tuple(base / entry for entry in self.terminal_dirs)

    def where(self, loc: Loc) -> str | None:
        """`line:column` of a key path in the source file (None without one)."""
        return None if self._located is None else self._located.where(loc)

    def error(self, loc: Loc, message: str) -> UserError:
        """A one-line UserError about the part of the chain at `loc`."""
        return UserError(
            f"{format_loc(loc)}: {message}" if loc else message,
            path=self.source,
            where=self.where(loc),
        )


def parse_chain(text: str, path: Path | str = "<chain>") -> Chain:
    """A validated chain from YAML text; `path` only names it in errors."""
    located = parse_yaml(text, path)
    if not isinstance(located.data, dict):
        raise UserError(
            "a chain file is a mapping with `masters:` (and optionally `system:`)",
            path=path,
            where=located.where(()),
        )
    try:
        chain = Chain.model_validate(located.data)
    except ValidationError as error:
        raise validation_error(located, (), error) from None
    chain._located = located
    _check_unique_names(chain)
    return chain


def _check_unique_names(chain: Chain) -> None:
    """TwinCAT names are unique in a project: two slaves may not share one."""
    seen: dict[str, str] = {}
    for m, master in enumerate(chain.masters):
        for s, slave in enumerate(master.slaves):
            if slave.name is None:
                continue
            if slave.name in seen:
                raise chain.error(
                    ("masters", m, "slaves", s, "name"),
                    f"name {slave.name!r} is already used by {seen[slave.name]}",
                )
            seen[slave.name] = format_loc(("masters", m, "slaves", s))


def load_chain(path: Path | str) -> Chain:
    """Read and validate a chain file; one-line UserErrors naming file and line."""
    path = Path(path)
    text = read_text_bounded(path, MAX_CHAIN_BYTES, what="chain file")
    return parse_chain(text, path)


__all__ = [
    "Chain",
    "MasterSpec",
    "SignalSpec",
    "SlaveSpec",
    "SystemSpec",
    "load_chain",
    "parse_chain",
]
