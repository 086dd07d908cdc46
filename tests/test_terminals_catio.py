"""catio-terminals files: refused as they are, imported through the ESI.

The catio file here is built from our own ESI-derived terminal files in the
shape catio-terminals writes (its `terminal_types.yaml`): a structure's
fields as separate dotted symbol nodes (`AI Standard Channel
{channel}.Value`) with their own `type_name`, the status bits as a composite
type (`Status__Underrange_6Bits` with `bit_fields`), channels as a count,
`Read-only`/`Read/Write`, no PDO indices, no CoE addresses, no bit offsets,
only the selected CoE objects.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import read_terminal_file
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.model import SymbolNode, TerminalType
from fastcs_ethercat.terminals.selection import (
    rename_coe,
    rename_symbol,
    select_coe,
    select_group,
    select_symbols,
)

from .conftest import NEEDS_ESI_SUBSET
from .test_terminals_support import ESI, TERMINALS, cache_home, run_cli

TYPES = ("EL3104", "EL1502", "EL2024", "EL1014", "EL3702", "EL4134")
INDEX_GROUPS = {"input": 0xF031, "output": 0xF021}


def _composite(node: SymbolNode, composites: dict[str, Any]) -> str:
    bits = [m for m in node.members if m.bit_size < 8]
    if not bits:
        return node.type_name
    name = (
        f"{bits[0].name}Bits" if len(bits) == 1 else f"{bits[0].name}_{len(bits)}Bits"
    )
    composites[name] = {
        "description": "Bit fields: " + ", ".join(m.name for m in bits),
        "ads_type": 65,
        "size": 1,
        "members": [],
        "bit_fields": [{"name": m.name, "bit": at} for at, m in enumerate(bits)],
    }
    return name


def _member_attribute(node: SymbolNode, member: str) -> str:
    """The attribute a member becomes (the symbol's own for a lone member)."""
    return (
        node.fastcs_name if len(node.members) == 1 else f"{node.fastcs_name}_{member}"
    )


def _catio_type(terminal: TerminalType, composites: dict[str, Any]) -> dict[str, Any]:
    nodes: list[dict[str, Any]] = []
    positions: dict[int, list[int]] = {}
    for position, node in enumerate(terminal.symbol_nodes):
        common = {
            "index_group": INDEX_GROUPS[node.direction],
            "channels": max(1, len(node.channels)),
            "access": "Read/Write" if node.direction == "output" else "Read-only",
        }
        mine = positions.setdefault(position, [])
        fields = [m for m in node.members if m.bit_size >= 8]
        if len(fields) < len(node.members) or not fields:
            mine.append(len(nodes))
            nodes.append({"name_template": node.name_template,
                          "type_name": _composite(node, composites), **common,
                          "fastcs_name": node.fastcs_name,
                          "selected": node.selected})  # fmt: skip
        for member in fields:
            mine.append(len(nodes))
            nodes.append({"name_template": f"{node.name_template}.{member.name}",
                          "type_name": member.type_name, **common,
                          "fastcs_name": _member_attribute(node, member.fastcs_name),
                          "selected": node.selected})  # fmt: skip
    body: dict[str, Any] = {
        "description": terminal.description,
        "identity": terminal.identity.model_dump(mode="json"),
        "symbol_nodes": nodes,
        "coe_objects": [
            {
                "index": obj.index,
                "name": obj.name,
                "type_name": obj.type_name,
                "bit_size": obj.bit_size,
                "access": obj.access,
                "subindices": [
                    {
                        "subindex": s.subindex,
                        "name": s.name,
                        "type_name": s.type_name,
                        "bit_size": s.bit_size,
                        "access": s.access,
                        "fastcs_name": f"{s.fastcs_name}_{obj.index:04x}",
                    }
                    for s in obj.sub_items
                ],
                "fastcs_name": obj.fastcs_name,
            }
            for obj in terminal.coe_objects
            if obj.selected
        ],
        "group_type": terminal.group_type,
    }
    if terminal.pdo_groups:
        body["pdo_groups"] = [
            {"name": g.name, "is_default": g.is_default,
             "symbol_indices": sorted(at for i in g.symbol_indices
                                      for at in positions[i])}
            for g in terminal.pdo_groups
        ]  # fmt: skip
        body["selected_pdo_group"] = terminal.selected_pdo_group
    return body


def catio_file(terminals: dict[str, TerminalType]) -> str:
    composites: dict[str, Any] = {}
    types = {name: _catio_type(t, composites) for name, t in terminals.items()}
    header = (
        "# Terminal Configuration\n# Automatically generated by catio_terminals\n\n"
    )
    body = {"composite_types": composites, "terminal_types": types}
    return header + yaml.safe_dump(body, sort_keys=False, width=80)


@pytest.fixture(scope="module")
def chosen() -> dict[str, TerminalType]:
    """Our files with choices an engineer made in catio."""
    if not ESI.is_dir():
        pytest.skip(NEEDS_ESI_SUBSET)
    terminals = {n: read_terminal_file(TERMINALS / f"{n}.yaml")[n] for n in TYPES}
    el3104 = select_coe(select_group(terminals["EL3104"], "Compact"), ["0x8000"])
    terminals["EL3104"] = rename_coe(
        rename_symbol(el3104, 1, "compact_{channel}"), 0x8000, "filter_ch1"
    )
    terminals["EL1014"] = select_symbols(
        terminals["EL1014"], ["Channel {channel}"], on=False
    )
    el1502 = terminals["EL1502"]
    other = next(g.name for g in el1502.pdo_groups if not g.is_default)
    terminals["EL1502"] = select_group(el1502, other)
    return terminals


def test_a_catio_file_is_refused_with_one_line(
    chosen: dict[str, TerminalType], tmp_path: Path
) -> None:
    path = tmp_path / "terminal_types.yaml"
    path.write_text(catio_file(chosen), encoding="utf-8")
    with pytest.raises(UserError) as caught:
        load_terminals([path])
    assert "\n" not in str(caught.value)
    assert str(caught.value).startswith(f"{path}:")
    assert "has no bit offsets: convert it with `fastcs-ethercat terminals import" in (
        str(caught.value)
    )


def test_import_places_every_node_at_the_esi_offsets_and_keeps_choices(
    chosen: dict[str, TerminalType], tmp_path: Path
) -> None:
    path = tmp_path / "terminal_types.yaml"
    path.write_text(catio_file(chosen), encoding="utf-8")
    out = tmp_path / "imported"
    with cache_home(tmp_path / "cache"):
        result = run_cli("terminals", "import", str(path), "--esi", str(ESI),
                         "--out", str(out))  # fmt: skip
    assert result.code == 0, result.err
    assert result.err == ""
    assert f"imported {len(TYPES)} of {len(TYPES)} types; 0 nodes" in result.out
    for name, expected in chosen.items():
        imported = read_terminal_file(out / f"{name}.yaml")[name]
        assert imported == expected, name
    el3104 = read_terminal_file(out / "EL3104.yaml")["EL3104"]
    standard = el3104.symbol_nodes[0]
    offsets = {m.name: m.bit_offset for m in standard.members}
    assert offsets["Status__Error"] == 6 and offsets["Value"] == 16
    el3702 = read_terminal_file(out / "EL3702.yaml")["EL3702"]
    assert el3702.oversampling is not None
    assert el3702.oversampling.selected_factor == 10


def test_import_names_what_it_cannot_place(
    chosen: dict[str, TerminalType], tmp_path: Path
) -> None:
    text = catio_file({"EL3104": chosen["EL3104"]})
    data = yaml.safe_load(text)
    nodes = data["terminal_types"]["EL3104"]["symbol_nodes"]
    nodes.append(dict(nodes[0], name_template="AI Standard Channel {channel}.Bogus"))
    nodes.append(dict(nodes[-2]))  # the same node twice
    data["terminal_types"]["EL3104"]["coe_objects"][0]["index"] = 0x7FF0
    data["terminal_types"]["EL9999"] = dict(data["terminal_types"]["EL3104"])
    path = tmp_path / "terminal_types.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    with cache_home(tmp_path / "cache"):
        result = run_cli("terminals", "import", str(path), "--esi", str(ESI),
                         "--out", str(tmp_path / "out"))  # fmt: skip
    assert result.code == 2
    warnings = result.err.splitlines()
    assert any("'AI Standard Channel {channel}.Bogus' matches no symbol or member "
               "of EL3104 revision 0x00110000" in w for w in warnings)  # fmt: skip
    assert any("repeats symbol_nodes[" in w for w in warnings)
    assert any("CoE object 0x7ff0 'AI Settings' is not in the ESI dictionary" in w
               for w in warnings)  # fmt: skip
    assert any("EL9999: no ESI description to import it from" in w for w in warnings)
    assert warnings[-1] == f"error: {path}: not imported: EL9999"
    assert all(w.startswith(("warning: ", "error: ")) for w in warnings)
    assert "imported 1 of 2 types; 3 nodes or choices could not be placed" in (
        result.out
    )
