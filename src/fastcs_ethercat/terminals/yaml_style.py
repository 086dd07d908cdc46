"""How values look in the terminal YAML: hex numbers, flow lists, text blocks.

The models mark fields with these annotations; `model_dump(mode="python")`
then yields `HexInt`/`FlowList`/`FlowDict` values the dumper writes as
`0x1a00`, `[1, 2]` and `{value: 0, text: Signed}`. In JSON mode (and in the
JSON schema) they are plain ints, lists and objects.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field, SerializationInfo, SerializerFunctionWrapHandler
from pydantic.functional_serializers import PlainSerializer, WrapSerializer


class HexInt(int):
    """An int the dumper writes in hex with a fixed number of digits."""

    digits: int

    def __new__(cls, value: int, digits: int) -> HexInt:
        made = super().__new__(cls, value)
        made.digits = digits
        return made

    def yaml_text(self) -> str:
        return f"0x{int(self):0{self.digits}x}"


class FlowList:
    """A list the dumper writes on one line: `[0x1a00, 0x1a02]`.

    Not a list subclass: pydantic would copy a list back into a plain list.
    """

    def __init__(self, items: list[Any]) -> None:
        self.items = items


class FlowDict:
    """A mapping the dumper writes on one line: `{value: 0, text: Signed}`."""

    def __init__(self, items: dict[str, Any]) -> None:
        self.items = items


def _hex(digits: int) -> PlainSerializer:
    def serialize(value: int, info: SerializationInfo) -> int:
        return HexInt(value, digits) if info.mode == "python" else value

    return PlainSerializer(serialize)


def _flow_list(
    value: list[Any], handler: SerializerFunctionWrapHandler, info: SerializationInfo
) -> Any:
    dumped = handler(value)
    return FlowList(dumped) if info.mode == "python" else dumped


def _flow_dict(
    value: Any, handler: SerializerFunctionWrapHandler, info: SerializationInfo
) -> Any:
    dumped = handler(value)
    return FlowDict(dumped) if info.mode == "python" else dumped


Hex8 = Annotated[int, Field(ge=0, le=0xFF), _hex(2)]
"""A CoE sub-index: `0x11`."""
Hex16 = Annotated[int, Field(ge=0, le=0xFFFF), _hex(4)]
"""A PDO or CoE index: `0x1a00`."""
Hex32 = Annotated[int, Field(ge=0, le=0xFFFFFFFF), _hex(8)]
"""A vendor id, product code or revision: `0x0c203052`."""

FLOW_LIST = WrapSerializer(_flow_list)
FLOW_DICT = WrapSerializer(_flow_dict)
