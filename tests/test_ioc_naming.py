"""PV names: the default scheme, aliases, and reported, collision-free shortening."""

from __future__ import annotations

import random
import re

import pytest
from fastcs.util import snake_to_pascal
from hypothesis import given, settings
from hypothesis import strategies as st

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.naming import (
    MAX_BASE_LENGTH,
    MAX_PREFIX_LENGTH,
    MAX_PV_LENGTH,
    RBV_SUFFIX,
    Node,
    NodeKind,
    PvNames,
    PvRequest,
    alias_key,
    default_segment,
    plan_pv_names,
)

PVI_NAME = re.compile(r"^([A-Z][a-z0-9]*)*$")
"""pvi's PascalStr: what a .bob widget name must match."""

MASTER = Node(NodeKind.MASTER, "Device 1 (EtherCAT)")
COUPLER = Node(NodeKind.COUPLER, "Term 1 (EK1100)")
EL3104 = Node(NodeKind.TERMINAL, "Term 5 (EL3104)")
PATH = (MASTER, COUPLER, EL3104)
PREFIX = "BL01T-EA-ECAT-01"


def _all_segments(names: PvNames) -> list[str]:
    return [*names.controllers.values(), *names.leaves.values()]


def test_default_scheme_for_twincat_names() -> None:
    requests = [
        PvRequest(PATH, "Term 5 (EL3104).AI Standard Channel 1.Value"),
        PvRequest(PATH, "WcState.WcState"),
        PvRequest((MASTER,), "SlaveCount"),
        PvRequest((), "ConnectionState"),
    ]

    names = plan_pv_names(PREFIX, requests)

    assert [names.pv(r) for r in requests] == [
        "BL01T-EA-ECAT-01:ETH1:RIO1:MOD5:AIStdCh1Value",
        "BL01T-EA-ECAT-01:ETH1:RIO1:MOD5:WcState",
        "BL01T-EA-ECAT-01:ETH1:SlaveCount",
        "BL01T-EA-ECAT-01:ConnectionState",
    ]
    assert names.controller_path(PATH) == [PREFIX, "ETH1", "RIO1", "MOD5"]
    assert names.shortened == ()


@pytest.mark.parametrize(
    ("name", "kind", "segment"),
    [
        ("Device 2 (EtherCAT)", NodeKind.MASTER, "ETH2"),
        ("Term 53 (EK1100)", NodeKind.COUPLER, "RIO53"),
        ("Term 55 (EL1014)", NodeKind.TERMINAL, "MOD55"),
        ("Shutter monitor", NodeKind.TERMINAL, "ShutterMonitor"),
        ("AI Inputs Channel 1.Value", None, "AIInputsCh1Value"),
        ("CNT Inputs Channel 1.Counter value", None, "CNTInputsCh1CounterValue"),
        ("PAI Samples 4 Channel 1", None, "PAISamples4Ch1"),
        ("Temperature °C / 0.1 %", None, "TemperatureDegC01Pct"),
        ("µA range", None, "UARange"),
        ("1st value", None, "N1stValue"),
        ("psu_monitor", None, "PsuMonitor"),
    ],
)
def test_default_segment(name: str, kind: NodeKind | None, segment: str) -> None:
    assert default_segment(name, kind) == segment


def test_long_names_are_shortened_and_reported() -> None:
    shutter = Node(NodeKind.TERMINAL, "Beamline shutter position monitor left side")
    long_leaf = "AI Standard Channel 1.Status.Limit 1 monitoring value reached"
    requests = [
        PvRequest((MASTER, COUPLER, shutter), long_leaf),
        PvRequest((MASTER, COUPLER, shutter), long_leaf + " again"),
        PvRequest(PATH, "AI Standard Channel 1.Status.Underrange"),
    ]

    names = plan_pv_names(PREFIX, requests)

    pvs = [names.pv(r) for r in requests]
    assert all(len(pv) + len(RBV_SUFFIX) <= MAX_PV_LENGTH for pv in pvs)
    assert len(set(pvs)) == len(pvs)
    reported = {s.source: s for s in names.shortened}
    terminal_key = alias_key([MASTER.name, COUPLER.name, shutter.name])
    assert reported[terminal_key].default == "BeamlineShutterPositionMonitorLeftSide"
    assert len(reported[terminal_key].segment) <= 16
    assert alias_key([*[n.name for n in requests[0].path], long_leaf]) in reported
    assert all(str(s).startswith(s.source) for s in names.shortened)


def test_vowels_go_first_when_that_is_enough() -> None:
    request = PvRequest(PATH, "AI Standard Channel 1.Status.Underrange")

    names = plan_pv_names("BL01T-EA-ECAT-01:X", [request])

    assert (
        names.pv(request) == "BL01T-EA-ECAT-01:X:ETH1:RIO1:MOD5:AIStdCh1StatusUndrrng"
    )
    assert names.shortened[0].reason == "vowels dropped to fit 22 characters"


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


def test_aliases_pin_segments_and_unused_ones_are_reported() -> None:
    value = PvRequest(PATH, "AI Standard Channel 1.Value")
    clash = PvRequest(PATH, "Ch1")
    terminal_key = alias_key(n.name for n in PATH)
    aliases = {
        terminal_key: "ShutterAdc",
        alias_key([*(n.name for n in PATH), value.leaf]): "Ch1",
        "Device 9 (EtherCAT)": "Gone",
    }

    names = plan_pv_names(PREFIX, [value, clash], aliases)

    assert names.pv(value) == f"{PREFIX}:ETH1:RIO1:ShutterAdc:Ch1"
    assert names.pv(clash).startswith(f"{PREFIX}:ETH1:RIO1:ShutterAdc:Ch1X")
    assert names.unused_aliases == ("Device 9 (EtherCAT)",)


@pytest.mark.parametrize(
    ("aliases", "message"),
    [
        ({"Device 1 (EtherCAT)": "eth_1"}, "must be PascalCase"),
        ({"Device 1 (EtherCAT)": "Pvi"}, "clashes"),
        ({"Device 1 (EtherCAT)": "A" * 40}, "at most"),
        (
            {
                alias_key(n.name for n in PATH) + "^A": "Same",
                alias_key(n.name for n in PATH) + "^B": "SAME",
            },
            "clashes",
        ),
    ],
)
def test_bad_aliases_are_user_errors(aliases: dict[str, str], message: str) -> None:
    requests = [PvRequest(PATH, "A"), PvRequest(PATH, "B")]

    with pytest.raises(UserError, match=message) as error:
        plan_pv_names(PREFIX, requests, aliases)

    assert "pv_aliases[" in str(error.value)


@pytest.mark.parametrize(
    ("prefix", "message"), [("BL01 EA", "only letters"), ("X" * 23, "at most 22")]
)
def test_bad_prefixes_are_user_errors(prefix: str, message: str) -> None:
    with pytest.raises(UserError, match=message):
        plan_pv_names(prefix, [PvRequest(PATH, "Value")])


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
    lambda depth, master, coupler, terminal, leaf: PvRequest(
        (
            Node(NodeKind.MASTER, master),
            Node(NodeKind.COUPLER, coupler),
            Node(NodeKind.TERMINAL, terminal),
        )[:depth],
        leaf,
    ),
    st.integers(0, 3),
    st.sampled_from(["Device 1 (EtherCAT)", "Device 2 (EtherCAT)", "device 1"]),
    st.one_of(st.sampled_from(["Term 1 (EK1100)", "Term 1 (EK1101)"]), TEXT),
    st.one_of(st.sampled_from(["Term 5 (EL3104)", "Term 05 (EL3104)"]), TEXT),
    TEXT,
)


@settings(max_examples=300, deadline=None)
@given(
    prefix=st.text(alphabet="AB01:-_", min_size=1, max_size=MAX_PREFIX_LENGTH),
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
    assert all(len(pv) <= MAX_BASE_LENGTH for pv in pvs)
    assert all(len(pv + RBV_SUFFIX) <= MAX_PV_LENGTH for pv in pvs)
    assert all(PVI_NAME.match(s) for s in _all_segments(names))
    assert [again.pv(r) for r in requests] == pvs
    assert again.shortened == names.shortened
    for request in requests:
        controllers = names.controller_path(request.path)
        assert len(":".join(controllers)) + len(":PVI") <= MAX_PV_LENGTH
