"""The client's sans-I/O session: every byte from the peer is checked, and a
bad frame becomes an event, never an exception."""

from __future__ import annotations

import struct
from dataclasses import replace
from typing import Final

from hypothesis import given, settings
from hypothesis import strategies as st

from fastcs_ethercat.ads.commands import (
    AdsRequest,
    DeviceNotification,
    NotificationSample,
    NotificationStamp,
    ReadRequest,
    ReadResponse,
    ReadStateRequest,
    ReadStateResponse,
)
from fastcs_ethercat.ads.constants import AdsReturnCode, AmsCommand
from fastcs_ethercat.ads.frames import AmsPacket, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.session import (
    Answered,
    BadFrame,
    Broken,
    ClientSession,
    Late,
    Malformed,
    Notified,
)

PLC: Final = AmsAddress(AmsNetId.parse("192.0.2.5.1.1"), 27905)
US: Final = AmsAddress(AmsNetId.parse("192.0.2.9.1.1"), 30000)


def sent(session: ClientSession, request: AdsRequest | None = None) -> AmsPacket:
    """Send a request (a 4-byte Read by default); return the header of the
    answer a well-behaved target would give (payload still to add)."""
    request = request or ReadRequest(0xF020, 0, 4)
    invoke_id, _ = session.send(PLC, US, request)
    return AmsPacket(
        target=US,
        source=PLC,
        command=request.command,
        state_flags=0x0005,
        invoke_id=invoke_id,
    )


def read_answer(session: ClientSession, data: bytes = b"\x01\x02\x03\x04") -> bytes:
    return good_answer(sent(session), data)


def good_answer(header: AmsPacket, data: bytes = bytes(4)) -> bytes:
    """The frame of a well-formed answer to the 4-byte Read of `header`."""
    return encode_packet(replace(header, payload=ReadResponse(0, data).encode()))


def awaited(session: ClientSession, frame: bytes) -> bool:
    """Whether `session` matches the answer `frame` to a request it still
    waits for (a request answered or failed is no longer waited for)."""
    return any(isinstance(event, Answered) for event in session.receive(frame))


def test_an_answer_is_matched_by_invoke_id_even_split_into_single_bytes() -> None:
    session = ClientSession()
    frame = read_answer(session)

    events = [e for byte in frame for e in session.receive(bytes([byte]))]

    assert len(events) == 1
    answer = events[0]
    assert isinstance(answer, Answered)
    assert answer.response == ReadResponse(0, b"\x01\x02\x03\x04")
    assert not awaited(session, frame)


def test_several_answers_in_one_read_come_out_in_order() -> None:
    session = ClientSession()
    frames = [read_answer(session, bytes([n]) * 4) for n in range(3)]

    events = session.receive(b"".join(frames))

    answers = [e.response for e in events if isinstance(e, Answered)]
    assert [a.data[0] for a in answers if isinstance(a, ReadResponse)] == [0, 1, 2]


def test_a_frame_longer_than_its_ams_header_says_fails_only_its_request() -> None:
    """The reply that crashed AdsLib: AMS/TCP length 1 KB past cbData 0."""
    session = ClientSession()
    packet = sent(session)
    header = encode_packet(packet)[6:38]
    frame = struct.pack("<HI", 0, 32 + 1024) + header + bytes(1024)
    good = read_answer(session)

    events = session.receive(frame + good)

    assert isinstance(events[0], BadFrame)
    assert events[0].kind is Malformed.HEADER
    assert events[0].invoke_id == packet.invoke_id
    assert isinstance(events[1], Answered)


def test_framing_that_cannot_be_trusted_breaks_the_stream() -> None:
    for bad in (
        struct.pack("<HI", 0, 0xFFFF_FFF0),  # huge length
        struct.pack("<HI", 0, 20) + bytes(20),  # shorter than an AMS header
        struct.pack("<HI", 0x1000, 40) + bytes(40),  # reserved field set
    ):
        session = ClientSession(max_frame_size=1 << 20)
        first = sent(session).invoke_id
        second = sent(session).invoke_id

        events = session.receive(bad)

        assert len(events) == 1
        broken = events[0]
        assert isinstance(broken, Broken)
        assert broken.kind in (Malformed.OVERSIZE, Malformed.FRAMING)
        assert set(broken.failed) == {first, second}  # failed, none waits more


def test_unknown_and_late_invoke_ids() -> None:
    session = ClientSession()
    packet = sent(session)
    session.forget(packet.invoke_id)
    late = encode_packet(replace(packet, payload=ReadResponse(0, bytes(4)).encode()))
    bogus = encode_packet(
        AmsPacket(US, PLC, AmsCommand.READ, 0x0005, 0, 99999, ReadResponse().encode())
    )

    events = session.receive(late + bogus)

    assert isinstance(events[0], Late)
    assert events[1] == BadFrame(
        Malformed.INVOKE_ID, "response with invoke id 99999 to no request"
    )


def test_answers_that_do_not_fit_their_request_fail_it() -> None:
    session = ClientSession()
    cases = {
        "other command": sent(session),
        "other source": sent(session),
        "payload lies": sent(session),
        "more than asked": sent(session),
    }
    frames = [
        encode_packet(
            AmsPacket(
                US,
                PLC,
                AmsCommand.WRITE,
                0x0005,
                0,
                cases["other command"].invoke_id,
                b"\0" * 4,
            )
        ),
        encode_packet(
            AmsPacket(
                US,
                AmsAddress(PLC.netid, 300),
                AmsCommand.READ,
                0x0005,
                0,
                cases["other source"].invoke_id,
                ReadResponse(0, bytes(4)).encode(),
            )
        ),
        encode_packet(
            replace(cases["payload lies"], payload=struct.pack("<II", 0, 100) + b"abc")
        ),
        encode_packet(
            replace(
                cases["more than asked"], payload=ReadResponse(0, bytes(5)).encode()
            )
        ),
    ]

    events = session.receive(b"".join(frames))

    assert all(isinstance(e, BadFrame) and e.invoke_id for e in events)
    assert [e.kind for e in events if isinstance(e, BadFrame)] == [
        Malformed.MISMATCH,
        Malformed.MISMATCH,
        Malformed.PAYLOAD,
        Malformed.PAYLOAD,
    ]
    assert not any(awaited(session, good_answer(case)) for case in cases.values())


def test_an_error_in_the_ams_header_is_an_answer() -> None:
    session = ClientSession()
    packet = sent(session, ReadStateRequest())

    (event,) = session.receive(
        encode_packet(
            AmsPacket(
                US,
                PLC,
                AmsCommand.READ_STATE,
                0x0005,
                AdsReturnCode.TARGET_PORT_NOT_FOUND,
                packet.invoke_id,
            )
        )
    )

    assert isinstance(event, Answered)
    assert event.response is None
    assert event.packet.error_code == AdsReturnCode.TARGET_PORT_NOT_FOUND


def test_notifications_and_requests_from_the_peer() -> None:
    session = ClientSession()
    stamps = (NotificationStamp(1234, (NotificationSample(7, b"\x05\x06"),)),)
    good = AmsPacket(
        US,
        PLC,
        AmsCommand.DEVICE_NOTIFICATION,
        0x0004,
        0,
        0,
        DeviceNotification(stamps).encode(),
    )
    garbage = replace(good, payload=b"\xff" * 13)
    request = AmsPacket(US, PLC, AmsCommand.READ, 0x0004, 0, 5, bytes(12))

    events = session.receive(
        encode_packet(good) + encode_packet(garbage) + encode_packet(request)
    )

    assert events[0] == Notified(US.port, PLC, stamps)
    assert isinstance(events[1], BadFrame)
    assert (events[1].kind, events[1].invoke_id) == (Malformed.NOTIFICATION, None)
    assert isinstance(events[2], BadFrame)
    assert (events[2].kind, events[2].invoke_id) == (Malformed.UNEXPECTED, None)


def test_answers_still_match_after_a_read_state() -> None:
    session = ClientSession()
    packet = sent(session, ReadStateRequest())
    answer = replace(packet, payload=ReadStateResponse(0, 5, 0).encode())

    (event,) = session.receive(encode_packet(answer))

    assert isinstance(event, Answered)
    assert event.response == ReadStateResponse(0, 5, 0)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=200), max_size=20))
def test_no_bytes_raise(chunks: list[bytes]) -> None:
    session = ClientSession(max_frame_size=4096)
    for _ in range(3):
        sent(session)
    for chunk in chunks:
        events = session.receive(chunk)
        if any(isinstance(e, Broken) for e in events):
            session = ClientSession(max_frame_size=4096)


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=32, max_size=300))
def test_any_body_behind_a_valid_length_is_an_event(body: bytes) -> None:
    session = ClientSession()
    sent(session)
    frame = struct.pack("<HI", 0, len(body)) + body

    events = session.receive(frame)

    assert len(events) == 1
    assert not isinstance(events[0], Broken)
