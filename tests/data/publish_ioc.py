"""A small IOC for the publish-path tests, driven over stdin.

    python tests/data/publish_ioc.py --prefix P

Serves CA and PVA as the IOC does for one controller with a float, an int
with limits, a bool, an enum and a text attribute, all published through
`Health` as poll cycles are. Each stdin line is a command, answered by one
`done <command> <number>` line:

    publish NAME=VALUE ...         one poll cycle's batch; number: values
                                   posted
    alarm NAME SEVERITY STATUS     Health.mark_invalid; number: 1
    clear NAME                     Health.mark_ok; number: 1
"""

from __future__ import annotations

import argparse
import asyncio
import enum
import sys
import threading
from typing import Any

from fastcs_ethercat.ioc.fastcs_adapter import import_ioc_modules

import_ioc_modules()

from fastcs.attributes import AttrR  # noqa: E402 - after the lean import
from fastcs.control_system import FastCS  # noqa: E402
from fastcs.controllers import Controller, ControllerAPI  # noqa: E402
from fastcs.datatypes import Bool, Enum, Float, Int, String  # noqa: E402
from fastcs.transports import Transport  # noqa: E402

from fastcs_ethercat.ioc.alarms import Status  # noqa: E402
from fastcs_ethercat.ioc.health import Health  # noqa: E402
from fastcs_ethercat.ioc.launch import LaunchOptions, build_transports  # noqa: E402


class Mode(enum.Enum):
    IDLE = 0
    RUN = 1
    FAULT = 2


class PublishTestController(Controller):
    """One attribute of each record type the publish path writes."""

    def __init__(self) -> None:
        super().__init__(description="publish test")
        self.add_attribute("Temperature", AttrR(Float(prec=2), initial_value=0.0))
        self.add_attribute("Counts", AttrR(Int(min=0, max=1000), initial_value=0))
        self.add_attribute("Flag", AttrR(Bool()))
        self.add_attribute("Mode", AttrR(Enum(Mode), initial_value=Mode.IDLE))
        self.add_attribute("Text", AttrR(String()))


def parse_value(attribute: AttrR[Any, Any], text: str) -> Any:
    datatype = attribute.datatype
    if isinstance(datatype, Enum):
        return Mode[text]
    if isinstance(datatype, Bool):
        return text == "1"
    if isinstance(datatype, Int):
        return int(text)
    if isinstance(datatype, Float):
        return float(text)
    return text


class Ready(Transport):
    """Starts publishing and prints the ready line once the transports serve."""

    def __init__(self, health: Health) -> None:
        self.health = health

    def connect(
        self, controller_apis: list[ControllerAPI], loop: asyncio.AbstractEventLoop
    ) -> None:
        """Nothing to connect."""

    async def serve(self) -> None:
        from fastcs_ethercat.ioc.database import initialised

        await initialised()
        await self.health.publisher.start()
        print("publish ioc ready", flush=True)


async def handle(controller: PublishTestController, health: Health, line: str) -> int:
    attributes: dict[str, Any] = controller.attributes
    match line.split():
        case ["publish", *pairs]:
            values = []
            for pair in pairs:
                name, _, text = pair.partition("=")
                values.append((attributes[name], parse_value(attributes[name], text)))
            published = await health.post_batch(values)
            for attribute, error in published.failures:
                print(f"failure {attribute.name}: {error}", flush=True)
            return published.posted
        case ["alarm", name, severity, status]:
            assert severity == "INVALID"
            health.mark_invalid([attributes[name]], "test", Status[status])
            return 1
        case ["clear", name]:
            await health.mark_ok([attributes[name]], "test")
            return 1
    raise ValueError(f"unknown command {line!r}")


def read_commands(
    controller: PublishTestController, health: Health, loop: asyncio.AbstractEventLoop
) -> None:
    for line in sys.stdin:
        if line.strip():
            coroutine = handle(controller, health, line)
            future = asyncio.run_coroutine_threadsafe(coroutine, loop)
            try:
                print(f"done {line.split()[0]} {future.result(30)}", flush=True)
            except Exception as error:
                print(f"failed {line.strip()}: {error!r}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--prefix", required=True)
    arguments = parser.parse_args()

    loop = asyncio.new_event_loop()
    asyncio.set_event_loop(loop)
    controller = PublishTestController()
    controller.set_path([arguments.prefix])
    health = Health()
    transports = [*build_transports(LaunchOptions()), Ready(health)]
    threading.Thread(
        target=read_commands, args=(controller, health, loop), daemon=True
    ).start()
    FastCS(controller, transports, loop).run(interactive=False)


if __name__ == "__main__":
    main()
