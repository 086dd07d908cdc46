"""`fastcs-ethercat ioc` (serve a TwinCAT target) and `fastcs-ethercat demo`.

    fastcs-ethercat ioc --config ioc/bl01.yaml [--prefix P] [--target HOST[:PORT]]
                        [--ams-net-id ID] [--poll-rate HZ] [--read-only] [--list-pvs]
    fastcs-ethercat demo [--prefix P]

Flags override the file. `--list-pvs` connects, discovers, prints every PV
(`NAME ACCESS TYPE SOURCE`, one a line, sorted) and exits; warnings go to
stderr as `warning: ...` lines.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path
from typing import Annotated, Final

import typer

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV

DEMO_CONFIG: Final = Path("ioc") / "demo.yaml"
DEMO_CHAIN: Final = Path("ioc") / "demo-chain.yaml"


def ioc_command(
    config: Annotated[
        Path, typer.Option("--config", help="IOC instance configuration (YAML).")
    ],
    prefix: Annotated[
        str | None, typer.Option("--prefix", help="PV prefix (overrides the file).")
    ] = None,
    target: Annotated[
        str | None,
        typer.Option("--target", help="TwinCAT host[:ADS TCP port]."),
    ] = None,
    ams_net_id: Annotated[
        str | None, typer.Option("--ams-net-id", help="AMS NetId of the target.")
    ] = None,
    poll_rate: Annotated[
        float | None, typer.Option("--poll-rate", help="Poll rate in Hz.")
    ] = None,
    read_only: Annotated[
        bool, typer.Option("--read-only", help="Serve every output read-only.")
    ] = False,
    acf: Annotated[
        Path | None,
        typer.Option("--acf", help="EPICS access security file (CA writes)."),
    ] = None,
    list_pvs: Annotated[
        bool,
        typer.Option("--list-pvs", help="Print every PV with type and source; exit."),
    ] = False,
) -> None:
    """Serve every terminal of a TwinCAT target as EPICS PVs (CA and PVA)."""
    from fastcs_ethercat.ioc.fastcs_adapter import check_installed

    check_installed()
    from fastcs_ethercat.ioc import app
    from fastcs_ethercat.ioc.config import load_ioc_config

    overrides = {
        "prefix": prefix,
        "target": target,
        "ams_net_id": ams_net_id,
        "poll_rate_hz": poll_rate,
        "read_only": True if read_only else None,
        "access_security_file": str(acf) if acf is not None else None,
    }
    settings = load_ioc_config(config, overrides)
    if settings.access_security_file is not None:
        from fastcs_ethercat.ioc.access import check_acf

        check_acf(settings.access_security_file)
    if list_pvs:
        entries, warnings = app.list_pvs(settings)
        for warning in warnings:
            print(f"warning: {warning}", file=sys.stderr)
        for entry in entries:
            print(entry.line())
        return
    app.serve(settings)


def demo_command(
    prefix: Annotated[str, typer.Option("--prefix", help="PV prefix.")] = "DEMO",
) -> None:
    """Run the simulator with the demo chain and an IOC against it (loopback)."""
    from fastcs_ethercat.ioc.fastcs_adapter import check_installed

    check_installed()
    from fastcs_ethercat.ioc import app
    from fastcs_ethercat.ioc.config import load_ioc_config
    from fastcs_ethercat.ioc.controllers.root import RootController
    from fastcs_ethercat.sim.process import SimProcess

    for needed in (DEMO_CONFIG, DEMO_CHAIN):
        if not needed.is_file():
            raise UserError(
                "not found; run the demo from a checkout of fastcs-ethercat",
                path=needed,
            )
    for variable, value in EPICS_LOOPBACK_ENV.items():
        os.environ.setdefault(variable, value)
    listing = Path(tempfile.gettempdir()) / f"fastcs-ethercat-{prefix}-pvs.txt"
    with SimProcess(chain=DEMO_CHAIN) as sim:
        settings = load_ioc_config(
            DEMO_CONFIG,
            {"prefix": prefix, "target": sim.pyads_ip, "ams_net_id": sim.net_id},
        )

        def ready(root: RootController) -> None:
            entries = root.pvs()
            listing.write_text("".join(entry.line() + "\n" for entry in entries))
            first = next(
                (e.name for e in entries if e.name.endswith(":AICompactCh1")),
                entries[0].name,
            )
            print(f"demo: simulator on {sim.pyads_ip} (NetId {sim.net_id})")
            print(f"demo: {len(entries)} PVs listed in {listing}")
            print(f"demo: try   caget {first}")
            print("demo: Ctrl-C to stop", flush=True)

        app.serve(settings, on_ready=ready)


if __name__ == "__main__":
    typer.run(ioc_command)
