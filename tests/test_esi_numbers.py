"""ESI number spelling and channel templates of PDO names (pure functions)."""

from __future__ import annotations

import pytest

from fastcs_ethercat.esi import EsiEntry, channel_template, parse_esi_int


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("#x1a00", 0x1A00),
        ("#x1A00", 0x1A00),  # EL3314 AlternativeSmMapping spelling
        ("#X1a00", 0x1A00),
        ("#xc823052", 0xC823052),  # short width
        ("#x0000000A", 10),
        ("#x98", 0x98),  # sub-index in hex (EL3702 NextSync1Time)
        ("4096", 4096),
        (" 17 ", 17),
        ("0x10", 16),
        ("-5", -5),
    ],
)
def test_parse_esi_int_accepts_every_spelling(text: str, value: int) -> None:
    assert parse_esi_int(text) == value


@pytest.mark.parametrize("text", ["", "#x", "#xZZ", "one", "1.5"])
def test_parse_esi_int_rejects_garbage(text: str) -> None:
    with pytest.raises(ValueError):
        parse_esi_int(text)


@pytest.mark.parametrize(
    ("name", "channel", "template"),
    [
        ("AI Standard Channel 1", 1, "AI Standard Channel {channel}"),
        ("AI Compact Channel 4", 4, "AI Compact Channel {channel}"),
        ("PAI Samples 10 Channel 1", 1, "PAI Samples 10 Channel {channel}"),
        ("PAI SamplesR32 100 Channel 3", 3, "PAI SamplesR32 100 Channel {channel}"),
        ("MTO Outputs 10x Channel 8", 8, "MTO Outputs 10x Channel {channel}"),
        ("Ch1 Sample", 1, "Ch{channel} Sample"),
        ("Ch2 CycleCount", 2, "Ch{channel} CycleCount"),
        ("Channel 12", 12, "Channel {channel}"),
    ],
)
def test_channel_template_finds_the_channel(
    name: str, channel: int, template: str
) -> None:
    assert channel_template(name) == (channel, template)
    assert template.format(channel=channel) == name


@pytest.mark.parametrize(
    "name",
    [
        "CNT Inputs",
        "Channels",
        "NextSync1Time",
        "L1 Voltage Samples",
        "Diag 3",
        "Sample1",
        "RMB Value (INT32)",
    ],
)
def test_channel_template_ignores_other_digits(name: str) -> None:
    assert channel_template(name) == (None, None)


def test_channel_template_escapes_braces() -> None:
    channel, template = channel_template("Odd {name} Channel 2")
    assert channel == 2
    assert template is not None
    assert template.format(channel=2) == "Odd {name} Channel 2"


def test_padding_entry_is_index_zero() -> None:
    gap = EsiEntry(index=0, subindex=0, bit_len=7, name="", data_type=None)
    value = EsiEntry(
        index=0x6000, subindex=17, bit_len=16, name="Value", data_type="INT"
    )
    assert gap.is_padding
    assert not value.is_padding
