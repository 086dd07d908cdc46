"""Framework entry points vulture cannot see called: the frameworks call them
by registration, not by name. Only such names belong here (vulture reads the
attribute names below as uses; the file is never imported).

    vulture src tests/vulture_whitelist.py --min-confidence 60
"""

from typing import Any

_: Any = None

TYPER_COMMANDS = (
    _._main,  # the root callback (cli/__init__.py)
    _.chain_callback,
    _.dump_command,
    _.ioc_command,
    _.schema_command,
    _.list_types,
    _.generate,
    _.regenerate,
    _.select_group_command,
    _.select_command,
    _.coe_command,
    _.units_command,
    _.severity_command,
    _.edit_command,
    _.import_command,
    _.update_cache,
    _.init_command,
)
FASTCS_HOOKS = (
    _.initialise,  # Controller.initialise, before the transports are built
    _.disconnect,  # Controller.disconnect, at stop
    _.read_stats,  # @scan methods
    _.read_diagnostics,
)
PYDANTIC_VALIDATORS = (
    _._revision_number,  # chain/file.py
    _._slave_name,
    _._net_id_text,
    _._master_name,
    _._terminal_dirs,
    _._one_password_source,  # ioc/config.py
    _._at_least_one,
    _._prefix_fits,
    _._target_parses,
    _._netid_parses,
    _._aliases_are_segments,
    _._scale_is_not_zero,  # terminals/model.py
    _._unit_fits_egu,
)
ASYNCIO_PROTOCOL_CALLBACKS = (
    _.datagram_received,  # DatagramProtocol (ads/udp_client.py, sim/udp.py)
    _.error_received,
    _.pause_writing,  # Protocol flow control (sim/server.py)
    _.resume_writing,
)
