"""The ADS services of each simulated AMS port.

| port | on | serves |
|---|---|---|
| 300 | system NetId | I/O server: device list, names, NetIds, types (group 0x5000) |
| 10000 | system NetId | system service: ReadState, WriteControl RUN / STOP |
| 27904 + n | system NetId | device n: symbols, handles, images, sum commands |
| 0xFFFF | device NetId | EtherCAT master queries, the master's CoE |
| slave address | device NetId | the slave's CoE dictionary (0xF302) |

Every port answers ReadState (RUN 5, or STOP 6 while the runtime is
stopped) and ReadDeviceInfo. Unknown index groups answer 0x702, services a
port does not offer 0x701, short read buffers 0x705. A read longer than a
table or string gets the bytes there are (facts section 9).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, TypeVar

import numpy as np
import numpy.typing as npt

from fastcs_ethercat.ads.commands import ReadDeviceInfoResponse
from fastcs_ethercat.ads.constants import (
    IO_DEVICE_TYPE_ETHERCAT,
    AdsReturnCode,
    AdsState,
    IndexGroup,
    IoServerDeviceOffset,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.ethercat import (
    encode_device_count,
    encode_device_ids,
    encode_device_name,
    encode_device_netid,
    encode_device_type,
)
from fastcs_ethercat.ads.sums import (
    SumReadItem,
    SumReadLayout,
    SumReadRequest,
    SumReadResponse,
    SumReadWriteRequest,
    SumReadWriteResponse,
    SumWriteRequest,
    SumWriteResponse,
)
from fastcs_ethercat.ads.wire import decode_text
from fastcs_ethercat.twincat.answers import Outcome, fit
from fastcs_ethercat.twincat.device import SimDevice
from fastcs_ethercat.twincat.image import read_bits, read_slice
from fastcs_ethercat.twincat.itemfaults import item_error
from fastcs_ethercat.twincat.layout import AREAS, INPUTS, OUTPUTS, ImageArea
from fastcs_ethercat.twincat.master import SlaveRuntime
from fastcs_ethercat.twincat.symtab import Resolved

VERSION: Final = (3, 1, 2103)
"""Version and build the I/O server reports (catio's dumps of real racks)."""
IO_SERVER_NAME: Final = "I/O Server"
SYSTEM_SERVICE_NAME: Final = "TwinCAT System"
DEVICE_PORT_NAME: Final = "EtherCAT Device"
MASTER_PORT_NAME: Final = "EtherCAT Master"

_SUM_GROUPS: Final = frozenset(
    {
        IndexGroup.SUMUP_READ,
        IndexGroup.SUMUP_WRITE,
        IndexGroup.SUMUP_READ_WRITE,
        IndexGroup.SUMUP_READ_EX,
        IndexGroup.SUMUP_READ_EX_2,
        IndexGroup.SUMUP_ADD_DEVICE_NOTIFICATION,
        IndexGroup.SUMUP_DELETE_DEVICE_NOTIFICATION,
    }
)
_U32: Final = struct.Struct("<I")

_Sum = TypeVar("_Sum", SumReadRequest, SumWriteRequest, SumReadWriteRequest)


@dataclass(slots=True)
class RunState:
    """Shared by every port: is the runtime running."""

    running: bool = True

    @property
    def ads_state(self) -> int:
        return int(AdsState.RUN if self.running else AdsState.STOP)


def request_name(data: bytes) -> str:
    """A symbol name as clients send it (NUL-terminated or not)."""
    return decode_text(data.split(b"\0", 1)[0]).strip()


@dataclass(slots=True)
class Port:
    """Defaults every AMS port shares."""

    run: RunState
    name: str = ""

    def device_info(self) -> ReadDeviceInfoResponse:
        major, minor, build = VERSION
        return ReadDeviceInfoResponse(
            major=major, minor=minor, build=build, name=self.name[:16]
        )

    def read_state(self) -> tuple[int, int]:
        return self.run.ads_state, 0

    def write_control(self, ads_state: int, device_state: int, data: bytes) -> int:
        return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED

    def read(self, group: int, offset: int, length: int) -> Outcome:
        return AdsReturnCode.DEVICE_INVALID_GROUP, b""

    def write(self, group: int, offset: int, data: bytes) -> int:
        return AdsReturnCode.DEVICE_INVALID_GROUP

    def read_write(self, group: int, offset: int, length: int, data: bytes) -> Outcome:
        return AdsReturnCode.DEVICE_INVALID_GROUP, b""


@dataclass(slots=True)
class SystemServicePort(Port):
    """Port 10000: the TwinCAT system's state; WriteControl starts/stops it."""

    def write_control(self, ads_state: int, device_state: int, data: bytes) -> int:
        if ads_state in (AdsState.RUN, AdsState.RESET):
            self.run.running = True
        elif ads_state in (AdsState.STOP, AdsState.CONFIG, AdsState.RECONFIG):
            self.run.running = False
        else:
            return AdsReturnCode.DEVICE_INVALID_DATA
        return AdsReturnCode.NO_ERROR


@dataclass(slots=True)
class IoServerPort(Port):
    """Port 300: the list of I/O devices (facts section 6, catio)."""

    devices: list[SimDevice] = field(default_factory=list)

    def read(self, group: int, offset: int, length: int) -> Outcome:
        base = IndexGroup.IO_SERVER_DEVICES
        if group == base:
            if offset == IoServerDeviceOffset.DEVICE_COUNT:
                return fit(encode_device_count(len(self.devices)), length)
            if offset == IoServerDeviceOffset.DEVICE_IDS:
                return fit(
                    encode_device_ids([d.device_id for d in self.devices]), length
                )
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        device = next((d for d in self.devices if group == base + d.device_id), None)
        if device is None:
            return AdsReturnCode.DEVICE_INVALID_GROUP, b""
        if offset == IoServerDeviceOffset.DEVICE_IDS:
            return fit(encode_device_name(device.name), length)
        if offset == IoServerDeviceOffset.DEVICE_NETID:
            return fit(encode_device_netid(device.master.net_id), length)
        if offset == IoServerDeviceOffset.DEVICE_TYPE:
            return fit(encode_device_type(IO_DEVICE_TYPE_ETHERCAT), length)
        return AdsReturnCode.DEVICE_INVALID_OFFSET, b""

    def write(self, group: int, offset: int, data: bytes) -> int:
        if self.read(group, offset, 0xFFFF)[0] == AdsReturnCode.DEVICE_INVALID_GROUP:
            return AdsReturnCode.DEVICE_INVALID_GROUP
        return AdsReturnCode.DEVICE_INVALID_ACCESS


@dataclass(slots=True)
class DevicePort(Port):
    """Port 27904 + n: the device's symbols, handles and process images."""

    device: SimDevice | None = None
    plans: SumReadPlans = field(
        default_factory=lambda: SumReadPlans(), repr=False, compare=False
    )

    @property
    def dev(self) -> SimDevice:
        assert self.device is not None
        return self.device

    def _area(self, group: int) -> tuple[ImageArea, bool] | None:
        for area in AREAS:
            if group == area.byte_group:
                return area, False
            if group == area.bit_group:
                return area, True
        return None

    def read(self, group: int, offset: int, length: int) -> Outcome:
        dev = self.dev
        table = dev.table
        match group:
            case IndexGroup.SYM_UPLOAD_INFO:
                return fit(table.upload_info, length)
            case IndexGroup.SYM_UPLOAD_INFO_2:
                if not dev.system.upload_info_2:  # older TwinCAT
                    return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
                return fit(table.upload_info2, length)
            case IndexGroup.SYM_UPLOAD:
                return fit(table.upload, length)
            case IndexGroup.SYM_DT_UPLOAD:
                return fit(table.data_types, length)
            case IndexGroup.SYM_VERSION:
                if not dev.system.symbol_version_on_device_port:
                    return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
                return fit(bytes([dev.version]), length)
            case IndexGroup.SYM_VALUE_BY_HANDLE:
                result, found = dev.handle(offset)
                if found is None:
                    return result, b""
                return dev.read_resolved(found, length)
        place = self._area(group)
        if place is not None:
            area, bits = place
            if code := item_error(dev.failing(), group, offset, length):
                return code, b""
            if bits:
                return dev.image.read_bit_bytes(area, offset, length)
            return dev.image.read_bytes(area, offset, length)
        for area in AREAS:
            if group == area.size_group:
                return fit(_U32.pack(dev.layout.size_of(area)), length)
        if group in _WRITE_ONLY_GROUPS or group in _NAME_GROUPS:
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
        return AdsReturnCode.DEVICE_INVALID_GROUP, b""

    def write(self, group: int, offset: int, data: bytes) -> int:
        dev = self.dev
        match group:
            case IndexGroup.SYM_VALUE_BY_HANDLE:
                result, found = dev.handle(offset)
                if found is None:
                    return result
                return dev.write_resolved(found, data)
            case IndexGroup.SYM_RELEASE_HANDLE:
                if len(data) != 4:
                    return AdsReturnCode.DEVICE_INVALID_SIZE
                self.plans.plans.clear()  # plans may read by that handle
                return dev.release_handle(_U32.unpack(data)[0])
            case IndexGroup.IO_IMAGE_CLEAR_INPUTS | IndexGroup.IO_IMAGE_CLEAR_OUTPUTS:
                area = (
                    AREAS[1] if group == IndexGroup.IO_IMAGE_CLEAR_INPUTS else AREAS[0]
                )
                buffer = dev.image.buffer(area)
                buffer[:] = bytes(len(buffer))
                return AdsReturnCode.NO_ERROR
        place = self._area(group)
        if place is not None:
            area, bits = place
            if bits:
                return dev.image.write_bit_bytes(area, offset, data)
            return dev.image.write_bytes(area, offset, data)
        if group in _READ_ONLY_GROUPS or any(group == a.size_group for a in AREAS):
            return AdsReturnCode.DEVICE_INVALID_ACCESS
        if group in _NAME_GROUPS:
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
        return AdsReturnCode.DEVICE_INVALID_GROUP

    def read_write(self, group: int, offset: int, length: int, data: bytes) -> Outcome:
        dev = self.dev
        match group:
            case IndexGroup.SYM_HANDLE_BY_NAME:
                found = dev.resolve(request_name(data))
                if found is None:
                    return AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND, b""
                if length < 4:
                    return AdsReturnCode.DEVICE_INVALID_SIZE, b""
                return AdsReturnCode.NO_ERROR, _U32.pack(dev.new_handle(found))
            case IndexGroup.SYM_VALUE_BY_NAME:
                found = dev.resolve(request_name(data))
                if found is None:
                    return AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND, b""
                return dev.read_resolved(found, length)
            case IndexGroup.SYM_INFO_BY_NAME_EX:
                found = dev.resolve(request_name(data))
                if found is None:
                    return AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND, b""
                return fit(found.entry().encode(), length)
            case IndexGroup.SYM_INFO_BY_NAME:
                found = dev.resolve(request_name(data))
                if found is None:
                    return AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND, b""
                info = struct.pack(
                    "<III", found.index_group, found.index_offset, found.size
                )
                return fit(info, length)
            case IndexGroup.SUMUP_READ:
                return self._sum_read(offset, length, data)
            case IndexGroup.SUMUP_WRITE:
                if not dev.system.sum_write_on_device_port:
                    return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
                return self._sum_write(offset, length, data)
            case IndexGroup.SUMUP_READ_WRITE:
                return self._sum_read_write(offset, length, data)
        if group in _SUM_GROUPS:
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
        if self.read(group, 0, 0)[0] != AdsReturnCode.DEVICE_INVALID_GROUP:
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
        return AdsReturnCode.DEVICE_INVALID_GROUP, b""

    # -- sum commands ---------------------------------------------------------

    def _sum_request(self, kind: type[_Sum], count: int, data: bytes) -> _Sum | int:
        """The decoded sum request, or the code that refuses all of it: more
        sub-commands than the limit (500, 0x705), or a malformed one."""
        if count > self.dev.system.max_sum_items or count == 0:
            return AdsReturnCode.DEVICE_INVALID_SIZE
        try:
            return kind.decode(data, count)
        except AdsCodecError as error:
            return error.return_code

    def _sum_read(self, count: int, length: int, data: bytes) -> Outcome:
        image = self.dev.image
        failing = self.dev.failing()
        plan = None if failing else self.plans.lookup(data, image.inputs, image.outputs)
        if plan is not None and plan.count == count:
            if length < plan.read_length:
                return AdsReturnCode.DEVICE_INVALID_SIZE, b""
            return AdsReturnCode.NO_ERROR, plan.answer(image.inputs, image.outputs)
        request = self._sum_request(SumReadRequest, count, data)
        if isinstance(request, int):
            return request, b""
        if length < request.read_length:
            return AdsReturnCode.DEVICE_INVALID_SIZE, b""
        if failing:
            # Items touching a failing symbol answer its error (zero data),
            # the others their values; no fast path.
            outcomes = [
                (code, b"")
                if (
                    code := item_error(failing, i.index_group, i.index_offset, i.length)
                )
                else self._sub_read(i.index_group, i.index_offset, i.length)
                for i in request.items
            ]
        else:
            if not self.plans.knows(data):
                self.plans.learn(
                    data, request.items, image.inputs, image.outputs, self._by_handle
                )
            # The hot path: plain slices of the images, single bits by lookup.
            areas = {area.byte_group: image.buffer(area) for area in AREAS}
            bits = {area.bit_group: image.buffer(area) for area in AREAS}
            outcomes = [
                read_slice(areas[i.index_group], i.index_offset, i.length)
                if i.index_group in areas
                else read_bits(bits[i.index_group], i.index_offset, 1)
                if i.length == 1 and i.index_group in bits
                else self._sub_read(i.index_group, i.index_offset, i.length)
                for i in request.items
            ]
        return AdsReturnCode.NO_ERROR, SumReadResponse.for_items(
            request.items, outcomes
        ).encode()

    def _by_handle(self, handle: int) -> Resolved | None:
        return self.dev.handle(handle)[1]

    def _sub_read(self, group: int, offset: int, length: int) -> Outcome:
        if group in _SUM_GROUPS:
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
        result, value = self.read(group, offset, length)
        return (
            (result, value)
            if len(value) <= length
            else (AdsReturnCode.DEVICE_INVALID_SIZE, b"")
        )

    def _sum_write(self, count: int, length: int, data: bytes) -> Outcome:
        request = self._sum_request(SumWriteRequest, count, data)
        if isinstance(request, int):
            return request, b""
        if length < request.read_length:
            return AdsReturnCode.DEVICE_INVALID_SIZE, b""
        results = tuple(
            AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
            if item.index_group in _SUM_GROUPS
            else self.write(item.index_group, item.index_offset, item.data)
            for item in request.items
        )
        return AdsReturnCode.NO_ERROR, SumWriteResponse(results).encode()

    def _sum_read_write(self, count: int, length: int, data: bytes) -> Outcome:
        request = self._sum_request(SumReadWriteRequest, count, data)
        if isinstance(request, int):
            return request, b""
        results: list[int] = []
        values: list[bytes] = []
        for item in request.items:
            if item.index_group in _SUM_GROUPS:
                result, value = AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED, b""
            else:
                result, value = self.read_write(
                    item.index_group, item.index_offset, item.read_length, item.data
                )
            results.append(result)
            values.append(value if result == AdsReturnCode.NO_ERROR else b"")
        answer = SumReadWriteResponse(tuple(results), tuple(values)).encode()
        return fit(answer, length)


@dataclass(slots=True)
class MasterPort(Port):
    """Port 0xFFFF of a device NetId: the EtherCAT master."""

    device: SimDevice | None = None

    def read(self, group: int, offset: int, length: int) -> Outcome:
        assert self.device is not None
        return self.device.ethercat.read(group, offset, length)

    def write(self, group: int, offset: int, data: bytes) -> int:
        assert self.device is not None
        result = self.device.ethercat.write(group, offset, data)
        self.device.refresh_states()
        return result


@dataclass(slots=True)
class SlavePort(Port):
    """A slave's port (its EtherCAT address): the CoE mailbox."""

    device: SimDevice | None = None
    runtime: SlaveRuntime | None = None

    def read_state(self) -> tuple[int, int]:
        assert self.runtime is not None
        return self.run.ads_state, self.runtime.state

    def read(self, group: int, offset: int, length: int) -> Outcome:
        assert self.device is not None and self.runtime is not None
        return self.device.ethercat.slave_read(self.runtime, group, offset, length)

    def write(self, group: int, offset: int, data: bytes) -> int:
        assert self.device is not None and self.runtime is not None
        return self.device.ethercat.slave_write(self.runtime, group, offset, data)


# -- the sum read fast path -----------------------------------------------------

_MAX_PLANS: Final = 256
"""Distinct sum read requests remembered per device port (a poller sends the
same few every cycle); past this the memory starts again."""

_IndexArray = npt.NDArray[np.intp]


@dataclass(frozen=True, slots=True)
class _Gather:
    """Where one image's bytes and bits go in a sum read answer's data."""

    byte_to: _IndexArray
    byte_from: _IndexArray
    bit_to: _IndexArray
    bit_from: _IndexArray
    bit_shift: npt.NDArray[np.uint8]

    def apply(self, data: npt.NDArray[np.uint8], buffer: bytearray) -> None:
        source = np.frombuffer(buffer, dtype=np.uint8)
        if len(self.byte_to):
            data[self.byte_to] = source[self.byte_from]
        if len(self.bit_to):
            data[self.bit_to] = (source[self.bit_from] >> self.bit_shift) & 1


@dataclass(frozen=True, slots=True)
class SumReadPlan:
    """A sum read whose every item is a valid image slice or single bit,
    precompiled into index arrays: answered with two numpy gathers into a
    zeroed answer (all results 0, `SumReadLayout`)."""

    count: int
    read_length: int
    inputs: _Gather
    outputs: _Gather

    def answer(self, inputs: bytearray, outputs: bytearray) -> bytes:
        answer = np.zeros(self.read_length, dtype=np.uint8)
        self.inputs.apply(answer, inputs)
        self.outputs.apply(answer, outputs)
        return answer.tobytes()


def compile_sum_read(
    items: tuple[SumReadItem, ...],
    inputs: bytearray,
    outputs: bytearray,
    by_handle: Callable[[int], Resolved | None] = lambda handle: None,
) -> SumReadPlan | None:
    """The plan for `items`, or None when any item needs the general path
    (another group, out of range, a multi-bit read, a handle that is not
    valid now). A read by handle is planned as the image slice or bit it
    names (`by_handle`), so a plan is only valid while its handles are."""
    layout = SumReadLayout.of(items)
    gathers: dict[int, tuple[bytearray, list[list[int]]]] = {}
    for area, buffer in ((INPUTS, inputs), (OUTPUTS, outputs)):
        lists: list[list[int]] = [[], [], [], [], []]
        gathers[area.byte_group] = (buffer, lists)
        gathers[area.bit_group] = (buffer, lists)
    byte_groups = {INPUTS.byte_group, OUTPUTS.byte_group}
    for item, position in zip(items, layout.data_offsets.tolist(), strict=True):
        if item.index_group == IndexGroup.SYM_VALUE_BY_HANDLE:
            planned = _handle_item(item, by_handle(item.index_offset))
            if planned is None:
                return None
            item = planned
        found = gathers.get(item.index_group)
        if found is None:
            return None
        buffer, (byte_to, byte_from, bit_to, bit_from, bit_shift) = found
        offset, length = item.index_offset, item.length
        if item.index_group in byte_groups:
            if offset + length > len(buffer):
                return None
            byte_to.extend(range(position, position + length))
            byte_from.extend(range(offset, offset + length))
        else:
            if length != 1 or offset >= 8 * len(buffer):
                return None
            bit_to.append(position)
            bit_from.append(offset >> 3)
            bit_shift.append(offset & 7)

    def gather(group: int) -> _Gather:
        byte_to, byte_from, bit_to, bit_from, bit_shift = gathers[group][1]
        return _Gather(
            np.asarray(byte_to, dtype=np.intp),
            np.asarray(byte_from, dtype=np.intp),
            np.asarray(bit_to, dtype=np.intp),
            np.asarray(bit_from, dtype=np.intp),
            np.asarray(bit_shift, dtype=np.uint8),
        )

    return SumReadPlan(
        count=len(items),
        read_length=layout.size,
        inputs=gather(INPUTS.byte_group),
        outputs=gather(OUTPUTS.byte_group),
    )


def _handle_item(item: SumReadItem, found: Resolved | None) -> SumReadItem | None:
    """The image read a read by handle amounts to: a single bit, or the
    first bytes of a byte-aligned value (a longer read gets zeros after
    them, as the general path answers); None for anything else."""
    if found is None:
        return None
    if found.type.is_bit:
        if found.type.bit_size != 1 or item.length < 1:
            return None
        return SumReadItem(found.area.bit_group, found.bit_address, 1)
    if found.bit_address % 8:
        return None
    return SumReadItem(
        found.area.byte_group, found.bit_address // 8, min(item.length, found.size)
    )


@dataclass(slots=True)
class SumReadPlans:
    """Plans keyed by the request's raw bytes, valid for one pair of image
    buffers: a new image (online change) or a resize forgets them all."""

    plans: dict[bytes, SumReadPlan | None] = field(default_factory=dict)
    images: tuple[bytearray, int, bytearray, int] | None = None

    def _current(self, inputs: bytearray, outputs: bytearray) -> None:
        known = self.images
        if (
            known is None
            or known[0] is not inputs
            or known[1] != len(inputs)
            or known[2] is not outputs
            or known[3] != len(outputs)
        ):
            self.plans.clear()
            self.images = (inputs, len(inputs), outputs, len(outputs))

    def lookup(
        self, data: bytes, inputs: bytearray, outputs: bytearray
    ) -> SumReadPlan | None:
        self._current(inputs, outputs)
        return self.plans.get(data)

    def knows(self, data: bytes) -> bool:
        """Whether `data` was seen (with a plan or found unplannable)."""
        return data in self.plans

    def learn(
        self,
        data: bytes,
        items: tuple[SumReadItem, ...],
        inputs: bytearray,
        outputs: bytearray,
        by_handle: Callable[[int], Resolved | None],
    ) -> None:
        if len(self.plans) >= _MAX_PLANS:
            self.plans.clear()
        self.plans[bytes(data)] = compile_sum_read(items, inputs, outputs, by_handle)


_READ_ONLY_GROUPS: Final = frozenset(
    {
        IndexGroup.SYM_UPLOAD_INFO,
        IndexGroup.SYM_UPLOAD_INFO_2,
        IndexGroup.SYM_UPLOAD,
        IndexGroup.SYM_DT_UPLOAD,
        IndexGroup.SYM_VERSION,
    }
)
_WRITE_ONLY_GROUPS: Final = frozenset(
    {
        IndexGroup.SYM_RELEASE_HANDLE,
        IndexGroup.IO_IMAGE_CLEAR_INPUTS,
        IndexGroup.IO_IMAGE_CLEAR_OUTPUTS,
    }
)
_NAME_GROUPS: Final = frozenset(
    {
        IndexGroup.SYM_HANDLE_BY_NAME,
        IndexGroup.SYM_VALUE_BY_NAME,
        IndexGroup.SYM_INFO_BY_NAME,
        IndexGroup.SYM_INFO_BY_NAME_EX,
        *_SUM_GROUPS,
    }
)


__all__ = [
    "DevicePort",
    "IoServerPort",
    "MasterPort",
    "Port",
    "RunState",
    "SlavePort",
    "SystemServicePort",
    "request_name",
]
