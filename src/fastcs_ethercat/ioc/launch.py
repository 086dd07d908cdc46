"""Start a FastCS controller tree as an EPICS IOC: CA and/or PVA, PVI.

FastCS's own `launch()` builds its controllers from a YAML schema of their
`__init__`; our tree comes from the live symbol table instead, so this module
builds the transports itself and runs `FastCS` directly:

- the database: FastCS's `EpicsCATransport` as `ioc.database` makes it
  (records that behave as EPICS records, their PVI entries, the site's
  databases, iocInit), served on CA, PVA (QSRV) or both; the callback queue
  is enlarged before iocInit, because every changed value of every record
  queues one callback and the EPICS default of 2000 overflows on a large
  rack,
- the access security rules (`ioc.access`), when there are any.

softioc can initialise only once per process, so an IOC (and every test of
one) lives in its own process. `on_built` runs once the tree is built,
before anything serves (the screens are written there: `ioc.screens`);
`on_pvs_built` once iocInit has returned; the ready line goes to stdout
then, so a parent process knows when to look for PVs (and screens).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Final

from fastcs.control_system import FastCS
from fastcs.controllers import Controller, ControllerAPI
from fastcs.transports import Transport

from fastcs_ethercat.process import ready_line

if TYPE_CHECKING:
    from fastcs_ethercat.ioc.database import SiteDatabase

DEFAULT_CALLBACK_QUEUE_SIZE: Final = 50_000
"""Entries per EPICS callback queue; the default 2000 overflows ("ring buffer
full") when a few thousand records change in one poll cycle."""


@dataclass(frozen=True)
class LaunchOptions:
    """How to serve the tree."""

    ca: bool = True
    pva: bool = True
    ca_aliases: Mapping[str, str] = field(default_factory=dict)
    """Extra record names, full PV -> alias (QSRV serves aliases on PVA too)."""
    callback_queue_size: int = DEFAULT_CALLBACK_QUEUE_SIZE
    access_security_file: Path | None = None
    """ACF loaded at iocInit; outputs get ASG OUTPUTS, CoE parameters COE."""
    read_only: bool = False
    """Outputs and CoE parameters served read-only: their records in ASG
    READ_ONLY (CA clients see "no write")."""
    site_databases: Sequence[SiteDatabase] = ()
    """A site's .db files, loaded after the IOC's own records."""
    autosave_dir: Path | None = None
    """Where the operators' settings are kept (`ioc.operator_settings`)."""

    def __post_init__(self) -> None:
        if not (self.ca or self.pva):
            raise ValueError("serve at least one of CA and PVA")


def build_transports(options: LaunchOptions, prefix: str = "ioc") -> list[Transport]:
    """The FastCS transports for `options` (imports softioc only for CA)."""
    from fastcs_ethercat.ioc.database import database_transport

    transports: list[Transport] = [
        database_transport(
            options.ca_aliases,
            options.site_databases,
            autosave_dir=options.autosave_dir,
            autosave_name=prefix,
            ca=options.ca,
            pva=options.pva,
        )
    ]
    if options.access_security_file is not None or options.read_only:
        from fastcs_ethercat.ioc.access import AccessSecurity, access_group_of

        transports.append(
            AccessSecurity(
                options.access_security_file,
                access_group_of,
                read_only=options.read_only,
            )
        )
    return transports


def build_fastcs(
    root: Controller,
    prefix: str,
    options: LaunchOptions,
    loop: asyncio.AbstractEventLoop,
    *,
    on_ready: Callable[[], object] | None = None,
    on_built: Callable[[], object] | None = None,
    on_pvs_built: Callable[[], Awaitable[object]] | None = None,
) -> FastCS:
    """A `FastCS` serving `root` under `prefix`; prints the ready line when up.

    Give the root its path before adding sub-controllers: FastCS copies a
    parent's path into a sub-controller when it is added.
    """
    if root.path and root.path != [prefix]:
        raise ValueError(f"root controller already has path {root.path}")
    if not root.path:
        root.set_path([prefix])
    from fastcs_ethercat.ioc.database import set_callback_queue_size

    set_callback_queue_size(options.callback_queue_size)
    announce = _Announce(prefix, on_ready, on_built, on_pvs_built)
    transports = [*build_transports(options, prefix), announce]
    return FastCS(root, transports, loop)


def run(
    root: Controller,
    prefix: str,
    options: LaunchOptions,
    *,
    on_ready: Callable[[], object] | None = None,
    on_built: Callable[[], object] | None = None,
    on_pvs_built: Callable[[], Awaitable[object]] | None = None,
) -> None:
    """Serve until SIGINT or SIGTERM, as this process's one IOC.

    The root's `initialise()` runs on the loop that then serves, so the ADS
    clients and the tree share it; FastCS calls the root's `disconnect()`
    when serving ends, then the loop is closed.
    """
    loop = asyncio.new_event_loop()
    asyncio.set_event_loop(loop)
    try:
        fastcs = build_fastcs(
            root,
            prefix,
            options,
            loop,
            on_ready=on_ready,
            on_built=on_built,
            on_pvs_built=on_pvs_built,
        )
        fastcs.run(interactive=False)
    finally:
        _cancel_left_tasks(loop)
        loop.close()
    # FastCS logs an exception of a transport's `serve` and returns: the
    # database's (a site database EPICS cannot load) is raised here
    from fastcs_ethercat.ioc.database import failure

    if (error := failure()) is not None:
        raise error


def _cancel_left_tasks(loop: asyncio.AbstractEventLoop) -> None:
    """Cancel what FastCS left running (its scan tasks, when serving stopped
    early) and let it end, as `asyncio.run` does."""
    left = asyncio.all_tasks(loop)
    for task in left:
        task.cancel()
    if left:
        loop.run_until_complete(asyncio.gather(*left, return_exceptions=True))


class _Announce(Transport):
    """Runs `on_built` once the tree is built, `on_pvs_built` once its PVs
    exist and prints the ready line once the real transports serve.

    FastCS connects every transport after the root's `initialise()`, then
    gathers their `serve()` in order: the database's runs iocInit
    (`ioc.database`), which starts the CA and PVA servers.
    """

    def __init__(
        self,
        prefix: str,
        on_ready: Callable[[], object] | None,
        on_built: Callable[[], object] | None = None,
        on_pvs_built: Callable[[], Awaitable[object]] | None = None,
    ) -> None:
        self.prefix = prefix
        self.on_ready = on_ready
        self.on_built = on_built
        self.on_pvs_built = on_pvs_built

    def connect(
        self, controller_apis: list[ControllerAPI], loop: asyncio.AbstractEventLoop
    ) -> None:
        """This transport serves no PVs: the tree is built, say so."""
        if self.on_built is not None:
            self.on_built()

    async def serve(self) -> None:
        from fastcs_ethercat.ioc.database import initialised

        await initialised()
        if self.on_pvs_built is not None:
            await self.on_pvs_built()
        for _ in range(3):
            await asyncio.sleep(0)
        print(ready_line("ioc", prefix=self.prefix), flush=True)  # the one print
        if self.on_ready is not None:
            self.on_ready()

    def __repr__(self) -> str:
        return "ReadyAnnouncement()"
