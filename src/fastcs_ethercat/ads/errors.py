"""The one exception the codec raises for bytes it cannot accept."""

from __future__ import annotations

from fastcs_ethercat.ads.constants import AdsReturnCode


class AdsCodecError(ValueError):
    """Bytes that break the ADS layout, with the return code a server answers.

    A server turns `return_code` into the `result` of its response (or the AMS
    error code); a client treats it as a protocol violation of its peer.
    """

    def __init__(
        self,
        message: str,
        return_code: AdsReturnCode = AdsReturnCode.DEVICE_INVALID_SIZE,
    ) -> None:
        super().__init__(message)
        self.return_code = return_code
