"""The old home of `read_text_bounded`, kept so imports of it keep working;
every bounded read lives in `fastcs_ethercat.bounded`."""

from fastcs_ethercat.bounded import read_text_bounded

__all__ = ["read_text_bounded"]
