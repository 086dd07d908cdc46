"""Where the terminals tools get ESI files: given paths, or the cached vendor zip.

`update-cache` downloads Beckhoff's `Beckhoff_EtherCAT_XML.zip` into the XDG
cache; commands run without `--esi` then read it. A network that does not
answer gives one line naming the URL and the reason.
"""

from __future__ import annotations

import os
import tempfile
import urllib.error
import urllib.request
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Final

from fastcs_ethercat.cache_dir import cache_dir
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog, build_catalog

VENDOR_ZIP_URL = (
    "https://download.beckhoff.com/download/configuration-files/io/ethercat/"
    "xml-device-description/Beckhoff_EtherCAT_XML.zip"
)
VENDOR_ZIP_NAME = "Beckhoff_EtherCAT_XML.zip"
DOWNLOAD_TIMEOUT_S = 30.0
CHUNK = 1 << 16


def esi_cache_dir() -> Path:
    """`$XDG_CACHE_HOME/fastcs-ethercat/esi` (XDG default `~/.cache`)."""
    return cache_dir("esi")


def cached_zip() -> Path:
    """Where `update-cache` puts the vendor zip."""
    return esi_cache_dir() / VENDOR_ZIP_NAME


def esi_sources(given: Sequence[Path] | None) -> list[Path]:
    """The ESI sources to read: the given ones, else the cached vendor zip."""
    if given:
        return list(given)
    zip_path = cached_zip()
    if zip_path.is_file():
        return [zip_path]
    raise UserError(
        "no ESI source: pass --esi DIR (or a Beckhoff_EtherCAT_XML.zip), "
        "or run `fastcs-ethercat terminals update-cache` first"
    )


CHECKOUT_ESI: Final = (
    Path(__file__).resolve().parents[3] / "tests" / "data" / "esi" / "beckhoff",
    Path(__file__).resolve().parents[3]
    / "tests"
    / "data"
    / "esi"
    / "EL3356-0010-fixture.xml",
)
"""The real Beckhoff ESI files a checkout ships for its tests (every shipped
type's), and the EL3356-0010 description the shipped YAML comes from."""


def checkout_default_esi() -> list[Path] | None:
    """Without `--esi`: the cached vendor zip, else in a checkout the ESI
    subset it ships (a plain clone can then add every shipped type), else
    None (`esi_sources` then says how to get one)."""
    if cached_zip().is_file():
        return [cached_zip()]
    if all(path.exists() for path in CHECKOUT_ESI):
        return list(CHECKOUT_ESI)
    return None


def open_catalog(given: Sequence[Path] | None) -> EsiCatalog:
    """The catalog of every device in the ESI sources."""
    return build_catalog(esi_sources(given))


Progress = Callable[[int, int | None], None]
"""Called with (bytes so far, total bytes if known)."""


def download_vendor_zip(
    url: str = VENDOR_ZIP_URL,
    destination: Path | None = None,
    progress: Progress | None = None,
) -> Path:
    """Download the ESI zip to `destination` (default: the cache), atomically.

    Any network or HTTP failure, or a download that is not a zip, is a
    one-line `UserError`; a previous cached zip stays in place.
    """
    target = destination or cached_zip()
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temp_name = tempfile.mkstemp(dir=target.parent, prefix=".download-")
    temp = Path(temp_name)
    try:
        with os.fdopen(handle, "wb") as out:
            _fetch(url, out.write, progress)
        if not zipfile.is_zipfile(temp):
            raise UserError(f"downloaded file is not a zip archive: {url}")
        temp.replace(target)
    finally:
        temp.unlink(missing_ok=True)
    return target


def _fetch(
    url: str, write: Callable[[bytes], object], progress: Progress | None
) -> None:
    try:
        with urllib.request.urlopen(url, timeout=DOWNLOAD_TIMEOUT_S) as response:
            length = response.headers.get("Content-Length")
            total = int(length) if length and length.isdigit() else None
            done = 0
            while chunk := response.read(CHUNK):
                write(chunk)
                done += len(chunk)
                if progress is not None:
                    progress(done, total)
    except urllib.error.HTTPError as error:
        raise UserError(
            f"cannot download {url}: HTTP {error.code} {error.reason}"
        ) from None
    except urllib.error.URLError as error:
        raise UserError(f"cannot download {url}: {error.reason}") from None
    except (OSError, ValueError) as error:
        raise UserError(f"cannot download {url}: {error}") from None
