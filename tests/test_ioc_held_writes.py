"""Writes held through an online change, in-process: the simulator on a
thread of this process, the IOC's controller tree discovered from it as at
start (no transport), its supervisor stepped by the test, so each put meets
the change at a known moment.

A put whose handle answers that the symbol table changed (0x711) is held
until the master has resolved again (`HOLD_S`), then:

- a later put on the same output supersedes it: the held put fails and is
  never sent again, the later one decides;
- its symbol gone, or there with another type or size: it fails visibly
  (the put raises, the setpoint shows INVALID/WRITE) and nothing is sent
  by the new handles.

What the IOC sends is seen by a spy on the real client's `write_by_handle`.
"""

from __future__ import annotations

import asyncio
import shutil
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml
from fastcs.attributes import AttrRW

from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ioc.alarms import Severity, Status
from fastcs_ethercat.ioc.app import root_controller
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.controllers.master import MasterController, SupersededError
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.twincat.target import SimTarget
from tests.conftest import TERMINALS_DIR
from tests.sim_thread import SimulatorThread
from tests.tree_support import chain_text

ANALOG_SLAVE = "Term 3 (EP4374-0002)"
ANALOG = f"{ANALOG_SLAVE}.AO Outputs Channel 3"
"""An INT output; a DINT of the same name in the terminal's other PDO group
(`_widened_terminal`)."""
WIDE_GROUP = "Compact"


@dataclass
class Sent:
    """Every write by handle this process sent: (handle, bytes)."""

    writes: list[tuple[int, bytes]] = field(default_factory=list)

    def of(self, data: bytes) -> list[int]:
        """The handles `data` was sent by."""
        return [handle for handle, sent in self.writes if sent == data]


@dataclass
class Served:
    sim: SimulatorThread
    root: RootController
    master: MasterController
    sent: Sent

    def output(self, symbol: str) -> AttrRW[Any, Any]:
        key = next(k for k, p in self.master.points.items() if p.symbol == symbol)
        attribute = self.master.shown_by_key[key]
        assert isinstance(attribute, AttrRW)
        return attribute

    def put(self, symbol: str, value: int) -> asyncio.Task[None]:
        return asyncio.create_task(self.output(symbol).put(value, sync_setpoint=False))

    async def refused_by_the_change(self, count: int) -> None:
        """Until `count` writes have been sent (each met the old handle)."""
        for _ in range(500):
            if len(self.sent.writes) >= count:
                return
            await asyncio.sleep(0.01)
        raise AssertionError(f"{count} writes expected, sent {self.sent.writes}")

    async def resolve_again(self) -> None:
        """The supervisor's next step: it sees the new symbol version and
        resolves every symbol again (new handles, polling again)."""
        supervisor = self.root.reconnection.supervisor
        resyncs = supervisor.stats.resyncs
        await supervisor.step()
        assert supervisor.stats.resyncs == resyncs + 1, supervisor.stats


def _widened_terminal(directory: Path) -> None:
    """EP4374-0002 whose other PDO group has its outputs as DINT under the
    same names: an online change to that group changes their type and size."""
    source = TERMINALS_DIR / "EP4374-0002.yaml"
    data = yaml.safe_load(source.read_text(encoding="utf-8"))
    (terminal,) = data.values()
    outputs = next(
        n for n in terminal["symbol_nodes"] if n["name_template"].startswith("AO ")
    )
    wide = {
        **outputs,
        "fastcs_name": "ao_outputs_wide_channel_{channel}",
        "selected": False,
        "pdo_indices": [0x1602, 0x1603],
        "type_name": "DINT",
        "bit_size": 32,
        "members": [{**outputs["members"][0], "type_name": "DINT", "bit_size": 32}],
    }
    terminal["symbol_nodes"].append(wide)
    group = next(g for g in terminal["pdo_groups"] if g["name"] == WIDE_GROUP)
    group["pdo_indices"] = [0x1A01, 0x1A03, 0x1602, 0x1603]
    group["symbol_indices"] = [1, len(terminal["symbol_nodes"]) - 1]
    (directory / source.name).write_text(
        yaml.safe_dump(data, sort_keys=False), encoding="utf-8"
    )


@asynccontextmanager
async def _served(work: Path, monkeypatch: pytest.MonkeyPatch) -> AsyncIterator[Served]:
    terminals = work / "terminals"
    terminals.mkdir()
    for name in ("EK1100", "EL2024"):
        shutil.copy(TERMINALS_DIR / f"{name}.yaml", terminals)
    _widened_terminal(terminals)
    chain = work / "chain.yaml"
    chain.write_text(chain_text(["EK1100", "EL2024", "EP4374-0002"]), "utf-8")
    sent = Sent()
    write_by_handle = AdsClient.write_by_handle

    async def spy(client: AdsClient, handle: int, data: bytes) -> None:
        sent.writes.append((handle, data))
        await write_by_handle(client, handle, data)

    monkeypatch.setattr(AdsClient, "write_by_handle", spy)
    with SimulatorThread(SimTarget.from_chain(chain, terminals)) as sim:
        config = IocConfig(
            prefix="HELD",
            target=f"127.0.0.1:{sim.endpoints.tcp_port}",
            ams_net_id=sim.endpoints.net_id,
            terminal_dirs=(terminals,),
        )
        root = root_controller(config)
        plan, connection = await root.plan_source()
        root.build(plan, connection)
        root.post_initialise()  # the IOs connected, as FastCS does
        (master,) = root.masters
        await master.start_polling()
        try:
            yield Served(sim, root, master, sent)
        finally:
            await root.disconnect()


async def test_a_later_put_supersedes_one_held_through_a_change(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    async with _served(tmp_path, monkeypatch) as served:
        served.sim.control.add_fault("online_change")
        first = served.put(ANALOG, 111)
        await served.refused_by_the_change(1)
        later = served.put(ANALOG, 222)
        await served.refused_by_the_change(2)
        (old,) = set(served.sent.of((111).to_bytes(2, "little")))
        await served.resolve_again()
        outcomes = await asyncio.gather(first, later, return_exceptions=True)
        plc = served.sim.control.get_symbol(ANALOG)
        alarm = served.root.health.setpoint_alarm(served.output(ANALOG))

    assert isinstance(outcomes[0], SupersededError), outcomes
    assert outcomes[1] is None, outcomes
    assert served.sent.of((111).to_bytes(2, "little")) == [old]  # never again
    sent_later = served.sent.of((222).to_bytes(2, "little"))
    assert len(sent_later) == 2 and sent_later[0] == old != sent_later[1]
    assert plc == 222
    assert alarm.severity == Severity.NO_ALARM


@pytest.mark.parametrize("change", ["removed", "widened"])
async def test_a_held_put_whose_symbol_went_or_changed_fails_and_is_not_sent(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, change: str
) -> None:
    """The terminal taken off the bus, or its outputs now DINT (another PDO
    group): the held put fails for the client, the setpoint says why, and
    nothing goes out by the new handles (the new DINT keeps its value)."""
    async with _served(tmp_path, monkeypatch) as served:
        output = served.output(ANALOG)  # the attribute, before the change
        if change == "removed":
            served.sim.control.add_fault("online_change", removed=[ANALOG_SLAVE])
        else:
            served.sim.control.add_fault(
                "online_change", pdo_groups={ANALOG_SLAVE: WIDE_GROUP}
            )
        held = asyncio.create_task(output.put(333, sync_setpoint=False))
        await served.refused_by_the_change(1)
        await served.resolve_again()
        (outcome,) = await asyncio.gather(held, return_exceptions=True)
        alarm = served.root.health.setpoint_alarm(output)
        widened = None if change == "removed" else served.sim.control.get_symbol(ANALOG)

    assert isinstance(outcome, LookupError), outcome
    assert "not on the target any more" in str(outcome)
    assert (alarm.severity, alarm.status) == (Severity.INVALID, Status.WRITE)
    assert "not on the target any more" in alarm.message
    assert len(served.sent.writes) == 1  # the attempt the change refused
    assert widened in (None, 0)
