"""ADS command payloads: hand-written layouts, round trips, error codes."""

from __future__ import annotations

import contextlib
from datetime import UTC, datetime

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyads.filetimes import dt_to_filetime, filetime_to_dt

from fastcs_ethercat.ads.commands import (
    FILETIME_UNIX_EPOCH,
    REQUEST_TYPES,
    RESPONSE_TYPES,
    AddDeviceNotificationRequest,
    AddDeviceNotificationResponse,
    AdsRequest,
    AdsResponse,
    DeleteDeviceNotificationRequest,
    DeleteDeviceNotificationResponse,
    DeviceNotification,
    NotificationSample,
    NotificationStamp,
    ReadDeviceInfoRequest,
    ReadDeviceInfoResponse,
    ReadRequest,
    ReadResponse,
    ReadStateRequest,
    ReadStateResponse,
    ReadWriteRequest,
    ReadWriteResponse,
    WriteControlRequest,
    WriteControlResponse,
    WriteRequest,
    WriteResponse,
    decode_request,
    decode_response,
    error_response,
    filetime_from_unix_ns,
    filetime_to_datetime,
    notification_time_from_ms,
)
from fastcs_ethercat.ads.constants import (
    AdsReturnCode,
    AdsState,
    AmsCommand,
    TransmissionMode,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from tests.ads_codec import filetime_from_datetime, filetime_to_unix_ns

u32 = st.integers(0, 0xFFFF_FFFF)
u16 = st.integers(0, 0xFFFF)
u8 = st.integers(0, 255)
blobs = st.binary(max_size=40)
samples = st.builds(NotificationSample, u32, blobs)
stamps = st.builds(
    NotificationStamp,
    st.integers(0, 2**64 - 1),
    st.lists(samples, max_size=3).map(tuple),
)
device_names = st.text(
    alphabet=st.characters(codec="cp1252", exclude_characters="\0"), max_size=16
).filter(lambda s: len(s.encode("cp1252")) <= 16)

payloads = st.one_of(
    st.just(ReadDeviceInfoRequest()),
    st.builds(ReadDeviceInfoResponse, u32, u8, u8, u16, device_names),
    st.builds(ReadRequest, u32, u32, u32),
    st.builds(ReadResponse, u32, blobs),
    st.builds(WriteRequest, u32, u32, blobs),
    st.builds(WriteResponse, u32),
    st.just(ReadStateRequest()),
    st.builds(ReadStateResponse, u32, u16, u16),
    st.builds(WriteControlRequest, u16, u16, blobs),
    st.builds(WriteControlResponse, u32),
    st.builds(AddDeviceNotificationRequest, u32, u32, u32, u32, u32, u32),
    st.builds(AddDeviceNotificationResponse, u32, u32),
    st.builds(DeleteDeviceNotificationRequest, u32),
    st.builds(DeleteDeviceNotificationResponse, u32),
    st.builds(DeviceNotification, st.lists(stamps, max_size=3).map(tuple)),
    st.builds(ReadWriteRequest, u32, u32, u32, blobs),
    st.builds(ReadWriteResponse, u32, blobs),
)


def h(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


# Layouts written out by hand from the facts file, section 2.
HAND_WRITTEN: list[tuple[AdsRequest | AdsResponse, str]] = [
    (ReadDeviceInfoRequest(), ""),
    (
        ReadDeviceInfoResponse(0, 3, 1, 2103, "I/O Server"),
        "00000000 03 01 3708" + "492f4f20536572766572" + "00" * 6,
    ),
    (ReadRequest(0xF00F, 0, 24), "0ff00000 00000000 18000000"),
    (ReadResponse(0, b"\x01\x02"), "00000000 02000000 0102"),
    (
        WriteRequest(0xF006, 0, b"\x05\x00\x00\x00"),
        "06f00000 00000000 04000000 05000000",
    ),
    (WriteResponse(0x705), "05070000"),
    (ReadStateRequest(), ""),
    (ReadStateResponse(0, AdsState.RUN, 0), "00000000 0500 0000"),
    (WriteControlRequest(AdsState.STOP, 0, b""), "0600 0000 00000000"),
    (WriteControlResponse(0), "00000000"),
    (
        AddDeviceNotificationRequest(
            0xF021, 0x10, 1, TransmissionMode.SERVER_CYCLE, 0, 100_000
        ),
        "21f00000 10000000 01000000 03000000 00000000 a0860100" + "00" * 16,
    ),
    (AddDeviceNotificationResponse(0, 7), "00000000 07000000"),
    (DeleteDeviceNotificationRequest(7), "07000000"),
    (DeleteDeviceNotificationResponse(0x714), "14070000"),
    (
        DeviceNotification(
            (NotificationStamp(FILETIME_UNIX_EPOCH, (NotificationSample(7, b"\x01"),)),)
        ),
        # length = 4 (stamp count) + 12 (stamp head) + 9 (sample) = 25
        "19000000 01000000 00803ed5deb19d01 01000000 07000000 01000000 01",
    ),
    (
        ReadWriteRequest(0xF003, 0, 4, b"Term 1\0"),
        "03f00000 00000000 04000000 07000000 5465726d203100",
    ),
    (ReadWriteResponse(0, b"\x2a\x00\x00\x00"), "00000000 04000000 2a000000"),
]


@pytest.mark.parametrize(("payload", "hex_text"), HAND_WRITTEN)
def test_hand_written_layouts(payload: AdsRequest | AdsResponse, hex_text: str) -> None:
    raw = h(hex_text)
    assert payload.encode() == raw
    decode = decode_response if payload.is_response else decode_request
    assert decode(payload.command, raw) == payload


def test_every_command_has_a_request_and_all_but_notification_a_response() -> None:
    assert set(REQUEST_TYPES) == set(AmsCommand) - {AmsCommand.INVALID}
    assert set(RESPONSE_TYPES) == set(REQUEST_TYPES) - {AmsCommand.DEVICE_NOTIFICATION}


@settings(max_examples=300)
@given(payloads)
def test_round_trip(payload: AdsRequest | AdsResponse) -> None:
    decode = decode_response if payload.is_response else decode_request
    assert decode(payload.command, payload.encode()) == payload


@pytest.mark.parametrize("command_id", [0, 10, 0x55, 0xFFFF])
def test_unknown_command_is_service_not_supported(command_id: int) -> None:
    for decode in (decode_request, decode_response):
        with pytest.raises(AdsCodecError) as caught:
            decode(command_id, b"")
        assert caught.value.return_code == AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED


def test_notification_has_no_response() -> None:
    with pytest.raises(AdsCodecError) as caught:
        decode_response(AmsCommand.DEVICE_NOTIFICATION, b"")
    assert caught.value.return_code == AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED


@pytest.mark.parametrize(
    ("command", "payload"),
    [
        (AmsCommand.READ, "0ff00000 00000000"),  # short
        (AmsCommand.READ, "0ff00000 00000000 18000000 00"),  # long
        (AmsCommand.WRITE, "06f00000 00000000 04000000 050000"),  # data short
        (AmsCommand.WRITE, "06f00000 00000000 04000000 0500000000"),  # data long
        (AmsCommand.READ_WRITE, "03f00000 00000000 04000000 08000000 41"),
        (AmsCommand.READ_STATE, "00"),
        (AmsCommand.READ_DEVICE_INFO, "00"),
        (AmsCommand.ADD_DEVICE_NOTIFICATION, "00" * 39),
        (AmsCommand.DELETE_DEVICE_NOTIFICATION, "000000"),
        (AmsCommand.WRITE_CONTROL, "0500 0000 01000000"),
    ],
)
def test_wrong_request_size_is_parameter_size_not_correct(
    command: AmsCommand, payload: str
) -> None:
    with pytest.raises(AdsCodecError) as caught:
        decode_request(command, h(payload))
    assert caught.value.return_code == AdsReturnCode.DEVICE_INVALID_SIZE


def test_notification_length_field_must_match() -> None:
    raw = bytearray(
        DeviceNotification(
            (NotificationStamp(1, (NotificationSample(1, b"ab"),)),)
        ).encode()
    )
    raw[0] += 1
    with pytest.raises(AdsCodecError, match="length field"):
        DeviceNotification.decode(bytes(raw))


def test_error_response_keeps_the_full_layout() -> None:
    assert error_response(AmsCommand.READ, 0x702).encode() == h("02070000 00000000")
    assert error_response(AmsCommand.READ_WRITE, 0x710).encode() == h(
        "10070000 00000000"
    )
    assert error_response(AmsCommand.WRITE, 0x704).encode() == h("04070000")
    assert error_response(AmsCommand.READ_STATE, 0x707).encode() == h(
        "07070000 0000 0000"
    )


def test_result_only_error_answers_are_accepted() -> None:
    assert ReadResponse.decode(h("02070000")) == ReadResponse(0x702)
    assert ReadWriteResponse.decode(h("10070000")) == ReadWriteResponse(0x710)
    with pytest.raises(AdsCodecError):
        ReadResponse.decode(h("00000000"))  # success must carry its length


def test_device_name_longer_than_16_bytes_is_rejected() -> None:
    with pytest.raises(AdsCodecError):
        ReadDeviceInfoResponse(name="x" * 17).encode()


def test_out_of_range_fields_raise_codec_errors() -> None:
    with pytest.raises(AdsCodecError):
        ReadRequest(2**32, 0, 0).encode()
    with pytest.raises(AdsCodecError):
        ReadStateResponse(0, 70000, 0).encode()


@settings(max_examples=500)
@given(st.sampled_from(list(AmsCommand)), st.booleans(), st.binary(max_size=64))
def test_decoders_only_raise_codec_errors(
    command: AmsCommand, response: bool, raw: bytes
) -> None:
    with contextlib.suppress(AdsCodecError):
        (decode_response if response else decode_request)(command, raw)


def test_filetime_agrees_with_pyads() -> None:
    moment = datetime(2024, 5, 17, 12, 30, 45, 123456, tzinfo=UTC)
    ticks = filetime_from_datetime(moment)
    assert ticks == dt_to_filetime(moment.replace(microsecond=0)) + 1_234_560
    assert filetime_to_datetime(ticks) == moment
    assert filetime_to_dt(ticks) == moment
    assert filetime_from_unix_ns(0) == FILETIME_UNIX_EPOCH
    assert filetime_to_unix_ns(FILETIME_UNIX_EPOCH + 15) == 1500
    assert filetime_from_datetime(datetime(1601, 1, 1)) == 0


def test_notification_times_travel_in_100ns_units() -> None:
    assert notification_time_from_ms(10) == 100_000
    assert notification_time_from_ms(0.5) == 5000
