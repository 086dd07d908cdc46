"""The FastCS controller tree: root, one per EtherCAT master, one per terminal."""

from fastcs_ethercat.ioc.controllers.master import MasterController
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.ioc.controllers.terminal import (
    GenericTerminalController,
    TerminalController,
)

__all__ = [
    "GenericTerminalController",
    "MasterController",
    "RootController",
    "TerminalController",
]
