"""A chain as the simulator plays it, for comparing chain files."""

from __future__ import annotations

from fastcs_ethercat.chain.file import Chain
from fastcs_ethercat.terminals.registry import TerminalRegistry
from fastcs_ethercat.twincat.resolve import resolve_chain


def played(chain: Chain, registry: TerminalRegistry) -> list[tuple[object, ...]]:
    """Per slave in bus order: master (name, NetId), the slave's name, type,
    identity, active PDO group, oversampling factor and AL state at start."""
    _, masters = resolve_chain(chain, registry)
    rows: list[tuple[object, ...]] = []
    for master in masters:
        for slave in master.slaves:
            oversampling = slave.terminal.oversampling
            rows.append(
                (
                    master.name,
                    str(master.net_id),
                    slave.name,
                    slave.type_name,
                    slave.identity,
                    slave.terminal.selected_pdo_group,
                    None if oversampling is None else oversampling.selected_factor,
                    slave.initial_state,
                )
            )
    return rows
