"""fastcs-ethercat: Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("fastcs-ethercat")
except PackageNotFoundError:  # running from a source tree without install
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
