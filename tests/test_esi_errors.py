"""Bad input gives one-line `UserError`s naming file, line and device."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi import build_catalog, parse_all, parse_file

BAD = Path(__file__).resolve().parent / "data" / "esi" / "bad"


def one_line(error: UserError | str) -> str:
    text = str(error)
    assert "\n" not in text
    return text


def test_truncated_file_names_line_and_device() -> None:
    path = BAD / "truncated.xml"
    with pytest.raises(UserError) as caught:
        parse_file(path)
    message = one_line(caught.value)
    assert message.startswith(f"{path}:")
    line = int(message.split(":")[1])
    assert line >= len(path.read_bytes().splitlines())
    assert "device EL1084 revision #x00100000" in message
    assert "not well-formed XML" in message


def test_malformed_xml_names_line_and_device() -> None:
    path = BAD / "malformed.xml"
    broken_line = next(
        number
        for number, text in enumerate(path.read_text().splitlines(), 1)
        if "</Nme>" in text
    )
    with pytest.raises(UserError) as caught:
        parse_file(path)
    message = one_line(caught.value)
    assert message.startswith(f"{path}:{broken_line}: device EL1084 revision")
    assert "mismatch" in message


def test_not_an_esi_file() -> None:
    with pytest.raises(UserError, match=r"not-esi.xml:3: not an ESI file.*TcSmProject"):
        parse_file(BAD / "not-esi.xml")


def test_empty_file() -> None:
    with pytest.raises(UserError, match=r"empty.xml:1: not well-formed XML"):
        parse_file(BAD / "empty.xml")


def test_missing_elements_spare_the_other_devices() -> None:
    path = BAD / "missing-elements.xml"
    result = parse_file(path)
    assert [(d.type_name, d.revision) for d in result.devices] == [
        ("EL1084", 0x00100000)
    ]
    messages = [one_line(warning) for warning in result.warnings]
    lines = path.read_text().splitlines()
    expected = [
        ("device EL1014 revision #x00100000", "PDO entry 'Input' has no <BitLen>"),
        ("device EL1014 revision #x00110000", "has no ProductCode"),
        ("device EL1084 revision #x00110000", "entry BitLen 'one' is not a number"),
    ]
    assert len(messages) == len(expected)
    for message, (device, reason) in zip(messages, expected, strict=True):
        match = re.fullmatch(rf"{re.escape(str(path))}:(\d+): (.*)", message)
        assert match, message
        assert match.group(2).startswith(device) and reason in match.group(2)
        line = lines[int(match.group(1)) - 1]
        assert "<Entry>" in line or "<Type" in line or "<BitLen>" in line
    with pytest.raises(UserError, match="device EL1014 revision #x00100000"):
        parse_file(path, strict=True)


def test_unknown_data_type_spares_the_other_device() -> None:
    path = BAD / "unknown-datatype.xml"
    result = parse_file(path)
    assert [d.type_name for d in result.devices] == ["EL1014"]
    (message,) = [one_line(w) for w in result.warnings]
    line = int(message.split(":")[1])
    assert "<Object>" in path.read_text().splitlines()[line - 1]
    assert message.endswith(
        "device EL4132 revision #x00000000: CoE object #x4061 "
        "'Feature bits' uses unknown data type 'DT4061'"
    )


def test_catalog_and_parse_all_collect_warnings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    catalog = build_catalog(BAD)
    # The listing only checks identities; device content is checked on load.
    assert sorted((e.type_name, e.revision) for e in catalog.entries) == [
        ("EL1014", 0x00100000),  # missing-elements.xml (entry without BitLen)
        ("EL1014", 0x00100000),  # unknown-datatype.xml
        ("EL1084", 0x00100000),
        ("EL1084", 0x00110000),  # BitLen "one"
        ("EL4132", 0x00000000),  # unknown data type
    ]
    with pytest.raises(UserError, match="unknown data type 'DT4061'"):
        catalog.load("EL4132")
    files_with_errors = {w.split(":")[0] for w in catalog.warnings}
    assert {Path(f).name for f in files_with_errors} >= {
        "empty.xml",
        "malformed.xml",
        "not-esi.xml",
        "truncated.xml",
        "missing-elements.xml",  # EL1014 #x00110000 without ProductCode
    }
    assert all("\n" not in w for w in catalog.warnings)
    result = parse_all(BAD)
    assert {d.type_name for d in result.devices} == {"EL1014", "EL1084"}
    assert len(result.warnings) == 4 + 3 + 1
    with pytest.raises(UserError):
        parse_all(BAD, strict=True)
