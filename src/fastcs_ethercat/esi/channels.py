"""Find the channel number in a PDO name and turn the name into a template.

Beckhoff names per-channel PDOs in two ways (seen in the real files):
"AI Standard Channel 1", "PAI Samples 10 Channel 1", "MTI Inputs 2x Channel 3"
(the word "Channel" then the number) and "Ch1 Sample", "Ch2 CycleCount"
("Ch" glued to the number). Other digits are not channels: "Samples 10" is an
oversampling factor, "L1" a mains phase, "NextSync1Time" a sync unit.
"""

from __future__ import annotations

import re

_CHANNEL = re.compile(r"(?:(?<=\bChannel )|(?<=\bCh))(\d+)(?!\d)")
CHANNEL_FIELD = "{channel}"


def channel_template(name: str) -> tuple[int | None, str | None]:
    """(channel number, template) for a PDO name; (None, None) if none found.

    The template is a `str.format` pattern: other braces are doubled, so
    `template.format(channel=n)` gives back the name of channel n.
    """
    matches = list(_CHANNEL.finditer(name))
    if not matches:
        return None, None
    match = matches[-1]
    head = name[: match.start()].replace("{", "{{").replace("}", "}}")
    tail = name[match.end() :].replace("{", "{{").replace("}", "}}")
    return int(match.group(1)), f"{head}{CHANNEL_FIELD}{tail}"
