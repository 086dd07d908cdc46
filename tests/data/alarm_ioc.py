"""A small IOC for the alarm and access-security tests, driven over stdin.

    python tests/data/alarm_ioc.py --prefix P [--acf FILE] [--read-only] [--extra N]

Serves CA and PVA (through our launcher's transports) for one controller with
a float, an enum, a waveform, an output, a CoE-like parameter and a setting;
the output goes to ASG OUTPUTS, the parameter to ASG COE, the setting stays
in DEFAULT; a write-only attribute refuses every write. Each stdin line is a command,
answered by one `done <command> <number>` line on stdout:

    alarm NAME SEVERITY STATUS [MESSAGE...]   publish_alarm, number: PVs reached
    clear NAME                                back to the value's own alarm
    alarm-all SEVERITY STATUS                 publish_alarm on every attribute
                                              (also prints how long it took)
    update NAME VALUE                         the value posted (ioc.publish)
    asactive                                  1 if access security is on
"""

from __future__ import annotations

import argparse
import asyncio
import ctypes
import enum
import sys
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from fastcs.attributes import Attribute, AttrR, AttrRW, AttrW
from fastcs.control_system import FastCS
from fastcs.controllers import Controller, ControllerAPI
from fastcs.datatypes import Enum, Float, Int, Waveform
from fastcs.transports import Transport

from fastcs_ethercat.ioc.access import (
    COE_GROUP,
    OUTPUTS_GROUP,
    AccessSecurity,
)
from fastcs_ethercat.ioc.alarms import (
    AlarmState,
    Severity,
    Status,
    publish_alarm,
    value_alarm,
)
from fastcs_ethercat.ioc.launch import LaunchOptions, build_transports
from fastcs_ethercat.ioc.publish import Publisher

PUBLISHER = Publisher()


def clear_alarm(attribute: Attribute[Any, Any]) -> int:
    """Back to the alarm of the attribute's value; records reached."""
    return publish_alarm(attribute, value_alarm(attribute))


def set_alarms(
    attributes: Iterable[Attribute[Any, Any]], severity: Severity, status: Status
) -> int:
    """`publish_alarm` for every attribute; records reached."""
    state = AlarmState(severity, status)
    return sum(publish_alarm(attribute, state) for attribute in attributes)


def _access_security_active() -> bool:
    """Whether EPICS access security is on (after iocInit loaded an ACF)."""
    from epicscorelibs.ioc import Com

    return bool(ctypes.c_int.in_dll(Com, "asActive").value)


class Mode(enum.Enum):
    IDLE = 0
    RUN = 1


class AlarmTestController(Controller):
    """One attribute of each kind the alarm code treats differently."""

    def __init__(self, extra: int = 0) -> None:
        super().__init__(description="alarm test")
        for index in range(extra):
            self.add_attribute(f"Extra{index}", AttrR(Float(), initial_value=index))
        self.add_attribute("Temperature", AttrR(Float(prec=2), initial_value=21.5))
        self.add_attribute("Mode", AttrR(Enum(Mode), initial_value=Mode.RUN))
        self.add_attribute(
            "Samples",
            AttrR(
                Waveform(np.int16, shape=(4,)),
                initial_value=np.array([1, 2, 3, 4], dtype=np.int16),
            ),
        )
        self.add_attribute("Output", AttrRW(Int(), initial_value=5))
        self.add_attribute("CoeGain", AttrRW(Float(prec=3), initial_value=1.5))
        self.add_attribute("Setting", AttrRW(Int(), initial_value=7))
        refusing = AttrW(Int())
        refusing.set_on_put_callback(refuse_write)
        self.add_attribute("Refusing", refusing)


async def refuse_write(attribute: AttrW[Any, Any], value: Any) -> None:
    """A write the device rejects, as an ADS write error would."""
    raise RuntimeError(f"device refused {value}")


def group_of(attribute: Attribute[Any, Any]) -> str | None:
    return {"Output": OUTPUTS_GROUP, "CoeGain": COE_GROUP}.get(attribute.name)


class Ready(Transport):
    """Posts the attributes' first values and prints the ready line once
    the database serves."""

    def __init__(self, controller: Controller) -> None:
        self.controller = controller

    def connect(
        self, controller_apis: list[ControllerAPI], loop: asyncio.AbstractEventLoop
    ) -> None:
        """Nothing to connect."""

    async def serve(self) -> None:
        from fastcs_ethercat.ioc.database import initialised

        await initialised()
        attributes = self.controller.attributes.values()
        await PUBLISHER.start([a for a in attributes if isinstance(a, AttrR)])
        print("alarm ioc ready", flush=True)


async def handle(controller: AlarmTestController, line: str) -> int:
    words = line.split()
    attributes: dict[str, Attribute[Any, Any]] = controller.attributes
    match words:
        case ["alarm", name, severity, status, *message]:
            state = AlarmState(Severity[severity], Status[status], " ".join(message))
            return publish_alarm(attributes[name], state)
        case ["clear", name]:
            return clear_alarm(attributes[name])
        case ["alarm-all", severity, status]:
            started = time.perf_counter()
            reached = set_alarms(
                attributes.values(), Severity[severity], Status[status]
            )
            took = time.perf_counter() - started
            print(f"alarm-all: {reached} PVs in {took * 1e3:.1f} ms", flush=True)
            return reached
        case ["update", name, value]:
            attribute = attributes[name]
            assert isinstance(attribute, AttrR)
            return int(await PUBLISHER.publish(attribute, float(value)))
        case ["asactive"]:
            return int(_access_security_active())
    raise ValueError(f"unknown command {line!r}")


def read_commands(
    controller: AlarmTestController, loop: asyncio.AbstractEventLoop
) -> None:
    for line in sys.stdin:
        if line.strip():
            future = asyncio.run_coroutine_threadsafe(handle(controller, line), loop)
            try:
                print(f"done {line.split()[0]} {future.result(30)}", flush=True)
            except Exception as error:
                print(f"failed {line.strip()}: {error!r}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--prefix", required=True)
    parser.add_argument("--acf", type=Path)
    parser.add_argument("--read-only", action="store_true")
    parser.add_argument("--extra", type=int, default=0, help="more float AttrRs")
    arguments = parser.parse_args()

    loop = asyncio.new_event_loop()
    asyncio.set_event_loop(loop)
    controller = AlarmTestController(arguments.extra)
    controller.set_path([arguments.prefix])
    transports = [
        *build_transports(LaunchOptions()),
        AccessSecurity(arguments.acf, group_of, read_only=arguments.read_only),
        Ready(controller),
    ]
    threading.Thread(target=read_commands, args=(controller, loop), daemon=True).start()
    FastCS(controller, transports, loop).run(interactive=False)


if __name__ == "__main__":
    main()
