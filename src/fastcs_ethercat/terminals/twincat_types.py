"""Sizes of the TwinCAT primitive types that appear in I/O symbols."""

from __future__ import annotations

import re

BIT_SIZES: dict[str, int] = {
    "BIT": 1,
    "BOOL": 1,
    "SINT": 8,
    "USINT": 8,
    "BYTE": 8,
    "INT": 16,
    "UINT": 16,
    "WORD": 16,
    "DINT": 32,
    "UDINT": 32,
    "DWORD": 32,
    "REAL": 32,
    "LINT": 64,
    "ULINT": 64,
    "LWORD": 64,
    "LREAL": 64,
}

_BITN = re.compile(r"^BIT([2-8])$")
