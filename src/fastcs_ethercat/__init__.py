"""fastcs-ethercat: Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs."""

__version__ = "0.1.0"
"""The one place the version is written: pyproject.toml reads it from here
(importing the package costs no metadata lookup)."""

__all__ = ["__version__"]
