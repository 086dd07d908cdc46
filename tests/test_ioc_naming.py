"""PV names: short stable segments by construction, aliases that cannot
collide, and shortening only as a reported last resort."""

from __future__ import annotations

import random
import re

import pytest
from fastcs.util import snake_to_pascal
from hypothesis import given, settings
from hypothesis import strategies as st

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.naming import (
    MAX_PREFIX_LENGTH,
    MAX_PV_LENGTH,
    RBV_SUFFIX,
    Node,
    NodeKind,
    PvNames,
    PvRequest,
    alias_key,
    coe_request,
    default_segment,
    plan_pv_names,
    symbol_request,
    value_names,
)
from fastcs_ethercat.ioc.plan import CoePoint

PVI_NAME = re.compile(r"^([A-Z][a-z0-9]*)*$")
"""pvi's PascalStr: what a .bob widget name must match."""

MASTER = Node(NodeKind.MASTER, "Device 1 (EtherCAT)")
COUPLER = Node(NodeKind.COUPLER, "Term 1 (EK1100)")
EL3104 = Node(NodeKind.TERMINAL, "Term 5 (EL3104)")
PATH = (MASTER, COUPLER, EL3104)
PREFIX = "BL21I-EA-ECAT-01"
"""A Diamond beamline prefix: 16 characters."""


def _all_segments(names: PvNames) -> list[str]:
    return [*names.controllers.values(), *names.leaves.values()]


def _pv_length(names: PvNames, request: PvRequest) -> int:
    rbv = len(RBV_SUFFIX) if request.writable else 0
    return len(names.pv(request)) + rbv


def _analog(path: tuple[Node, ...], group: str = "Standard") -> list[PvRequest]:
    """An EL3104's values as discovery finds them (Standard or Compact PDOs)."""
    terminal = path[-1].name
    requests = []
    for channel in range(1, 5):
        if group == "Compact":
            symbol = f"{terminal}.AI Compact Channel {channel}"
            requests.append(
                symbol_request(path, symbol, entry_name="Value", channel=channel)
            )
            continue
        for entry in ("Status.Underrange", "Status.TxPDO Toggle", "Value"):
            symbol = f"{terminal}.AI Standard Channel {channel}.{entry}"
            requests.append(
                symbol_request(path, symbol, entry_name=entry, channel=channel)
            )
    return requests


def test_values_sit_under_their_channel_with_short_names() -> None:
    requests = [
        *_analog(PATH),
        PvRequest(PATH, "AlState"),
        PvRequest(PATH, "Term 5 (EL3104).WcState.WcState"),
        PvRequest((MASTER,), "SlaveCount"),
        PvRequest((), "ConnectionState"),
    ]

    names = plan_pv_names(PREFIX, requests)

    pvs = {names.pv(r) for r in requests}
    assert {
        "BL21I-EA-ECAT-01:ETH1:RIO1:MOD5:CH1:Underrange",
        "BL21I-EA-ECAT-01:ETH1:RIO1:MOD5:CH1:TxPDOToggle",
        "BL21I-EA-ECAT-01:ETH1:RIO1:MOD5:CH4:Value",
        "BL21I-EA-ECAT-01:ETH1:RIO1:MOD5:AlState",
        "BL21I-EA-ECAT-01:ETH1:RIO1:MOD5:WcState",
        "BL21I-EA-ECAT-01:ETH1:SlaveCount",
        "BL21I-EA-ECAT-01:ConnectionState",
    } <= pvs
    assert names.controller_path(PATH) == [PREFIX, "ETH1", "RIO1", "MOD5"]
    assert names.shortened == ()


def test_standard_and_compact_pdos_give_the_same_value_names() -> None:
    standard = plan_pv_names(PREFIX, _analog(PATH))
    compact_path = (MASTER, COUPLER, Node(NodeKind.TERMINAL, "Term 9 (EL3104)"))
    compact = plan_pv_names(PREFIX, _analog(compact_path, "Compact"))

    def values(names: PvNames) -> set[str]:
        return {
            pv.split(":MOD", 1)[1].split(":", 1)[1]
            for pv in map(names.pv, names.leaves)
            if pv.endswith(":Value")
        }

    assert values(standard) == values(compact) == {f"CH{n}:Value" for n in (1, 2, 3, 4)}


PLACES = [
    PATH,
    (MASTER, Node(NodeKind.COUPLER, "Term 100 (EK1100)"), EL3104),
    (MASTER, COUPLER, Node(NodeKind.TERMINAL, "Term 105 (EL3104)")),
    (MASTER, Node(NodeKind.COUPLER, "Term 700 (EK1100)"), EL3104),
    (MASTER, Node(NodeKind.TERMINAL, "Term 999 (EL3104)")),
    (Node(NodeKind.MASTER, "Device 3 (EtherCAT)"), EL3104),
]


def test_a_terminal_type_gets_the_same_suffixes_wherever_it_sits() -> None:
    """The room of a value comes from the budgets of its levels, one for the
    whole IOC, not from where the terminal sits: the longest names, at the
    limit of their room, are cut the same way at `MOD5`, at `MOD999` and
    behind no coupler."""
    long_entries = [
        "Status.Output functions enabled",
        "Control.Enable output functions",
    ]
    requests = {
        path: [
            symbol_request(
                path,
                f"{path[-1].name}.CNT Channel 1.{entry}",
                entry_name=entry,
                channel=1,
                writable=entry.startswith("Control"),
            )
            for entry in long_entries
        ]
        + _analog(path)
        for path in PLACES
    }

    names = plan_pv_names(PREFIX, [r for each in requests.values() for r in each])

    def suffixes(path: tuple[Node, ...]) -> list[str]:
        return sorted(":".join(names.below(r, len(path))) for r in requests[path])

    assert "CH1:EnblOutputFnctns" in suffixes(PATH)  # at its limit: a real check
    assert all(suffixes(path) == suffixes(PATH) for path in PLACES)
    assert all(_pv_length(names, r) <= MAX_PV_LENGTH for r in names.leaves)


@pytest.mark.parametrize(
    ("symbol", "entry", "channel", "expected"),
    [
        (
            "AI Standard Channel 2.Status.Underrange",
            "Status.Underrange",
            2,
            "Underrange",
        ),
        ("AI Compact Channel 2", "Value", 2, "Value"),
        ("Ch1 CycleCount", "Ch1 CycleCount", 1, "CycleCount"),
        ("Ch1 Sample 0", "Ch1 Value", 1, "Value"),
        ("AO Output Channel 3", "Analog output", 3, "AnalogOutput"),
        ("CNT Outputs.Control.Set counter", "Control.Set counter", None, "SetCounter"),
        ("PAI Samples 4 Channel 1.Samples", "Samples", 1, "Samples"),
        ("WcState.WcState", "", None, "WcState"),
        ("Channel 12", "", 12, "Ch12"),
    ],
)
def test_a_value_is_named_by_its_esi_entry(
    symbol: str, entry: str, channel: int | None, expected: str
) -> None:
    assert default_segment(value_names(symbol, entry, channel)[0]) == expected


def test_values_that_would_share_a_name_take_their_longer_names() -> None:
    requests = [
        symbol_request(PATH, f"{EL3104.name}.X Channel 1.{entry}", entry_name=entry,
                       channel=1, writable=entry.startswith("Control"))
        for entry in ("Status.Error", "Control.Error", "Value")
    ]  # fmt: skip
    requests.append(
        symbol_request(
            PATH, f"{EL3104.name}.Y Channel 1", entry_name="Value", channel=1
        )
    )

    names = plan_pv_names(PREFIX, requests)

    assert sorted(names.leaves.values()) == [
        "ControlError",
        "StatusError",
        "XValue",
        "Y",  # a whole symbol: its name without the channel
    ]
    assert names.shortened == ()


def test_coe_values_sit_under_their_object() -> None:
    def coe(subindex: int, name: str) -> CoePoint:
        return CoePoint(f"ai_settings_{subindex}", 0x8000, subindex, "BOOL", 1, True,
                        name=name, object_name="AI Settings")  # fmt: skip

    points = [coe(6, "Enable filter"), coe(0x11, "Reserved"), coe(0x12, "Reserved")]
    requests = [coe_request(PATH, f"Coe {p.attribute}", p) for p in points]

    names = plan_pv_names(PREFIX, requests)

    assert [
        names.pv(r).removeprefix(f"{PREFIX}:ETH1:RIO1:MOD5:") for r in requests
    ] == [
        "C8000:EnableFilter",
        "C8000:Reserved11",
        "C8000:Reserved12",
    ]


def test_long_names_are_shortened_and_reported() -> None:
    shutter = Node(NodeKind.TERMINAL, "Beamline shutter position monitor left side")
    long_leaf = "Limit 1 monitoring value reached for the second time today"
    requests = [
        PvRequest((MASTER, COUPLER, shutter), long_leaf, writable=True),
        PvRequest((MASTER, COUPLER, shutter), long_leaf + " again"),
        symbol_request(
            PATH,
            f"{EL3104.name}.AI Channel 1.Status.Limit one exceeded upwards",
            entry_name="Status.Limit one exceeded upwards",
            channel=1,
        ),
    ]

    names = plan_pv_names(PREFIX, requests)

    assert all(_pv_length(names, r) <= MAX_PV_LENGTH for r in requests)
    assert len({names.pv(r) for r in requests}) == len(requests)
    reported = {s.source: s for s in names.shortened}
    terminal_key = alias_key([MASTER.name, COUPLER.name, shutter.name])
    assert reported[terminal_key].default == "BeamlineShutterPositionMonitorLeftSide"
    assert len(reported[terminal_key].segment) <= 16
    assert all(str(s).startswith(s.source) for s in names.shortened)
    value = names.leaves[requests[2]]
    assert value == "LimitOneExcddUpwards"  # 20: vowels dropped, no hash
    assert not reported[
        alias_key([*(n.name for n in PATH), requests[2].leaf[16:]])
    ].hashed
    shortened = {s.node for s in names.shortened}
    assert all(r in shortened or r.path in shortened for r in requests)


def test_words_are_cut_before_a_hash_is_given() -> None:
    entry = "Enable automatic calibration"
    request = symbol_request(PATH, f"{EL3104.name}.S Channel 1.{entry}",
                             entry_name=entry, channel=1, writable=True)  # fmt: skip

    names = plan_pv_names("BL21I-EA-ECAT-01-LONG", [request])

    [shortening] = names.shortened
    assert (shortening.default, shortening.segment) == (
        "EnableAutomaticCalibration",
        "EnblAtmtClbrt",
    )
    assert shortening.reason == "words cut short to fit 13 characters"
    assert not shortening.hashed


def test_names_that_sanitise_alike_stay_distinct() -> None:
    requests = [
        PvRequest(PATH, "AI Standard Channel 1.Value"),
        PvRequest(PATH, "AI_Standard_Channel_1.Value"),
        PvRequest(PATH, "ai standard channel 1 value"),
        PvRequest(PATH, "PVI"),
    ]

    names = plan_pv_names(PREFIX, requests)

    lowered = {names.pv(r).lower() for r in requests}
    assert len(lowered) == len(requests)
    assert f"{PREFIX}:ETH1:RIO1:MOD5:pvi".lower() not in lowered
    assert len(names.shortened) == len(requests)
    assert all(s.hashed for s in names.shortened)


def test_aliases_pin_segments_and_unused_ones_are_reported() -> None:
    [value, *_] = _analog(PATH)
    terminal_key = alias_key(n.name for n in PATH)
    aliases = {
        terminal_key: "ShutterAdc",
        alias_key([*(n.name for n in PATH), value.leaf[16:]]): "Low",
        "Device 9 (EtherCAT)": "Gone",
    }

    names = plan_pv_names(PREFIX, [value, PvRequest(PATH, "AlState")], aliases)

    assert names.pv(value) == f"{PREFIX}:ETH1:RIO1:ShutterAdc:CH1:Low"
    assert names.unused_aliases == ("Device 9 (EtherCAT)",)


TERMINAL_KEY = alias_key(n.name for n in PATH)
SIX = Node(NodeKind.TERMINAL, "Term 6 (EL2024)")


@pytest.mark.parametrize(
    ("aliases", "message"),
    [
        ({TERMINAL_KEY: "MOD6"}, "alias 'MOD6' is also the name of .*Term 6 .*MOD6"),
        (
            {f"{TERMINAL_KEY}^AI Standard Channel 1.Value": "Limit1"},
            "alias 'Limit1' is also the name of .*Channel 1.Status.Limit 1",
        ),
        ({f"{TERMINAL_KEY}^Dial": "AlState"}, "also the name of .*AlState"),
        ({MASTER.name: "Connected"}, "also the name of 'Connected'"),
        ({f"{TERMINAL_KEY}^Dial": "CH1"}, "also the name of .*CH1"),
        (
            {f"{TERMINAL_KEY}^Dial": "Same", f"{TERMINAL_KEY}^Knob": "SAME"},
            "is also the alias of",
        ),
        ({MASTER.name: "Pvi"}, "FastCS's own PVI"),
        ({MASTER.name: "eth_1"}, "must be PascalCase"),
        ({MASTER.name: "A" * 40}, "at most"),
        ({f"{TERMINAL_KEY}^Dial": "A" * 30}, r"at most 26 fit"),
    ],
)
def test_an_alias_equal_to_another_name_stops_with_one_line_naming_both(
    aliases: dict[str, str], message: str
) -> None:
    requests = [
        PvRequest(PATH, f"{EL3104.name}.Dial", ("Dial",)),
        PvRequest(PATH, f"{EL3104.name}.Knob", ("Knob",)),
        PvRequest(PATH, "AlState"),
        PvRequest((MASTER, COUPLER, SIX), "AlState"),
        PvRequest((), "Connected"),
        symbol_request(PATH, f"{EL3104.name}.AI Standard Channel 1.Value",
                       entry_name="Value", channel=1),
        symbol_request(PATH, f"{EL3104.name}.AI Standard Channel 1.Status.Limit 1",
                       entry_name="Status.Limit 1", channel=1),
    ]  # fmt: skip

    with pytest.raises(UserError, match=message) as error:
        plan_pv_names(PREFIX, requests, aliases)

    text = str(error.value)
    assert "pv_aliases[" in text and "\n" not in text


@pytest.mark.parametrize(
    ("prefix", "message"), [("BL01 EA", "only letters"), ("X" * 23, "at most 22")]
)
def test_bad_prefixes_are_user_errors(prefix: str, message: str) -> None:
    with pytest.raises(UserError, match=message):
        plan_pv_names(prefix, [PvRequest(PATH, "Value")])


def test_the_longest_prefix_still_fits_every_value() -> None:
    requests = [*_analog(PATH), *_analog((MASTER, COUPLER, SIX))]
    requests = [
        symbol_request(PATH, r.leaf, entry_name="Status.Underrange", channel=1,
                       writable=True)
        for r in requests[:1]
    ] + requests  # fmt: skip

    names = plan_pv_names("P" * MAX_PREFIX_LENGTH, requests)

    assert all(_pv_length(names, r) <= MAX_PV_LENGTH for r in requests)
    assert not any(s.hashed for s in names.shortened)


def test_a_level_over_its_budget_takes_room_from_below() -> None:
    path = (Node(NodeKind.MASTER, "Device 10 (EtherCAT)"), COUPLER, EL3104)
    entry = "Status.Output functions on"  # 17 characters: fits its room of 21
    request = symbol_request(path, f"{EL3104.name}.C Channel 1.{entry}",
                             entry_name=entry, channel=1)  # fmt: skip
    pinned = {alias_key([path[0].name]): "EthercatMain"}  # 7 over its budget

    plain = plan_pv_names(PREFIX, [request])
    names = plan_pv_names(PREFIX, [request], pinned)

    assert plain.pv(request) == f"{PREFIX}:ETH10:RIO1:MOD5:CH1:OutputFunctionsOn"
    assert names.pv(request) == f"{PREFIX}:EthercatMain:RIO1:MOD5:CH1:OutputFnctnsOn"
    assert _pv_length(names, request) <= MAX_PV_LENGTH


def test_every_segment_survives_fastcs_pvi_and_screens() -> None:
    requests = [
        PvRequest(PATH, leaf)
        for leaf in ("x", "value_2", "Ä Ö ü", "", "...", "9 lives", "ABC_def ghi")
    ]

    names = plan_pv_names("P", requests)

    for segment in _all_segments(names):
        assert PVI_NAME.match(segment), segment
        assert snake_to_pascal(segment) == segment


TEXT = st.text(alphabet="AaBbEeLlTtCh01 ._()-µ", max_size=70)
REQUEST = st.builds(
    lambda depth, master, coupler, terminal, leaf, entry, channel, writable: (
        symbol_request(
            (
                Node(NodeKind.MASTER, master),
                Node(NodeKind.COUPLER, coupler),
                Node(NodeKind.TERMINAL, terminal),
            )[:depth],
            leaf,
            entry_name=entry,
            channel=channel if depth else None,
            writable=writable,
        )
    ),
    st.integers(0, 3),
    st.sampled_from(["Device 1 (EtherCAT)", "Device 2 (EtherCAT)", "device 1"]),
    st.one_of(st.sampled_from(["Term 1 (EK1100)", "Term 1 (EK1101)"]), TEXT),
    st.one_of(st.sampled_from(["Term 5 (EL3104)", "Term 05 (EL3104)"]), TEXT),
    TEXT,
    st.one_of(st.just(""), st.sampled_from(["Value", "Status.Error"]), TEXT),
    st.one_of(st.none(), st.integers(1, 99)),
    st.booleans(),
)


@settings(max_examples=300, deadline=None)
@given(
    prefix=st.text(alphabet="AB01:-_", min_size=1, max_size=MAX_PREFIX_LENGTH).filter(
        lambda prefix: not prefix.endswith(":")  # refused: see check_prefix
    ),
    requests=st.lists(REQUEST, min_size=1, max_size=40, unique=True),
    seed=st.integers(0, 2**32 - 1),
)
def test_unique_inputs_give_unique_short_deterministic_names(
    prefix: str, requests: list[PvRequest], seed: int
) -> None:
    names = plan_pv_names(prefix, requests)
    shuffled = list(requests)
    random.Random(seed).shuffle(shuffled)
    again = plan_pv_names(prefix, shuffled)

    pvs = [names.pv(r) for r in requests]
    assert len({pv.lower() for pv in pvs}) == len(requests)
    assert all(_pv_length(names, r) <= MAX_PV_LENGTH for r in requests)
    assert all(PVI_NAME.match(s) for s in _all_segments(names))
    assert [again.pv(r) for r in requests] == pvs
    assert again.shortened == names.shortened
    for request in requests:
        controllers = names.controller_path(request.path)
        assert len(":".join(controllers)) + len(":PVI") <= MAX_PV_LENGTH
