"""What the demo tells a first-time user once it serves.

The lines must work when pasted into another shell as they are: the EPICS
variables that keep the client on loopback and on the demo's ports come
first, then the client from this venv (the `tools` extra installs it).
Text PVs are arrays of characters on CA, which plain `caget` prints as
numbers, so the text example uses `caget -S`.
"""

from __future__ import annotations

import getpass
import os
import shlex
import shutil
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from fastcs_ethercat.cli.ports import CA_SERVER_PORT, PVA_SERVER_PORT, DemoPorts
from fastcs_ethercat.loopback import LOOPBACK

NUMBER_PV_SUFFIX: Final = ":MOD5:CH1:Value"
"""The demo's first EL3104 (`Term 5`): a sine."""
CHANNEL_VALUE: Final = ":CH1:Value"
TEXT_PV_SUFFIX: Final = ":AlStateText"
TOOLS_EXTRA: Final = "pip install 'fastcs-ethercat[tools]'"


@dataclass(frozen=True)
class DemoHints:
    """The demo's ports and PV names: enough to say how to read one."""

    ports: DemoPorts
    names: Sequence[str]

    def port_lines(self) -> list[str]:
        if not self.ports.moved:
            return []
        return [
            f"demo: port {CA_SERVER_PORT} (CA) or {PVA_SERVER_PORT} (PVA) is taken "
            f"on this host (another IOC?): serving CA on {self.ports.ca}, PVA on "
            f"{self.ports.pva} (search port {self.ports.pva_broadcast}); the lines "
            "below carry these ports"
        ]

    def try_lines(self) -> list[str]:
        number = self._first(NUMBER_PV_SUFFIX)
        same_terminal = number.removesuffix(CHANNEL_VALUE) + TEXT_PV_SUFFIX
        text = (
            same_terminal
            if same_terminal in self.names
            else self._first(TEXT_PV_SUFFIX)
        )
        ca = self._ca_env()
        pva = self._pva_env()
        lines = [
            "demo: read a value from another shell:",
            f"demo: try   {_command(ca, 'caget', number)}",
            f"demo: try   {_command(pva, 'pvget', number)}",
            f"demo: text  {_command(ca, 'caget', '-S', text)}",
        ]
        if _tool("caget") == "caget" and shutil.which("caget") is None:
            lines.append(f"demo: no caget found: `{TOOLS_EXTRA}` installs it")
        return lines

    def _first(self, suffix: str) -> str:
        return next((n for n in self.names if n.endswith(suffix)), self.names[0])

    def _ca_env(self) -> dict[str, str]:
        return {
            "EPICS_CA_AUTO_ADDR_LIST": "NO",
            "EPICS_CA_ADDR_LIST": LOOPBACK,
            "EPICS_CA_SERVER_PORT": str(self.ports.ca),
        }

    def _pva_env(self) -> dict[str, str]:
        return {
            "EPICS_PVA_AUTO_ADDR_LIST": "NO",
            "EPICS_PVA_ADDR_LIST": LOOPBACK,
            "EPICS_PVA_BROADCAST_PORT": str(self.ports.pva_broadcast),
        }


IMAGE_VARIABLE: Final = "FASTCS_ETHERCAT_IMAGE"
"""Set in the image: its paths mean nothing to the host's shell, where the
lines are pasted, so they name the tools bare."""


def _tool(name: str) -> str:
    """The venv's own copy of an EPICS tool if it has one, else the bare name."""
    beside = Path(sys.executable).parent / name
    in_image = bool(os.environ.get(IMAGE_VARIABLE))
    return str(beside) if beside.is_file() and not in_image else name


def _command(env: dict[str, str], tool: str, *args: str) -> str:
    words = [f"{key}={value}" for key, value in env.items()]
    return shlex.join([*words, _tool(tool), *args])


def pv_list_dir() -> Path:
    """A folder of this user's in the temp folder (mode 0700, ours alone)."""
    user = f"{getpass.getuser()}-{os.getuid()}"
    folder = Path(tempfile.gettempdir()) / f"fastcs-ethercat-{user}"
    folder.mkdir(mode=0o700, exist_ok=True)
    info = folder.lstat()
    if folder.is_symlink() or info.st_uid != os.getuid():
        raise PermissionError(f"{folder} is not this user's own folder")
    return folder


def write_pv_list(prefix: str, lines: Sequence[str]) -> str:
    """Write the PV list; the demo line saying where, or why not (never fatal)."""
    try:
        path = pv_list_dir() / f"{prefix}-pvs.txt"
        path.write_text("".join(line + "\n" for line in lines), encoding="utf-8")
    except OSError as error:
        return (
            f"demo: {len(lines)} PVs (could not write their list: {error}; "
            "`fastcs-ethercat ioc --config FILE --list-pvs` prints it)"
        )
    return f"demo: {len(lines)} PVs listed in {path}"
