"""EPICS threads at ordinary priority, and no memory locked, even as root.

EPICS base gives its threads real-time (SCHED_FIFO) priorities whenever it
may, and then locks every page the process maps, now and later
(`mlockall(MCL_CURRENT | MCL_FUTURE)` at iocInit). As root that is always:
each thread's 8 MB stack and 64 MB malloc arena become resident, and the
IOC held 290-330 MB where the same IOC run as an ordinary user (the image's
`ioc` user) held 120-140 MB; a container's memory limit counts all of it.
A Python IOC gains nothing from either (its timing is the interpreter's), so
the IOC gives up the right to real-time scheduling before EPICS starts: EPICS
then finds no priority range, as for an ordinary user, and locks nothing.
"""

from __future__ import annotations

import ctypes
import logging
import sys
from typing import Final

logger = logging.getLogger(__name__)

CAP_SYS_NICE: Final = 23
"""The capability that allows real-time scheduling (linux/capability.h)."""
_CAPABILITY_VERSION_3: Final = 0x20080522


class _CapHeader(ctypes.Structure):
    _fields_ = (("version", ctypes.c_uint32), ("pid", ctypes.c_int))


class _CapData(ctypes.Structure):
    _fields_ = (
        ("effective", ctypes.c_uint32),
        ("permitted", ctypes.c_uint32),
        ("inheritable", ctypes.c_uint32),
    )


def give_up_realtime_scheduling() -> bool:
    """Drop CAP_SYS_NICE from this thread (threads it starts inherit that);
    True if it was held. Call before EPICS starts its first thread."""
    if not sys.platform.startswith("linux"):
        return False
    libc = ctypes.CDLL(None, use_errno=True)
    header = _CapHeader(_CAPABILITY_VERSION_3, 0)
    data = (_CapData * 2)()
    if libc.capget(ctypes.byref(header), data) != 0:
        return False
    bit = 1 << CAP_SYS_NICE
    if not data[0].effective & bit:
        return False
    data[0].effective &= ~bit
    data[0].permitted &= ~bit
    data[0].inheritable &= ~bit
    if libc.capset(ctypes.byref(header), data) != 0:
        error = ctypes.get_errno()
        logger.warning("cannot give up real-time scheduling: errno %d", error)
        return False
    logger.debug("EPICS threads run at ordinary priority (CAP_SYS_NICE dropped)")
    return True
