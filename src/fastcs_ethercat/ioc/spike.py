"""A small IOC without ADS that proves the FastCS plumbing end to end.

    python -m fastcs_ethercat.ioc.spike --prefix SPIKE [--screens DIR] [--measure N]

The tree has the shape the real IOC will have, with names from `naming` and
types from `datatypes`:

    <prefix>                    Counter (a @scan), Uptime
    <prefix>:ETH1               SlaveCount (read once)
    <prefix>:ETH1:RIO1:MOD5     one attribute per symbol of a made-up terminal,
                                declared at run time, read and written through
                                an AttributeIO on an in-memory "device"

`--measure N` adds N float and N integer attributes and, once the IOC serves,
prints what one `attribute.update()` costs with both transports attached.
"""

from __future__ import annotations

import argparse
import asyncio
import time
from collections.abc import Sequence
from dataclasses import KW_ONLY, dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from fastcs.attributes import AttributeIO, AttributeIORef, AttrR, AttrRW, AttrW
from fastcs.controllers import Controller
from fastcs.datatypes import DataType, Int
from fastcs.methods import scan
from fastcs.util import ONCE

from fastcs_ethercat.ioc.datatypes import ExactFloat, description, to_fastcs
from fastcs_ethercat.ioc.launch import LaunchOptions, run
from fastcs_ethercat.ioc.naming import Node, NodeKind, PvNames, PvRequest, plan_pv_names
from fastcs_ethercat.ioc.publish import Publisher

MASTER: Final = Node(NodeKind.MASTER, "Device 1 (EtherCAT)")
COUPLER: Final = Node(NodeKind.COUPLER, "Term 1 (EK1100)")
TERMINAL: Final = Node(NodeKind.TERMINAL, "Term 5 (EL3104)")


@dataclass(frozen=True)
class SpikeSymbol:
    """A made-up TwinCAT symbol of the spike terminal."""

    name: str
    type_name: str
    value: Any
    writable: bool = False
    units: str | None = None
    enum_members: dict[int, str] | None = None


SYMBOLS: Final = (
    SpikeSymbol("AI Standard Channel 1.Value", "INT", -1234, units="counts"),
    SpikeSymbol("AI Standard Channel 1.Status.Overrange", "BOOL", True),
    SpikeSymbol("CNT Inputs.Counter value", "UDINT", 4_000_000_001),
    SpikeSymbol("Scaled.Value", "LREAL", 1.2345678901234567, units="V"),
    SpikeSymbol("Info.Name", "STRING(20)", "EL3104 spike"),
    SpikeSymbol("Oversampling.Samples", "ARRAY [0..7] OF INT", list(range(-4, 4))),
    SpikeSymbol(
        "Settings.Mode",
        "USINT",
        1,
        writable=True,
        enum_members={0: "Signed", 1: "Unsigned", 5: "Absolute MSB sign"},
    ),
    SpikeSymbol("AO Output Channel 1.Analog output", "SINT", 0, writable=True),
    SpikeSymbol("Outputs.Enable", "BOOL", False, writable=True),
)


@dataclass
class DeviceRef(AttributeIORef):
    """Which value of the in-memory device an attribute reads and writes."""

    key: str
    _: KW_ONLY
    update_period: float | None = 0.2


class DeviceIO(AttributeIO[Any, DeviceRef]):
    """Device access for `DeviceRef` attributes: read and write a dict."""

    def __init__(self, device: dict[str, Any]) -> None:
        super().__init__()
        self.device = device

    async def update(self, attr: AttrR[Any, DeviceRef]) -> None:
        await attr.update(self.device[attr.io_ref.key])

    async def send(self, attr: AttrW[Any, DeviceRef], value: Any) -> None:
        self.device[attr.io_ref.key] = value


class SpikeTerminal(Controller):
    """One terminal: its attributes are declared from its symbols at run time."""

    def __init__(
        self, names: PvNames, symbols: Sequence[SpikeSymbol], device: dict[str, Any]
    ) -> None:
        super().__init__(description="Term 5 (EL3104)", ios=[DeviceIO(device)])
        for symbol in symbols:
            datatype: DataType = to_fastcs(
                symbol.type_name,
                units=symbol.units,
                enum_members=symbol.enum_members,
                enum_name=symbol.name,
            )
            device[symbol.name] = datatype.validate(_initial(symbol))
            kind = AttrRW if symbol.writable else AttrR
            self.add_attribute(
                names.leaves[PvRequest((MASTER, COUPLER, TERMINAL), symbol.name)],
                kind(
                    datatype,
                    io_ref=DeviceRef(symbol.name),
                    description=description(symbol.name),
                ),
            )


class SpikeCoupler(Controller):
    """A coupler level with nothing of its own, as an EK1100 has."""


class SpikeMaster(Controller):
    """An EtherCAT master with one value read once at start."""

    slave_count = AttrR(Int(), io_ref=DeviceRef("SlaveCount", update_period=ONCE))

    def __init__(self, device: dict[str, Any]) -> None:
        super().__init__(description="Device 1 (EtherCAT)", ios=[DeviceIO(device)])


class SpikeBench(Controller):
    """Attributes without IO, only there to time `update()`."""

    def __init__(self, count: int) -> None:
        super().__init__(description="update() timing")
        self.floats = [AttrR(ExactFloat(prec=3)) for _ in range(count)]
        self.ints = [AttrR(Int()) for _ in range(count)]
        for index, (real, integer) in enumerate(
            zip(self.floats, self.ints, strict=True)
        ):
            self.add_attribute(f"F{index}", real)
            self.add_attribute(f"I{index}", integer)


class SpikeRoot(Controller):
    """The root: a counter moved by a scan method, and the tree below."""

    counter = AttrR(Int(), description="Counts scans of the root")
    uptime = AttrR(ExactFloat(prec=1, units="s"))

    def __init__(self, prefix: str, measure: int = 0) -> None:
        super().__init__(description="fastcs-ethercat spike")
        self.set_path([prefix])
        self.device: dict[str, Any] = {"SlaveCount": 3}
        self.names = plan_pv_names(
            prefix,
            [PvRequest((MASTER, COUPLER, TERMINAL), s.name) for s in SYMBOLS],
        )
        self._started = time.monotonic()
        master = SpikeMaster(self.device)
        coupler = SpikeCoupler()
        terminal = SpikeTerminal(self.names, SYMBOLS, self.device)
        self.add_sub_controller(self.names.controllers[(MASTER,)], master)
        master.add_sub_controller(self.names.controllers[(MASTER, COUPLER)], coupler)
        coupler.add_sub_controller(
            self.names.controllers[(MASTER, COUPLER, TERMINAL)], terminal
        )
        # Assigning a controller (or an attribute) to `self` registers it with
        # FastCS under that name: this is the sub-controller `<prefix>:Bench`.
        self.bench = SpikeBench(measure) if measure else None

    @scan(0.1)
    async def tick(self) -> None:
        await self.counter.update(self.counter.get() + 1)
        await self.uptime.update(time.monotonic() - self._started)


async def measure_updates(bench: SpikeBench, rounds: int = 5) -> dict[str, float]:
    """Microseconds per `update()`: changed value, same value, via gather, and
    through the IOC's `Publisher`."""
    attributes = [*bench.floats, *bench.ints]

    async def timed(values: Sequence[float], together: bool = False) -> float:
        started = time.perf_counter()
        for value in values:
            updates = [a.update(a.datatype.validate(value)) for a in attributes]
            if together:
                await asyncio.gather(*updates)
            else:
                for update in updates:
                    await update
        elapsed = time.perf_counter() - started
        return 1e6 * elapsed / (len(values) * len(attributes))

    async def published(values: Sequence[float]) -> float:
        publisher = Publisher()
        publisher.start()
        stamp = time.time()
        await asyncio.gather(*(publisher.publish(a, -1.0, stamp) for a in attributes))
        started = time.perf_counter()
        for value in values:
            for attribute in attributes:
                await publisher.publish(attribute, value, stamp)
        elapsed = time.perf_counter() - started
        return 1e6 * elapsed / (len(values) * len(attributes))

    changed = await timed([k + 0.5 for k in range(rounds)])
    unchanged = await timed([rounds - 0.5] * rounds)
    together = await timed([k + 100.5 for k in range(rounds)], together=True)
    publish = await published([k + 200.0 for k in range(rounds)])
    return {
        "changed_us": changed,
        "unchanged_us": unchanged,
        "gather_us": together,
        "published_us": publish,
    }


def _initial(symbol: SpikeSymbol) -> Any:
    if symbol.enum_members is not None:
        return symbol.value
    if isinstance(symbol.value, list):
        return np.asarray(symbol.value)
    return symbol.value


def _arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="A FastCS IOC without ADS.")
    parser.add_argument("--prefix", required=True)
    parser.add_argument("--screens", type=Path, default=None)
    parser.add_argument("--no-ca", action="store_true")
    parser.add_argument("--no-pva", action="store_true")
    parser.add_argument("--measure", type=int, default=0, metavar="N")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> None:
    arguments = _arguments(argv)
    root = SpikeRoot(arguments.prefix, arguments.measure)
    options = LaunchOptions(
        ca=not arguments.no_ca, pva=not arguments.no_pva, screens_dir=arguments.screens
    )

    def on_ready() -> None:
        if root.bench is not None:
            bench = root.bench
            task = asyncio.get_running_loop().create_task(measure_updates(bench))
            task.add_done_callback(
                lambda done: print(
                    "measure: "
                    + " ".join(f"{k}={v:.1f}" for k, v in done.result().items()),
                    flush=True,
                )
            )

    run(root, arguments.prefix, options, on_ready=on_ready)


if __name__ == "__main__":
    main()
