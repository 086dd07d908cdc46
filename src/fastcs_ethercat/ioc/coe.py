"""CoE SDO access to one slave's objects: group 0xF302 on its mailbox port.

The request goes to the master's NetId with the slave's EtherCAT address as
AMS port, offset = index << 16 | subindex (facts sections 3 and 6). Values are
packed by the CoE type name; enumerated and other vendor types (DT0800EN03)
travel as unsigned numbers of their bit size.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fastcs_ethercat.ads.constants import IndexGroup
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.values import TwinCatType, parse_type
from fastcs_ethercat.ads.wire import STRING_ENCODING
from fastcs_ethercat.ioc.clients import ClientFactory, read_text
from fastcs_ethercat.ioc.plan import CoePoint

NUMBERS = ("int", "float")


def sdo_offset(index: int, subindex: int) -> int:
    return index << 16 | subindex


def coe_size(point: CoePoint) -> int:
    """Bytes of the object on the wire (at least one)."""
    return max(1, (point.bit_size + 7) // 8)


def _known_type(point: CoePoint) -> TwinCatType | None:
    try:
        parsed = parse_type(point.type_name)
    except AdsCodecError:
        return None
    if parsed.kind == "array":  # arrays of numbers (ELM3704 diagnosis texts)
        element = parsed.element
        return parsed if element is not None and element.kind in NUMBERS else None
    return parsed if parsed.kind in ("bool", "string", *NUMBERS) else None


def is_string(point: CoePoint) -> bool:
    parsed = _known_type(point)
    return parsed is not None and parsed.kind == "string"


def decode_coe(point: CoePoint, raw: bytes) -> Any:
    """The value of an SDO answer."""
    parsed = _known_type(point)
    if parsed is not None and parsed.kind == "string":
        return raw.split(b"\0", 1)[0].decode(STRING_ENCODING, errors="replace")
    if parsed is not None and parsed.kind == "bool":
        return bool(raw[0] & 1) if raw else False
    if parsed is not None and parsed.element is not None:
        dtype = parsed.element.dtype  # a short answer gives the elements it holds
        return np.frombuffer(raw[: len(raw) - len(raw) % dtype.itemsize], dtype).copy()
    if parsed is not None and parsed.size == len(raw):
        return parsed.unpack(raw)
    value = int.from_bytes(raw, "little")
    return value & ((1 << point.bit_size) - 1) if point.bit_size else value


def encode_coe(point: CoePoint, value: Any) -> bytes:
    """The bytes to write for `value`."""
    parsed = _known_type(point)
    size = coe_size(point)
    if parsed is not None and parsed.kind == "string":
        return str(value).encode(STRING_ENCODING)
    if parsed is not None and parsed.kind == "bool":
        return b"\x01" if bool(value) else b"\x00"
    if parsed is not None and parsed.size == size:
        return parsed.pack(np.asarray(value).tolist())
    number = int(value)
    if not 0 <= number < 1 << max(point.bit_size, 1):
        raise ValueError(f"{value!r} does not fit {point.bit_size} bits")
    return number.to_bytes(size, "little")


class SlaveCoe:
    """SDO read/write of one slave (`address`) behind master `master_net_id`.

    `read` and `write` fit the controllers' CoE reader/writer callables.
    """

    def __init__(
        self, client_factory: ClientFactory, master_net_id: str, address: int
    ) -> None:
        self.client_factory = client_factory
        self.master_net_id = master_net_id
        self.address = address

    async def read(self, point: CoePoint) -> Any:
        client = await self.client_factory(self.master_net_id, self.address)
        offset = sdo_offset(point.index, point.subindex)
        if is_string(point):
            raw = await read_text(client, IndexGroup.COE_SDO, offset, coe_size(point))
        else:
            raw = await client.read(IndexGroup.COE_SDO, offset, coe_size(point))
        return decode_coe(point, raw)

    async def write(self, point: CoePoint, value: Any) -> None:
        client = await self.client_factory(self.master_net_id, self.address)
        await client.write(
            IndexGroup.COE_SDO,
            sdo_offset(point.index, point.subindex),
            encode_coe(point, value),
        )
