"""The files of an init DIR, and how they reach it: all at once or not at all.

    DIR/ioc.yaml             the IOC's configuration (commented; yours once written)
    DIR/ioc.schema.json      its JSON schema, for editors
    DIR/chain.yaml           the rack (boot without the PLC; `sim --chain`)
    DIR/terminals/*.yaml     one YAML per terminal type and revision
    DIR/screens/*.bob        Phoebus screens
    DIR/pvlists/             archiver.json, autosave.req
    DIR/instance/NAME/       a services-repo instance: values.yaml, config/

Everything is written into a folder beside DIR (`staging`: DIR's files
copied in first), which then takes DIR's place; on any error the folder is
removed and DIR is as it was. `differences` lists what a run would change
(`init --check`).
"""

from __future__ import annotations

import contextlib
import filecmp
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from fastcs_ethercat import __version__
from fastcs_ethercat.errors import UserError

IOC_FILE: Final = "ioc.yaml"
SCHEMA_FILE: Final = "ioc.schema.json"
CHAIN_FILE: Final = "chain.yaml"
TERMINALS_DIR: Final = "terminals"
SCREENS_DIR: Final = "screens"
PV_LISTS_DIR: Final = "pvlists"
INSTANCE_DIR: Final = "instance"
VALUES_FILE: Final = "values.yaml"
CONFIG_DIR: Final = "config"
IMAGE: Final = "ghcr.io/example-org/fastcs-ethercat"
"""The image the instance runs (`deploy/build-image.sh` builds it); the
values name it for the engineer to change to their registry's."""
ROUTE_SECRET_DIR: Final = "/run/secrets/twincat-route"


@dataclass(frozen=True, slots=True)
class Settings:
    """What the command line says about the IOC of DIR."""

    prefix: str
    target: str
    ams_net_id: str | None = None
    route_user: str | None = None
    password_env: str | None = None


def check_out_dir(out: Path) -> None:
    """DIR may be missing or a directory, nothing else."""
    if out.exists() and not out.is_dir():
        raise UserError("exists and is not a directory: give a directory with --out",
                        path=out)  # fmt: skip


@contextlib.contextmanager
def staging(out: Path) -> Iterator[Path]:
    """A folder beside `out` holding a copy of it; removed unless `commit`
    moved it into place."""
    parent = out.parent
    made = [folder for folder in (parent, *parent.parents) if not folder.exists()]
    try:
        parent.mkdir(parents=True, exist_ok=True)
        folder = Path(tempfile.mkdtemp(prefix=f".{out.name}.init-", dir=parent))
    except OSError as error:
        raise UserError(f"cannot write beside it: {error.strerror or error}",
                        path=out) from None  # fmt: skip
    try:
        if out.is_dir():
            shutil.copytree(out, folder, symlinks=True, dirs_exist_ok=True)
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        for created in made:  # deepest first; only while still empty
            with contextlib.suppress(OSError):
                created.rmdir()


def commit(folder: Path, out: Path) -> None:
    """Put the staged `folder` in `out`'s place (the old DIR removed after)."""
    old: Path | None = None
    try:
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
            os.replace(out, old / out.name)
        os.replace(folder, out)
    except OSError as error:
        if old is not None and not out.exists():
            os.replace(old / out.name, out)
        raise UserError(f"cannot move into place: {error.strerror or error}",
                        path=out) from None  # fmt: skip
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def differences(before: Path, after: Path) -> list[str]:
    """`added/removed/changed: PATH` for every file that differs."""
    old = _files(before) if before.is_dir() else set()
    new = _files(after)
    found = [f"added: {path}" for path in sorted(new - old)]
    found += [f"removed: {path}" for path in sorted(old - new)]
    found += [
        f"changed: {path}"
        for path in sorted(old & new)
        if not filecmp.cmp(before / path, after / path, shallow=False)
    ]
    return found


def _files(folder: Path) -> set[str]:
    return {
        path.relative_to(folder).as_posix()
        for path in folder.rglob("*")
        if path.is_file()
    }


def write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


def write_new(path: Path, text: str) -> bool:
    """Write `text` unless `path` exists (it is the engineer's); True if written."""
    if path.exists():
        return False
    write_text(path, text)
    return True


def instance_name(prefix: str) -> str:
    """The services-repo folder of an IOC: its prefix in lower case."""
    return prefix.lower().replace(":", "-")


def ioc_yaml(settings: Settings) -> str:
    """DIR/ioc.yaml: every choice init made, commented."""
    return _config_text(
        settings,
        intro=(
            f"# {settings.prefix}: every EtherCAT terminal of {settings.target} as\n"
            "# EPICS PVs (CA and PVA), as `fastcs-ethercat init` found the rack.\n"
            "# Yours to edit: `init` again keeps this file and updates chain.yaml,\n"
            "# terminals/ (your choices and comments kept), screens/ and pvlists/.\n"
            "#\n"
            "#   fastcs-ethercat ioc --config ioc.yaml\n"
            "#   fastcs-ethercat ioc --config ioc.yaml --list-pvs   # names only\n"
            "#\n"
            "# Relative paths are relative to this file.\n"
        ),
        password_file=None,
        screens=SCREENS_DIR,
        pv_lists=PV_LISTS_DIR,
    )


def instance_ioc_yaml(settings: Settings) -> str:
    """The instance's config/ioc.yaml, as the container mounts it."""
    return _config_text(
        settings,
        intro=(
            f"# {settings.prefix} for the epics-containers ioc-instance chart: the\n"
            "# chart mounts this folder at /epics/ioc/config (read-only) and the\n"
            "# image runs `fastcs-ethercat ioc --config /epics/ioc/config/ioc.yaml`.\n"
            "# Written by `fastcs-ethercat init`; terminals/ and chain.yaml are\n"
            "# copies of the init folder's (`init` again refreshes them).\n"
        ),
        password_file=f"{ROUTE_SECRET_DIR}/password",
        screens="/epics/opi",
        pv_lists=None,
    )


def _config_text(
    settings: Settings,
    *,
    intro: str,
    password_file: str | None,
    screens: str,
    pv_lists: str | None,
) -> str:
    lines = [f"# yaml-language-server: $schema={SCHEMA_FILE}", intro.rstrip("\n")]
    lines += [
        "",
        "# PV prefix: every PV is <prefix>:<master>:<coupler>:<terminal>[:<channel>]:",
        "# <name>, at most 60 characters (with _RBV).",
        f"prefix: {_quoted(settings.prefix)}",
        "",
        "# The TwinCAT PC: host or host:port (ADS over TCP, default port 48898).",
        f"target: {_quoted(settings.target)}",
        "",
    ]
    if settings.ams_net_id is not None:
        lines += [
            "# AMS NetId of the TwinCAT PC.",
            f"ams_net_id: {settings.ams_net_id}",
        ]
    else:
        lines += [
            "# AMS NetId of the TwinCAT PC: asked of the PC itself (UDP 48899).",
            "# ams_net_id: 192.0.2.50.1.1",
        ]
    lines += ["", *_route_lines(settings, password_file), ""]
    lines += [
        "# Sum-read rate of every master (Hz).",
        "poll_rate_hz: 10",
        "",
        "# One YAML per terminal type and revision on the rack (init wrote them;",
        "# `fastcs-ethercat terminals edit terminals` changes what they serve).",
        "terminal_dirs:",
        f"  - {TERMINALS_DIR}",
        "",
        "# The rack as init found it: served (every PV INVALID) while the PC does",
        "# not answer at start; `fastcs-ethercat sim --chain chain.yaml` plays it",
        f"# (its `terminal_dirs: [{TERMINALS_DIR}]` names the YAML it is played from).",
        f"chain: {CHAIN_FILE}",
        "",
        "# Phoebus screens, written at every start.",
        f"screens_dir: {screens}",
    ]
    if pv_lists is not None:
        lines += [
            "",
            "# The Archiver Appliance list and the autosave request, at every start.",
            f"pv_lists_dir: {pv_lists}",
        ]
    return "\n".join(lines) + "\n"


def _route_lines(settings: Settings, password_file: str | None) -> list[str]:
    if settings.route_user is None:
        return [
            "# Add a route for this host on the PC before connecting (the password",
            "# is never written here: an environment variable or a file holds it).",
            "# route:",
            "#   user: Administrator",
            "#   password_env: TWINCAT_PASSWORD",
        ]
    source = (
        f"  password_file: {password_file}"
        if password_file is not None
        else f"  password_env: {settings.password_env}"
    )
    return [
        "# Add a route for this host on the PC before connecting (the password",
        "# is never written here).",
        "route:",
        f"  user: {_quoted(settings.route_user)}",
        source,
    ]


def _quoted(text: str) -> str:
    """A YAML scalar that stays text (a host like `10.0.0.1:48898` too)."""
    plain = text.replace("-", "").replace(".", "").replace("_", "")
    return text if plain.isalnum() and not text[0].isdigit() else json.dumps(text)


def values_yaml(settings: Settings) -> str:
    """The instance's values.yaml for the ioc-instance chart."""
    name = instance_name(settings.prefix)
    lines = [
        f"# {settings.prefix} for the epics-containers ioc-instance chart: the",
        "# fastcs-ethercat image serving the rack of config/ioc.yaml (mounted at",
        "# /epics/ioc/config by the chart). Written by `fastcs-ethercat init`.",
        "ioc-instance:",
        f"  image: {IMAGE}:{__version__}",
        "",
        "  # The IOC under stdio-socket: `console` (or `ec attach`) reaches it.",
        "  command:",
        "    - stdio-socket",
        "  args:",
        "    - --ptty",
        "    - fastcs-ethercat ioc --config /epics/ioc/config/ioc.yaml"
        " --log-level info",
        "",
        "  # CA and PVA to the beamline network, and the IOC's own AMS NetId (the",
        "  # node's IP + .1.1) on the PC's route table.",
        "  hostNetwork: true",
        "",
        "  # Measure your own rack and set these (a 100-terminal rack: ~350 MB).",
        "  resources:",
        "    requests:",
        "      cpu: 100m",
        "      memory: 384Mi",
        "    limits:",
        "      cpu: 1500m",
        "      memory: 768Mi",
        "",
        "  securityContext:",
        "    allowPrivilegeEscalation: false",
    ]
    if settings.route_user is not None:
        lines += [
            "",
            "  # The TwinCAT route password, from a Secret created beside the chart:",
            f"  #   kubectl create secret generic {name}-route \\",
            "  #     --from-file=password=./twincat-password.txt",
            "  volumes:",
            "    - name: twincat-route",
            "      secret:",
            f"        secretName: {name}-route",
            "        defaultMode: 0400",
            "  volumeMounts:",
            "    - name: twincat-route",
            f"      mountPath: {ROUTE_SECRET_DIR}",
            "      readOnly: true",
        ]
    return "\n".join(lines) + "\n"
