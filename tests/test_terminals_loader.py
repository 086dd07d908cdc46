"""Loading: files, directories, globs, catio's single-file layout; the registry."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import read_terminal_file, write_terminal_file
from fastcs_ethercat.terminals.loader import load_terminals, terminal_paths
from fastcs_ethercat.terminals.registry import variant_of
from fastcs_ethercat.terminals.symbols import expanded_symbols

from .test_terminals_support import TERMINALS

CATIO_FILE = """\
# Terminal Configuration (catio-terminals single-file layout)
composite_types:
  Status__Underrange_6Bits:
    description: 'Bit fields'
    ads_type: 65
    size: 2
    members: []
    bit_fields:
      - name: Status__Underrange
        bit: 0
terminal_types:
  EL3104:
    description: 4-channel Analog Input +/-10V 16-bit
    identity:
      vendor_id: 2
      product_code: 203436114
      revision_number: 1048576
    symbol_nodes:
      - name_template: AI Standard Channel {channel}
        index_group: 61489
        type_name: Status__Underrange_6Bits
        channels: 4
        access: Read-only
        fastcs_name: ai_standard_channel_{channel}
        selected: true
      - name_template: AI Standard Channel {channel}.Value
        index_group: 61489
        type_name: INT
        channels: 4
        access: Read-only
        fastcs_name: ai_standard_channel_{channel}_value
        selected: true
        bit_offset: 16
      - name_template: AI Compact Channel {channel}.Value
        index_group: 61489
        type_name: INT
        channels: 4
        access: Read-only
        fastcs_name: ai_compact_channel_{channel}_value
        selected: false
    coe_objects:
      - index: 32768
        name: AI Settings
        type_name: DT8000
        bit_size: 160
        access: rw
        subindices:
          - subindex: 1
            name: Enable user scale
            type_name: BOOL
            bit_size: 1
            access: rw
            default_data: '00'
            fastcs_name: enable_user_scale_8000
        fastcs_name: ai_settings
    group_type: AnaIn
    pdo_groups:
      - name: Standard
        is_default: true
        symbol_indices: [0, 1]
      - name: Compact
        is_default: false
        symbol_indices: [2]
    selected_pdo_group: Standard
  EL2024:
    description: 4-channel Digital Output 24V DC
    identity:
      vendor_id: 2
      product_code: 132657234
      revision_number: 1048576
    symbol_nodes:
      - name_template: Channel {channel}
        index_group: 61473
        type_name: BIT
        channels: 4
        access: Read/Write
        fastcs_name: channel_{channel}
    coe_objects: []
    group_type: DigOut
"""


@pytest.fixture
def terminals_copy(tmp_path: Path) -> Path:
    copy = tmp_path / "terminals"
    shutil.copytree(TERMINALS, copy)
    return copy


def test_directory_file_and_glob_sources(terminals_copy: Path) -> None:
    everything = terminal_paths([terminals_copy])
    assert len(everything) == 20 and all(p.suffix == ".yaml" for p in everything)
    analog_in = terminal_paths([str(terminals_copy / "EL31*.yaml")])
    assert [p.stem for p in analog_in] == ["EL3104", "EL3124"]
    mixed = load_terminals(
        [terminals_copy / "EL1014.yaml", str(terminals_copy / "EL31*.yaml")]
    )
    assert mixed.type_names() == ["EL1014", "EL3104", "EL3124"]
    again = terminal_paths([terminals_copy / "EL1014.yaml", terminals_copy])
    assert again.count(terminals_copy / "EL1014.yaml") == 1


def test_missing_sources_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no terminal YAML files match"):
        terminal_paths([str(tmp_path / "*.yaml")])
    with pytest.raises(UserError, match="no such terminal YAML file"):
        terminal_paths([tmp_path / "EL9999.yaml"])


def test_catio_single_file_layout_is_read(tmp_path: Path) -> None:
    path = tmp_path / "terminal_types.yaml"
    path.write_text(CATIO_FILE, encoding="utf-8")
    registry = load_terminals([path])
    assert registry.type_names() == ["EL2024", "EL3104"]
    el3104 = registry.get("EL3104").terminal
    standard, compact = el3104.symbol_nodes
    assert standard.name_template == "AI Standard Channel {channel}"
    assert standard.channels == [1, 2, 3, 4]
    assert [m.name for m in standard.members] == ["Value"]
    assert standard.members[0].bit_offset == 16 and standard.bit_size == 32
    assert standard.pdo_indices == [] and standard.members[0].coe == []
    assert compact.name_template == "AI Compact Channel {channel}"
    assert compact.type_name == "AI Compact Channel {channel}_TYPE"
    assert not compact.selected
    assert [g.symbol_indices for g in el3104.pdo_groups] == [[0], [1]]
    assert el3104.coe_objects[0].selected
    assert el3104.coe_objects[0].sub_items[0].fastcs_name == "enable_user_scale_8000"
    el2024 = registry.get("EL2024").terminal
    assert el2024.symbol_nodes[0].direction == "output"
    assert el2024.symbol_nodes[0].access == "rw"
    names = [s.name for s in expanded_symbols(el2024)]
    assert names == ["Channel 1", "Channel 2", "Channel 3", "Channel 4"]


def test_catio_layout_errors_name_the_place(tmp_path: Path) -> None:
    path = tmp_path / "terminal_types.yaml"
    path.write_text(CATIO_FILE.replace("        access: Read/Write\n",
                                       "        acess: Read/Write\n"),
                    encoding="utf-8")  # fmt: skip
    with pytest.raises(UserError) as caught:
        load_terminals([path])
    line = CATIO_FILE.splitlines().index("        access: Read/Write") + 1
    assert str(caught.value) == (
        f"{path}:{line}:9: terminal_types.EL2024.symbol_nodes[0].acess: "
        "unknown key 'acess'"
    )


def test_registry_exact_and_nearest_older_revision(terminals_copy: Path) -> None:
    el3104 = read_terminal_file(terminals_copy / "EL3104.yaml")["EL3104"]
    registry = load_terminals([str(terminals_copy / "EL3*.yaml")])
    code = el3104.identity.product_code
    exact = registry.lookup(code, 0x00110000)
    assert exact is not None and exact.exact and exact.type_name == "EL3104"
    newer = registry.lookup(code, 0x00150000, vendor_id=2)
    assert newer is not None and not newer.exact and newer.type_name == "EL3104"
    assert newer.requested_revision == 0x00150000
    assert registry.lookup(code, 0x00100000) is None  # only newer ones known
    assert registry.lookup(code, 0x00150000, vendor_id=7) is None
    assert registry.lookup(0x12345678, 0x00110000) is None


def test_nearest_older_revision_stays_within_the_variant(tmp_path: Path) -> None:
    el3356 = read_terminal_file(TERMINALS / "EL3356-0010.yaml")
    assert variant_of(el3356["EL3356-0010"].identity.revision_number) == 10
    plain = el3356["EL3356-0010"].model_copy(deep=True)
    plain.identity.revision_number = 0x00110000
    write_terminal_file(tmp_path / "EL3356-0010.yaml", el3356)
    write_terminal_file(tmp_path / "EL3356.yaml", {"EL3356": plain})
    registry = load_terminals([tmp_path])
    code = plain.identity.product_code
    ten = registry.lookup(code, 0x0014000A)
    assert ten is not None and ten.type_name == "EL3356-0010" and not ten.exact
    zero = registry.lookup(code, 0x00140000)
    assert zero is not None and zero.type_name == "EL3356"


def test_registry_refuses_duplicates(terminals_copy: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(terminals_copy / "EL3104.yaml", other / "EL3104.yaml")
    analog = str(terminals_copy / "EL31*.yaml")
    with pytest.raises(UserError, match="terminal type EL3104 is also defined in"):
        load_terminals([analog, other])
    el3104 = read_terminal_file(terminals_copy / "EL3104.yaml")["EL3104"]
    write_terminal_file(other / "EL3104.yaml", {"EL3104-COPY": el3104})
    with pytest.raises(UserError, match="has the same identity"):
        load_terminals([analog, other])
