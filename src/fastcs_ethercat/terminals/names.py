"""Names: `{channel}` templates and PV-friendly attribute names.

Symbol and member names in the terminal YAML are templates where one node
stands for the same PDO on several channels ("AI Standard Channel {channel}").
FastCS attribute names must be snake_case identifiers and become part of PV
names, so they are derived here once, the same way for generator and loader.
"""

from __future__ import annotations

import re

CHANNEL = "{channel}"

_MARK = "\x00"
_NOT_ALNUM = re.compile(r"[^0-9a-zA-Z\x00]+")
_CAMEL_HUMP = re.compile(r"([a-z0-9])([A-Z])")


def expand(template: str, channel: int | None) -> str:
    """The name for one channel (templates without `{channel}` stay as they are)."""
    if channel is None:
        return template
    return template.replace(CHANNEL, str(channel))


def templatize(name: str, channel: int) -> str:
    """Replace the channel number in `name` by `{channel}` where it stands alone.

    "Ch2 Value" with channel 2 -> "Ch{channel} Value"; digits that are part
    of a longer number ("12") are left alone.
    """
    return re.sub(rf"(?<!\d){channel}(?!\d)", CHANNEL, name)


def snake_name(text: str, *, split_camel: bool = False) -> str:
    """A snake_case identifier for a free-text name, keeping `{channel}`.

    "AI Standard Channel {channel}" -> "ai_standard_channel_{channel}",
    "Ch{channel} Value" -> "ch{channel}_value", "Status__TxPDO Toggle" ->
    "status_txpdo_toggle"; a name that would start with a digit gets an `n`
    (a channel: `ch`) in front so it stays a valid identifier. With
    `split_camel` (TwinCAT's own names) "Frm0WcState" -> "frm0_wc_state".
    """
    if split_camel:
        text = _CAMEL_HUMP.sub(r"\1_\2", text)
    marked = text.replace(CHANNEL, _MARK)
    snaked = _NOT_ALNUM.sub("_", marked).strip("_").lower()
    if not snaked:
        return "unnamed"
    if snaked[0].isdigit():
        snaked = "n" + snaked
    elif snaked[0] == _MARK:
        snaked = "ch" + snaked
    return snaked.replace(_MARK, CHANNEL)


def take_unique(name: str, taken: set[str], suffix: str = "") -> str:
    """The first free of `name`, `name_<suffix>` (if given), then `_2`, `_3`...
    appended; it is added to `taken`. The one rule for names that must differ
    from their siblings (symbol, member, CoE and attribute names)."""
    candidate = name
    if candidate in taken and suffix:
        name = candidate = f"{name}_{suffix}"
    number = 2
    while candidate in taken:
        candidate = f"{name}_{number}"
        number += 1
    taken.add(candidate)
    return candidate
