"""A discovered chain written in the simulator's chain format, and the cache of
the last chain each target showed.

One format for three uses: `fastcs-ethercat chain dump` writes a live rack as
a chain file that `sim --chain` plays offline; the IOC keeps the last chain it
discovered per target (`$FASTCS_ETHERCAT_RUNTIME_DIR/chains/` if set, as in
the image, else `$XDG_CACHE_HOME/fastcs-ethercat/chains/`) and boots from it, or from
a configured `chain:` file, while the PLC does not answer.

What a chain holds is what the master and the live symbol table say: masters
(name, NetId), slaves in bus order with their TwinCAT names and identities
(type, revision, serial; vendor and product code for a type without YAML),
the PDO group each runs, oversampling factors and AL states other than OP.
"""

from __future__ import annotations

import datetime
import logging
import os
import re
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from fastcs_ethercat.ads.ethercat import AlState
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.plan import MasterPlan, SystemPlan, TerminalPlan
from fastcs_ethercat.runtime import state_dir
from fastcs_ethercat.terminals.yaml_io import dump_yaml
from fastcs_ethercat.terminals.yaml_style import HexInt

if TYPE_CHECKING:  # read and checked only once kept, not at import
    from fastcs_ethercat.chain.file import Chain

logger = logging.getLogger(__name__)

CACHE_KIND: Final = "chains"
AL_STATE_MASK: Final = 0x0F
"""The state in the AL status byte (the high bits are flags)."""
_UNSAFE: Final = re.compile(r"[^A-Za-z0-9.-]+")


def chain_data(plan: SystemPlan) -> dict[str, Any]:
    """`plan` as a chain file's content (`chain/file.py`)."""
    system: dict[str, Any] = {"net_id": plan.net_id}
    if plan.symbol_version < 0:  # the device port did not answer 0xF008
        system["symbol_version_on_device_port"] = False
    return {"system": system, "masters": [_master(m) for m in plan.masters]}


def _master(master: MasterPlan) -> dict[str, Any]:
    return {
        "name": master.name,
        "net_id": master.net_id,
        "slaves": [_slave(terminal) for terminal in master.terminals],
    }


def _slave(terminal: TerminalPlan) -> dict[str, Any]:
    slave = terminal.slave
    identity = slave.identity
    known = terminal.terminal_type is not None
    entry: dict[str, Any] = {
        "type": terminal.terminal_type
        or slave.type_name
        or f"0x{identity.product_code:08x}",
        "name": slave.name,
        "revision": HexInt(identity.revision, 8),
    }
    if not known:  # the simulator plays it from its identity alone
        entry["vendor_id"] = HexInt(identity.vendor_id, 8)
        entry["product_code"] = HexInt(identity.product_code, 8)
    if identity.serial_number:
        entry["serial"] = identity.serial_number
    state = _al_state_name(slave.al_state)
    if state is not None and state != AlState.OP.name:
        entry["al_state"] = state
    if known and terminal.active_group is not None:
        entry["pdo_group"] = terminal.active_group
    if known and terminal.oversampling is not None:
        entry["oversampling"] = terminal.oversampling
    return entry


def _al_state_name(raw: int) -> str | None:
    try:
        return AlState(raw & AL_STATE_MASK).name
    except ValueError:
        return None


def chain_text(plan: SystemPlan, source: str) -> str:
    """The chain file's text, headed by where and when it was read."""
    now = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
    header = (
        f"# The chain of {source} as fastcs-ethercat discovered it on {now}\n"
        "# (the simulator's chain format: `fastcs-ethercat sim --chain FILE`).\n"
    )
    return dump_yaml(chain_data(plan), header=header)


def write_chain(plan: SystemPlan, source: str, path: Path) -> Chain:
    """Write `plan` as a chain file at `path` (atomically) and return it as
    read back: what is written is always a chain the simulator accepts."""
    from fastcs_ethercat.chain.file import parse_chain

    text = chain_text(plan, source)
    chain = parse_chain(text, path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as file:
            file.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return chain


def cache_path(target: str) -> Path:
    """Where the last chain of `target` (host[:port]) is kept."""
    return state_dir(CACHE_KIND) / f"{_UNSAFE.sub('_', target)}.yaml"


def remember(plan: SystemPlan, target: str) -> None:
    """Keep `plan`'s chain as the last one `target` showed; never raises (a
    read-only or full cache only costs the next offline boot)."""
    path = cache_path(target)
    try:
        write_chain(plan, target, path)
    except (OSError, UserError) as error:
        logger.warning("cannot keep the chain of %s in %s: %s", target, path, error)
        return
    logger.debug("kept the chain of %s in %s", target, path)


def cached_chain(target: str) -> Chain | None:
    """The last chain `target` showed, if one is kept and still reads."""
    from fastcs_ethercat.chain.file import load_chain

    path = cache_path(target)
    if not path.is_file():
        return None
    try:
        return load_chain(path)
    except UserError as error:
        logger.warning("ignoring the cached chain: %s", error)
        return None


__all__ = [
    "cache_path",
    "cached_chain",
    "chain_data",
    "chain_text",
    "remember",
    "write_chain",
]
