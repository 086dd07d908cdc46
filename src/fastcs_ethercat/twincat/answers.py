"""What a simulated read answers: an ADS return code and the bytes read."""

from __future__ import annotations

from fastcs_ethercat.ads.constants import AdsReturnCode

Outcome = tuple[int, bytes]
"""(ADS return code, data); data is empty unless the code is NO_ERROR."""


def fit(data: bytes, length: int) -> Outcome:
    """The answer to a read of `length` bytes: all of `data` if it fits."""
    if length < len(data):
        return AdsReturnCode.DEVICE_INVALID_SIZE, b""
    return AdsReturnCode.NO_ERROR, data
