"""Numbers of the ADS protocol and the TwinCAT I/O server, with readable names.

Sources: Beckhoff's ADS specification and return-code tables, the EtherCAT
ADS interface, pyads' constants, and the team's facts file (sections 1-6).
"""

from __future__ import annotations

from enum import IntEnum, IntFlag
from typing import Final

ADS_TCP_PORT: Final = 48898
"""AMS/TCP port every TwinCAT router listens on."""

ADS_UDP_PORT: Final = 48899
"""UDP port of the discovery and add-route service."""

AMS_TCP_HEADER_SIZE: Final = 6
AMS_HEADER_SIZE: Final = 32

MAX_SUM_SUB_COMMANDS: Final = 500
"""Beckhoff's recommended maximum of sub-commands per sum request (pyads too)."""


class AmsPort(IntEnum):
    """Well-known AMS ports of a TwinCAT system."""

    LOGGER = 100
    EVENT_LOGGER = 110
    REALTIME_CORE = 200
    IO_SERVER = 300
    NC = 500
    PLC_RUNTIME_1 = 851
    SYSTEM_SERVICE = 10000
    DEVICE_BASE = 27904
    """Device n serves its process image and symbols on DEVICE_BASE + n."""
    ETHERCAT_MASTER = 0xFFFF
    """The EtherCAT master of a device, addressed with the device's own NetId."""


def device_port(device_id: int) -> int:
    """AMS port of I/O device `device_id` (27905 for device 1)."""
    return AmsPort.DEVICE_BASE + device_id


class AmsCommand(IntEnum):
    """ADS command ids carried in the AMS header."""

    INVALID = 0
    READ_DEVICE_INFO = 1
    READ = 2
    WRITE = 3
    READ_STATE = 4
    WRITE_CONTROL = 5
    ADD_DEVICE_NOTIFICATION = 6
    DELETE_DEVICE_NOTIFICATION = 7
    DEVICE_NOTIFICATION = 8
    READ_WRITE = 9


class StateFlag(IntFlag):
    """Bits of the AMS header's state flags."""

    RESPONSE = 0x0001
    NO_RETURN = 0x0002
    ADS_COMMAND = 0x0004
    SYSTEM_COMMAND = 0x0008
    HIGH_PRIORITY = 0x0010
    TIMESTAMP_ADDED = 0x0020
    UDP = 0x0040
    INIT_COMMAND = 0x0080
    BROADCAST = 0x8000


REQUEST_FLAGS: Final = StateFlag.ADS_COMMAND
"""State flags of an ADS request over TCP (0x0004)."""

RESPONSE_FLAGS: Final = StateFlag.ADS_COMMAND | StateFlag.RESPONSE
"""State flags of an ADS response over TCP (0x0005)."""


class AdsState(IntEnum):
    """ADS states (ReadState / WriteControl); a running TwinCAT answers RUN."""

    INVALID = 0
    IDLE = 1
    RESET = 2
    INIT = 3
    START = 4
    RUN = 5
    STOP = 6
    SAVE_CONFIG = 7
    LOAD_CONFIG = 8
    POWER_FAILURE = 9
    POWER_GOOD = 10
    ERROR = 11
    SHUTDOWN = 12
    SUSPEND = 13
    RESUME = 14
    CONFIG = 15
    RECONFIG = 16


class TransmissionMode(IntEnum):
    """AddDeviceNotification transmission modes (Beckhoff ADSTRANSMODE).

    pyads names 2 `ADSTRANS_CLIENT1REQ`; Beckhoff's TcAdsDef.h names it
    client-on-change and gives client-1-request the value 10.
    """

    NO_TRANSMISSION = 0
    CLIENT_CYCLE = 1
    CLIENT_ON_CHANGE = 2
    SERVER_CYCLE = 3
    SERVER_ON_CHANGE = 4
    SERVER_CYCLE_2 = 5
    SERVER_ON_CHANGE_2 = 6
    CLIENT_1_REQUEST = 10


NOTIFICATION_TIME_UNITS_PER_MS: Final = 10_000
"""Max delay and cycle time travel in 100 ns units: milliseconds x 10 000."""


class IndexGroup(IntEnum):
    """Reserved ADS index groups (symbol services, I/O image, sum commands)."""

    PLC_MEMORY = 0x4020
    PLC_DATA = 0x4040
    IO_SERVER_DEVICES = 0x5000
    """Device list on the I/O server; device n answers at 0x5000 + n."""
    SYM_TAB = 0xF000
    SYM_NAME = 0xF001
    SYM_VAL = 0xF002
    SYM_HANDLE_BY_NAME = 0xF003
    SYM_VALUE_BY_NAME = 0xF004
    SYM_VALUE_BY_HANDLE = 0xF005
    SYM_RELEASE_HANDLE = 0xF006
    SYM_INFO_BY_NAME = 0xF007
    SYM_VERSION = 0xF008
    SYM_INFO_BY_NAME_EX = 0xF009
    SYM_DOWNLOAD = 0xF00A
    SYM_UPLOAD = 0xF00B
    SYM_UPLOAD_INFO = 0xF00C
    SYM_DOWNLOAD_2 = 0xF00D
    SYM_DT_UPLOAD = 0xF00E
    SYM_UPLOAD_INFO_2 = 0xF00F
    SYM_NOTE = 0xF010
    IO_IMAGE_RW_INPUT_BYTES = 0xF020
    IO_IMAGE_RW_INPUT_BITS = 0xF021
    IO_IMAGE_INPUT_SIZE = 0xF025
    IO_IMAGE_RW_OUTPUT_BYTES = 0xF030
    IO_IMAGE_RW_OUTPUT_BITS = 0xF031
    IO_IMAGE_OUTPUT_SIZE = 0xF035
    IO_IMAGE_CLEAR_INPUTS = 0xF040
    IO_IMAGE_CLEAR_OUTPUTS = 0xF050
    SUMUP_READ = 0xF080
    SUMUP_WRITE = 0xF081
    SUMUP_READ_WRITE = 0xF082
    SUMUP_READ_EX = 0xF083
    SUMUP_READ_EX_2 = 0xF084
    SUMUP_ADD_DEVICE_NOTIFICATION = 0xF085
    SUMUP_DELETE_DEVICE_NOTIFICATION = 0xF086
    DEVICE_DATA = 0xF100
    COE_SDO = 0xF302


class IoServerDeviceOffset(IntEnum):
    """Index offsets on the I/O server (port 300) below group 0x5000 (+ id)."""

    DEVICE_IDS = 1
    """On 0x5000: u16 count then u16 per device. On 0x5000+id: device name."""
    DEVICE_COUNT = 2
    """On 0x5000: device count u32."""
    DEVICE_NETID = 5
    """On 0x5000+id: the device's own AMS NetId (6 bytes)."""
    DEVICE_TYPE = 7
    """On 0x5000+id: device type u16 (94 = EtherCAT master)."""


IO_DEVICE_TYPE_ETHERCAT: Final = 94
"""Device type of an EtherCAT master in catio's dumps of real racks."""


class EtherCatMasterGroup(IntEnum):
    """Index groups of the EtherCAT master (device NetId, port 0xFFFF)."""

    MASTER_STATE = 0x03
    """Offset 0x100: master state u16."""
    SLAVE_COUNT = 0x06
    SLAVE_ADDRESSES = 0x07
    SLAVE_STATES = 0x09
    """Offset 0: (AL state u8, link state u8) per slave; offset = address: one."""
    FRAME_COUNTERS = 0x0C
    SLAVE_IDENTITY = 0x11
    """Offset = slave address: vendor, product, revision, serial (4 x u32)."""
    SLAVE_CRC_COUNTERS = 0x12


MASTER_STATE_OFFSET: Final = 0x100
"""Index offset of the master state within EtherCatMasterGroup.MASTER_STATE."""

COE_COMPLETE_ACCESS_FLAG: Final = 0x100
"""Bit 8 of a CoE SDO index offset requests complete access."""


class AdsDataType(IntEnum):
    """ADS type ids of symbol and data-type entries (ADST_*)."""

    VOID = 0
    INT16 = 2
    INT32 = 3
    REAL32 = 4
    REAL64 = 5
    INT8 = 16
    UINT8 = 17
    UINT16 = 18
    UINT32 = 19
    INT64 = 20
    UINT64 = 21
    STRING = 30
    WSTRING = 31
    REAL80 = 32
    BIT = 33
    BIGTYPE = 65


class SymbolFlag(IntFlag):
    """Flags of a symbol entry (ADSSYMBOLFLAG_*).

    TYPE_GUID means a 16-byte type GUID follows the comment; ATTRIBUTES means
    an attribute list follows. Both live in the entry's extra bytes.
    """

    PERSISTENT = 0x0001
    BIT_VALUE = 0x0002
    REFERENCE_TO = 0x0004
    TYPE_GUID = 0x0008
    TC_COM_INTERFACE_POINTER = 0x0010
    READ_ONLY = 0x0020
    INTERFACE_METHOD_ACCESS = 0x0040
    METHOD_DEREF = 0x0080
    CONTEXT_MASK = 0x0F00
    ATTRIBUTES = 0x1000
    STATIC = 0x2000
    INIT_ON_RESET = 0x4000
    EXTENDED_FLAGS = 0x8000


class DataTypeFlag(IntFlag):
    """Flags of a data-type entry (ADSDATATYPEFLAG_*)."""

    DATA_TYPE = 0x0000_0001
    DATA_ITEM = 0x0000_0002
    REFERENCE_TO = 0x0000_0004
    METHOD_DEREF = 0x0000_0008
    OVERSAMPLE = 0x0000_0010
    BIT_VALUES = 0x0000_0020
    PROPERTY_ITEM = 0x0000_0040
    TYPE_GUID = 0x0000_0080
    PERSISTENT = 0x0000_0100
    COPY_MASK = 0x0000_0200
    TC_COM_INTERFACE_POINTER = 0x0000_0400
    METHOD_INFOS = 0x0000_0800
    ATTRIBUTES = 0x0000_1000
    ENUM_INFOS = 0x0000_2000
    ALIGNED = 0x0001_0000
    STATIC = 0x0002_0000


class AdsReturnCode(IntEnum):
    """ADS return codes (result fields and the AMS header's error code)."""

    NO_ERROR = 0x0
    INTERNAL_ERROR = 0x1
    NO_REALTIME = 0x2
    ALLOCATION_LOCKED_MEMORY = 0x3
    MAILBOX_FULL = 0x4
    WRONG_HMSG = 0x5
    TARGET_PORT_NOT_FOUND = 0x6
    TARGET_MACHINE_NOT_FOUND = 0x7
    UNKNOWN_COMMAND_ID = 0x8
    INVALID_TASK_ID = 0x9
    NO_IO = 0xA
    UNKNOWN_AMS_COMMAND = 0xB
    WIN32_ERROR = 0xC
    PORT_NOT_CONNECTED = 0xD
    INVALID_AMS_LENGTH = 0xE
    INVALID_AMS_NETID = 0xF
    LOW_INSTALLATION_LEVEL = 0x10
    NO_DEBUG_AVAILABLE = 0x11
    PORT_DISABLED = 0x12
    PORT_ALREADY_CONNECTED = 0x13
    AMS_SYNC_WIN32_ERROR = 0x14
    AMS_SYNC_TIMEOUT = 0x15
    AMS_SYNC_AMS_ERROR = 0x16
    AMS_SYNC_NO_INDEX_MAP = 0x17
    INVALID_AMS_PORT = 0x18
    NO_MEMORY = 0x19
    TCP_SEND_ERROR = 0x1A
    HOST_UNREACHABLE = 0x1B
    INVALID_AMS_FRAGMENT = 0x1C
    DEVICE_ERROR = 0x700
    DEVICE_SERVICE_NOT_SUPPORTED = 0x701
    DEVICE_INVALID_GROUP = 0x702
    DEVICE_INVALID_OFFSET = 0x703
    DEVICE_INVALID_ACCESS = 0x704
    DEVICE_INVALID_SIZE = 0x705
    DEVICE_INVALID_DATA = 0x706
    DEVICE_NOT_READY = 0x707
    DEVICE_BUSY = 0x708
    DEVICE_INVALID_CONTEXT = 0x709
    DEVICE_NO_MEMORY = 0x70A
    DEVICE_INVALID_PARAM = 0x70B
    DEVICE_NOT_FOUND = 0x70C
    DEVICE_SYNTAX = 0x70D
    DEVICE_INCOMPATIBLE = 0x70E
    DEVICE_EXISTS = 0x70F
    DEVICE_SYMBOL_NOT_FOUND = 0x710
    DEVICE_SYMBOL_VERSION_INVALID = 0x711
    DEVICE_INVALID_STATE = 0x712
    DEVICE_TRANSMISSION_MODE_NOT_SUPPORTED = 0x713
    DEVICE_NOTIFY_HANDLE_INVALID = 0x714
    DEVICE_CLIENT_UNKNOWN = 0x715
    DEVICE_NO_MORE_HANDLES = 0x716
    DEVICE_INVALID_WATCH_SIZE = 0x717
    DEVICE_NOT_INITIALIZED = 0x718
    DEVICE_TIMEOUT = 0x719
    DEVICE_NO_INTERFACE = 0x71A
    DEVICE_INVALID_INTERFACE = 0x71B
    DEVICE_INVALID_CLSID = 0x71C
    DEVICE_INVALID_OBJECT_ID = 0x71D
    DEVICE_PENDING = 0x71E
    DEVICE_ABORTED = 0x71F
    DEVICE_WARNING = 0x720
    DEVICE_INVALID_ARRAY_INDEX = 0x721
    DEVICE_SYMBOL_NOT_ACTIVE = 0x722
    DEVICE_ACCESS_DENIED = 0x723
    DEVICE_LICENSE_NOT_FOUND = 0x724
    CLIENT_ERROR = 0x740
    CLIENT_INVALID_PARAM = 0x741
    CLIENT_LIST_EMPTY = 0x742
    CLIENT_VAR_USED = 0x743
    CLIENT_DUPLICATE_INVOKE_ID = 0x744
    CLIENT_SYNC_TIMEOUT = 0x745
    """Raised by the client library when no answer arrives, never sent."""
    CLIENT_W32_ERROR = 0x746
    CLIENT_TIMEOUT_INVALID = 0x747
    CLIENT_PORT_NOT_OPEN = 0x748
    CLIENT_NO_AMS_ADDR = 0x749
    CLIENT_SYNC_INTERNAL = 0x750
    CLIENT_ADD_HASH = 0x751
    CLIENT_REMOVE_HASH = 0x752
    CLIENT_NO_MORE_SYMBOLS = 0x753
    CLIENT_SYNC_RES_INVALID = 0x754
    CLIENT_SYNC_PORT_LOCKED = 0x755
    SOCKET_CONNECTION_RESET = 0x2746
    """WSAECONNRESET (10054): the peer dropped the connection."""
    SOCKET_CONNECTION_TIMEOUT = 0x274C
    """WSAETIMEDOUT (10060): the TCP connection was not established in time."""
    SOCKET_CONNECTION_REFUSED = 0x274D
    """WSAECONNREFUSED (10061): nothing listens on the target's ADS port."""
    SOCKET_HOST_UNREACHABLE = 0x2751
    """WSAEHOSTUNREACH (10065): no route to the target host."""
    SOCKET_HOST_NOT_FOUND = 0x2AF9
    """WSAHOST_NOT_FOUND (11001): the host name does not resolve."""


def describe_return_code(code: int) -> str:
    """A readable name for any return code, known or not."""
    if code < 0:  # pyads' own failures carry no ADS code
        return f"client error {code}"
    try:
        return f"{AdsReturnCode(code).name} (0x{code:X})"
    except ValueError:
        return f"0x{code:X}"
