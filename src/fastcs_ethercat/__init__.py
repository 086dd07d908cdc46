"""fastcs-ethercat: Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs."""

try:  # written by setuptools-scm at every build and install, from the git tag
    from fastcs_ethercat._version import __version__
except ImportError:  # a source tree never built or installed
    from importlib.metadata import PackageNotFoundError, version

    try:
        __version__ = version("fastcs-ethercat")
    except PackageNotFoundError:
        __version__ = "0+unknown"

__all__ = ["__version__"]
