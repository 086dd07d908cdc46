"""Terminal YAML: models, load/save, registry, generation from ESI, regenerate.

The YAML schema and its models (`TerminalType` and its parts) are in
`fastcs_ethercat.terminals.model`, the one place to import them from.

Public API:

- `load_terminals(paths)` -> `TerminalRegistry` (files, directories, globs;
  catio-terminals' `terminal_types:` files are converted by `catio_import`);
  `TerminalRegistry.lookup(product_code, revision)` -> `RegistryMatch`
  (exact, else nearest older revision of the same variant, `exact=False`).
- `read_terminal_file(path)` / `write_terminal_file(path, {name: terminal})`
  / `terminal_file_text(...)`: one file, byte-stable round trip.
- `terminal_from_esi(device)`: generate from an `EsiDevice`.
- `merge_terminal(name, old, new)` -> (merged, `ChangeReport`): regenerate
  keeping the engineer's choices.
- `select_group(terminal, group)`: switch the PDO group and its flags.
- `expanded_symbols(terminal)`: per-channel I/O symbols for IOC and simulator.
"""

from fastcs_ethercat.terminals.files import (
    read_terminal_file,
    terminal_file_name,
    terminal_file_text,
    write_terminal_file,
)
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.loader import load_terminals, terminal_paths
from fastcs_ethercat.terminals.merge import ChangeReport, merge_terminal
from fastcs_ethercat.terminals.registry import (
    RegisteredTerminal,
    RegistryMatch,
    TerminalRegistry,
)
from fastcs_ethercat.terminals.selection import UnknownGroupError, select_group
from fastcs_ethercat.terminals.symbols import (
    ExpandedMember,
    ExpandedSymbol,
    expanded_symbols,
)

__all__ = [
    "ChangeReport",
    "ExpandedMember",
    "ExpandedSymbol",
    "RegisteredTerminal",
    "RegistryMatch",
    "TerminalRegistry",
    "UnknownGroupError",
    "expanded_symbols",
    "load_terminals",
    "merge_terminal",
    "read_terminal_file",
    "select_group",
    "terminal_file_name",
    "terminal_file_text",
    "terminal_from_esi",
    "terminal_paths",
    "write_terminal_file",
]
