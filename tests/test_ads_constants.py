"""Protocol numbers agree with pyads' constants and the facts file."""

from __future__ import annotations

import pyads.constants as pc
import pytest
from pyads.errorcodes import ERROR_CODES

from fastcs_ethercat.ads.client import unreachable
from fastcs_ethercat.ads.constants import (
    ADS_TCP_PORT,
    ADS_UDP_PORT,
    MAX_SUM_SUB_COMMANDS,
    RESPONSE_FLAGS,
    AdsDataType,
    AdsReturnCode,
    AdsState,
    AmsCommand,
    AmsPort,
    IndexGroup,
    StateFlag,
    SymbolFlag,
    TransmissionMode,
    describe_return_code,
    device_port,
)
from tests.ads_codec import coe_index_offset


def test_command_ids_match_pyads() -> None:
    assert AmsCommand.READ_DEVICE_INFO == pc.ADSCOMMAND_READDEVICEINFO
    assert AmsCommand.READ == pc.ADSCOMMAND_READ
    assert AmsCommand.WRITE == pc.ADSCOMMAND_WRITE
    assert AmsCommand.READ_STATE == pc.ADSCOMMAND_READSTATE
    assert AmsCommand.WRITE_CONTROL == pc.ADSCOMMAND_WRITECTRL
    assert AmsCommand.ADD_DEVICE_NOTIFICATION == pc.ADSCOMMAND_ADDDEVICENOTE
    assert AmsCommand.DELETE_DEVICE_NOTIFICATION == pc.ADSCOMMAND_DELDEVICENOTE
    assert AmsCommand.DEVICE_NOTIFICATION == pc.ADSCOMMAND_DEVICENOTE
    assert AmsCommand.READ_WRITE == pc.ADSCOMMAND_READWRITE
    assert StateFlag.ADS_COMMAND == pc.ADSSTATEFLAG_COMMAND
    assert StateFlag.RESPONSE == pc.ADSSTATEFLAG_REQRESP
    assert RESPONSE_FLAGS == 0x0005


@pytest.mark.parametrize("state", list(AdsState))
def test_ads_states_match_pyads(state: AdsState) -> None:
    pyads_name = "ADSSTATE_" + state.name.replace("_", "").replace(
        "SAVECONFIG", "SAVECFG"
    )
    pyads_name = pyads_name.replace("LOADCONFIG", "LOADCFG")
    assert getattr(pc, pyads_name) == state


@pytest.mark.parametrize("data_type", list(AdsDataType))
def test_ads_type_ids_match_pyads(data_type: AdsDataType) -> None:
    assert getattr(pc, f"ADST_{data_type.name}") == data_type


def test_index_groups_match_pyads() -> None:
    pairs = {
        IndexGroup.SYM_HANDLE_BY_NAME: pc.ADSIGRP_SYM_HNDBYNAME,
        IndexGroup.SYM_VALUE_BY_NAME: pc.ADSIGRP_SYM_VALBYNAME,
        IndexGroup.SYM_VALUE_BY_HANDLE: pc.ADSIGRP_SYM_VALBYHND,
        IndexGroup.SYM_RELEASE_HANDLE: pc.ADSIGRP_SYM_RELEASEHND,
        IndexGroup.SYM_INFO_BY_NAME: pc.ADSIGRP_SYM_INFOBYNAME,
        IndexGroup.SYM_VERSION: pc.ADSIGRP_SYM_VERSION,
        IndexGroup.SYM_INFO_BY_NAME_EX: pc.ADSIGRP_SYM_INFOBYNAMEEX,
        IndexGroup.SYM_UPLOAD: pc.ADSIGRP_SYM_UPLOAD,
        IndexGroup.SYM_UPLOAD_INFO: pc.ADSIGRP_SYM_UPLOADINFO,
        IndexGroup.SYM_DT_UPLOAD: pc.ADSIGRP_SYM_DT_UPLOAD,
        IndexGroup.SYM_UPLOAD_INFO_2: pc.ADSIGRP_SYM_UPLOADINFO2,
        IndexGroup.IO_IMAGE_RW_INPUT_BYTES: pc.ADSIGRP_IOIMAGE_RWIB,
        IndexGroup.IO_IMAGE_RW_INPUT_BITS: pc.ADSIGRP_IOIMAGE_RWIX,
        IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES: pc.ADSIGRP_IOIMAGE_RWOB,
        IndexGroup.IO_IMAGE_RW_OUTPUT_BITS: pc.ADSIGRP_IOIMAGE_RWOX,
        IndexGroup.SUMUP_READ: pc.ADSIGRP_SUMUP_READ,
        IndexGroup.SUMUP_WRITE: pc.ADSIGRP_SUMUP_WRITE,
        IndexGroup.DEVICE_DATA: pc.ADSIGRP_DEVICE_DATA,
    }
    for ours, theirs in pairs.items():
        assert ours == theirs, ours.name
    assert IndexGroup.SUMUP_READ_WRITE == 0xF082
    assert IndexGroup.COE_SDO == 0xF302


def test_ports_and_limits() -> None:
    assert AmsPort.IO_SERVER == pc.PORT_IO == 300
    assert AmsPort.SYSTEM_SERVICE == pc.PORT_SYSTEMSERVICE
    assert ADS_UDP_PORT == pc.PORT_REMOTE_UDP == 48899
    assert ADS_TCP_PORT == 48898
    assert AmsPort.ETHERCAT_MASTER == 0xFFFF
    assert device_port(1) == 27905 == 0x6D01
    assert MAX_SUM_SUB_COMMANDS == pc.MAX_ADS_SUB_COMMANDS


def test_transmission_modes_and_symbol_flags() -> None:
    assert TransmissionMode.NO_TRANSMISSION == pc.ADSTRANS_NOTRANS
    assert TransmissionMode.CLIENT_CYCLE == pc.ADSTRANS_CLIENTCYCLE
    assert TransmissionMode.SERVER_CYCLE == pc.ADSTRANS_SERVERCYCLE
    assert TransmissionMode.SERVER_ON_CHANGE == pc.ADSTRANS_SERVERONCHA
    assert SymbolFlag.BIT_VALUE == pc.ADSSYMBOLFLAG_BITVALUE
    assert SymbolFlag.TYPE_GUID == pc.ADSSYMBOLFLAG_TYPEGUID
    assert SymbolFlag.READ_ONLY == pc.ADSSYMBOLFLAG_READONLY


NOT_IN_PYADS = {
    AdsReturnCode.CLIENT_NO_AMS_ADDR,  # 0x749
    AdsReturnCode.SOCKET_CONNECTION_RESET,  # Winsock 10054
    AdsReturnCode.SOCKET_HOST_NOT_FOUND,  # Winsock 11001
}


@pytest.mark.parametrize("code", [c for c in AdsReturnCode if c not in NOT_IN_PYADS])
def test_return_codes_are_known_to_pyads(code: AdsReturnCode) -> None:
    assert int(code) in ERROR_CODES


def test_facts_file_return_codes() -> None:
    facts = {
        0x6: "TARGET_PORT_NOT_FOUND",
        0x7: "TARGET_MACHINE_NOT_FOUND",
        0x700: "DEVICE_ERROR",
        0x701: "DEVICE_SERVICE_NOT_SUPPORTED",
        0x702: "DEVICE_INVALID_GROUP",
        0x703: "DEVICE_INVALID_OFFSET",
        0x704: "DEVICE_INVALID_ACCESS",
        0x705: "DEVICE_INVALID_SIZE",
        0x706: "DEVICE_INVALID_DATA",
        0x707: "DEVICE_NOT_READY",
        0x708: "DEVICE_BUSY",
        0x710: "DEVICE_SYMBOL_NOT_FOUND",
        0x711: "DEVICE_SYMBOL_VERSION_INVALID",
        0x713: "DEVICE_TRANSMISSION_MODE_NOT_SUPPORTED",
        0x714: "DEVICE_NOTIFY_HANDLE_INVALID",
        0x716: "DEVICE_NO_MORE_HANDLES",
        0x717: "DEVICE_INVALID_WATCH_SIZE",
        0x745: "CLIENT_SYNC_TIMEOUT",
    }
    for code, name in facts.items():
        assert AdsReturnCode(code).name == name
    assert describe_return_code(0x702) == "DEVICE_INVALID_GROUP (0x702)"
    assert describe_return_code(0x9999) == "0x9999"
    assert describe_return_code(-1) == "client error -1"


def test_unreachable_codes_are_told_from_answered_errors() -> None:
    """No answer (timeouts, routing, ports, pyads' own) vs an error answered."""
    assert all(
        unreachable(code) for code in (0x745, 0x719, 0x6, 0x7, -1, 0x274D, 0x2AF9)
    )
    assert not any(unreachable(code) for code in (0x701, 0x705, 0x710, 0x711))


def test_coe_index_offset() -> None:
    assert coe_index_offset(0x1018, 1) == 0x1018_0001
    assert coe_index_offset(0x8000, 2, complete_access=True) == 0x8000_0102
