"""EPICS access security (an ACF file) for the IOC's records, on CA and PVA.

A site restricts who may write by an ACF file: `load_access_security(path)`
checks it and hands it to EPICS, which reads it at iocInit. Records belong to
the access security group (ASG) DEFAULT unless their ASG field names another;
`assign_access_group` sets that field on the out records FastCS made for
given attributes, which must happen after the database transport connected
(the records exist) and before it serves (the database is loaded): in
between runs `AccessSecurity.connect`, a transport to list after that one.

Two ways to use it (see ioc/access-example.acf):
- without ASGs on records, an ACF whose DEFAULT group allows WRITE only to
  some users/hosts restricts every write;
- with `group_of` naming OUTPUTS/COE for output and CoE attributes, only those
  records are restricted and DEFAULT may stay open.

`--read-only` (`AccessSecurity(read_only=True)`) adds an ASG READ_ONLY without
write rules to the site's ACF (or to an open one) and puts the records of every
output and CoE parameter in it (served as plain read records then), so CA
clients see each as read-only ("read, no write") and cannot write it.

PV Access is served from the same records by QSRV, which asks EPICS access
security for every put as the CA server does: one ACF governs both.
"""

from __future__ import annotations

import asyncio
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, Final

from fastcs.attributes import Attribute
from fastcs.controllers import ControllerAPI
from fastcs.transports import Transport

from fastcs_ethercat.bounded import MAX_ACF_BYTES, read_text_bounded
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.dbaccess import is_serving, set_access_security_file
from fastcs_ethercat.ioc.fastcs_adapter import database_records

OUTPUTS_GROUP: Final = "OUTPUTS"
"""ASG for output PVs (process data the IOC writes to terminals)."""
COE_GROUP: Final = "COE"
"""ASG for CoE parameter PVs."""
READ_ONLY_GROUP: Final = "READ_ONLY"
"""ASG that `--read-only` puts every CA out record in: nobody may write."""
_READ_ONLY_RULES: Final = f"""
# Added by fastcs-ethercat for --read-only: every output record is in here.
ASG({READ_ONLY_GROUP}) {{
    RULE(1, READ)
}}
"""
_OPEN_DEFAULT: Final = """ASG(DEFAULT) {
    RULE(1, READ)
    RULE(1, WRITE)
}
"""

_CHECK_SCRIPT: Final = """
import ctypes, sys
from epicscorelibs.ioc import Com
Com.asInitFile.argtypes = (ctypes.c_char_p, ctypes.c_char_p)
Com.asInitFile.restype = ctypes.c_long
sys.exit(0 if Com.asInitFile(sys.argv[1].encode(), None) == 0 else 1)
"""
_ANSI: Final = re.compile(r"\x1b\[[0-9;]*m")
_AT_LINE: Final = re.compile(r"\s*at line (\d+):?")


def check_acf(path: Path) -> None:
    """Parse `path` with EPICS's own ACF parser (in a child process, so this
    process's access security stays untouched); `UserError` on any complaint.

    EPICS skips rules with unknown keywords with only a warning; here that is
    an error too, as a mistyped WRITE would silently deny every write.
    """
    if not path.is_file():
        raise UserError("access security file not found", path=path)
    read_acf(path)  # bounded before EPICS's parser reads it whole
    done = subprocess.run(
        [sys.executable, "-c", _CHECK_SCRIPT, str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    complaint = _ANSI.sub("", done.stdout + done.stderr).strip()
    if done.returncode != 0 or complaint:
        raise _acf_error(path, complaint or "EPICS rejected the file")


def read_acf(path: Path) -> str:
    """The text of an ACF, read bounded (`bounded.MAX_ACF_BYTES`)."""
    return read_text_bounded(path, MAX_ACF_BYTES, what="access security file")


def groups_left_to_default(text: str) -> list[str]:
    """What an ACF leaves to DEFAULT's rules of what the IOC puts in groups:
    "outputs (ASG OUTPUTS)" when it has no ASG(OUTPUTS), likewise COE.
    EPICS puts a record whose ASG the file lacks in DEFAULT, silently."""
    code = "\n".join(line.split("#", 1)[0] for line in text.splitlines())
    left = []
    for group, what in ((OUTPUTS_GROUP, "outputs"), (COE_GROUP, "CoE parameters")):
        if not re.search(rf"\bASG\s*\(\s*{group}\s*\)", code):
            left.append(f"{what} (ASG {group})")
    return left


def _acf_error(path: Path, complaint: str) -> UserError:
    words = " ".join(complaint.split())
    for prefix in ("ERROR ", "WARNING "):
        words = words.replace(prefix, "")
    line = _AT_LINE.search(words)
    where = f"line {line.group(1)}" if line else None
    message = _AT_LINE.sub("", words, count=1).strip() or words
    return UserError(message, path=path, where=where)


def load_access_security(path: Path) -> None:
    """Check `path` and make iocInit load it; call before the CA transport serves."""
    if is_serving():
        raise RuntimeError("access security must be loaded before iocInit")
    check_acf(path)
    if not set_access_security_file(str(path.resolve())):
        raise UserError("EPICS did not accept the access security file", path=path)


def assign_access_group(
    attributes: Iterable[Attribute[Any, Any]], group: str, *, reads: bool = False
) -> list[str]:
    """Set ASG=`group` on the CA out records of `attributes` (and their in
    records too if `reads`); the records' names.

    Only between the CA transport's connect and serve (see module docstring).
    """
    if is_serving():
        raise RuntimeError("ASG fields must be set before the CA database loads")
    names = []
    for attribute in attributes:
        for record in database_records(attribute, reads=reads):
            record.ASG = group
            names.append(record.name)
    return names


def read_only_acf(site_acf: Path | None, directory: Path) -> Path:
    """An ACF in `directory`: the site's (or an open DEFAULT) plus READ_ONLY.

    CA clients then see every output as read-only (cainfo: "read, no write";
    Phoebus draws it so), which is how `--read-only` shows on the PVs.
    """
    if site_acf is not None and not site_acf.is_file():
        raise UserError("access security file not found", path=site_acf)
    text = read_acf(site_acf) if site_acf else _OPEN_DEFAULT
    if re.search(rf"\bASG\(\s*{READ_ONLY_GROUP}\s*\)", text):
        raise UserError(f"ASG {READ_ONLY_GROUP} is reserved", path=site_acf)
    path = directory / "read-only.acf"
    path.write_text(text + _READ_ONLY_RULES, encoding="utf-8")
    return path


class AccessSecurity(Transport):
    """Loads an ACF and assigns ASGs; list it after the CA transport.

    FastCS connects every transport before any serves, so `connect` runs with
    the CA records built and the database not yet loaded. It serves no PVs.
    `group_of` names the ASG of an attribute, or None to leave it in DEFAULT.
    `read_only` puts every out record in READ_ONLY instead (the ACF used is
    `read_only_acf(acf, ...)`, written to a temporary directory).
    """

    def __init__(
        self,
        acf: Path | None,
        group_of: Callable[[Attribute[Any, Any]], str | None] | None = None,
        *,
        read_only: bool = False,
    ) -> None:
        self.acf = acf
        self.group_of = group_of
        self.read_only = read_only
        self.assigned: dict[str, str] = {}
        """Record name -> ASG, for logs and tests."""
        self._scratch: Path | None = None

    def connect(
        self, controller_apis: list[ControllerAPI], loop: asyncio.AbstractEventLoop
    ) -> None:
        group_of = self.group_of
        acf = self.acf
        if self.read_only:
            self._scratch = Path(tempfile.mkdtemp(prefix="fastcs-ethercat-acf-"))
            acf = read_only_acf(acf, self._scratch)
            group_of = _read_only_group_of
        if acf is not None:
            from fastcs_ethercat.ioc.audit import trapwrite_acf

            if self._scratch is None:
                self._scratch = Path(tempfile.mkdtemp(prefix="fastcs-ethercat-acf-"))
            load_access_security(trapwrite_acf(acf, self._scratch))  # audited
        if group_of is None:
            return
        for root in controller_apis:
            for api in root.walk_api():
                for attribute in api.attributes.values():
                    group = group_of(attribute)
                    if group is None:
                        continue
                    reads = group == READ_ONLY_GROUP  # read-only: in records
                    for name in assign_access_group([attribute], group, reads=reads):
                        self.assigned[name] = group

    async def serve(self) -> None:
        """Nothing to serve: EPICS enforces the rules from iocInit on.

        Once the CA transport, listed before, has run iocInit, the ACF
        written for it (TRAPWRITE added: `ioc.audit`) has been read and can go.
        """
        from fastcs_ethercat.ioc.database import initialised

        await initialised()
        if self._scratch is not None:
            shutil.rmtree(self._scratch, ignore_errors=True)
            self._scratch = None

    def __repr__(self) -> str:
        return f"AccessSecurity(acf={self.acf})"


def access_group_of(attribute: Attribute[Any, Any]) -> str | None:
    """The ASG of one of our attributes: outputs and CoE parameters are the
    writes a site restricts; everything else stays in DEFAULT."""
    from fastcs.attributes.attr_w import AttrW

    from fastcs_ethercat.ioc.attributes import CoeRef, PointRef

    if not isinstance(attribute, AttrW):
        return None
    if isinstance(attribute.io_ref, CoeRef):
        return COE_GROUP
    if isinstance(attribute.io_ref, PointRef):
        return OUTPUTS_GROUP
    return None


def _read_only_group_of(attribute: Attribute[Any, Any]) -> str | None:
    """READ_ONLY for whatever a client could write, and for outputs and CoE
    items that `--read-only` serves as plain reads."""
    from fastcs.attributes.attr_w import AttrW

    from fastcs_ethercat.ioc.attributes import CoeRef, PointRef

    if isinstance(attribute, AttrW):
        return READ_ONLY_GROUP
    ref = attribute.io_ref if attribute.has_io_ref() else None
    writable = (isinstance(ref, PointRef) and ref.point.writable) or (
        isinstance(ref, CoeRef) and ref.coe.writable
    )
    return READ_ONLY_GROUP if writable else None
