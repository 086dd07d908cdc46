"""The files `init` writes into the staged DIR (`layout.staging`): each
type's YAML with the running group selected (a kept file only where the
rack changed under the engineer's choice), the chain, the configuration,
the screens and PV lists of the IOC's tree, the services-repo instance."""

from __future__ import annotations

import shutil
from pathlib import Path

from fastcs_ethercat.commission import layout
from fastcs_ethercat.commission.choices import (
    running_choice,
    selected_group,
    with_running,
)
from fastcs_ethercat.commission.rack import ChangeKind, RackChange
from fastcs_ethercat.commission.served import Preview, Served, serve_preview
from fastcs_ethercat.commission.sources import Described, Origin
from fastcs_ethercat.ioc.config import config_schema_text
from fastcs_ethercat.ioc.plan import SystemPlan


def chain_text(plan: SystemPlan, prefix: str) -> str:
    """The chain file, headed without a date or an address: a rack that did
    not change gives the same file, whether read live or from a chain."""
    from fastcs_ethercat.ioc.chains import chain_data
    from fastcs_ethercat.terminals.yaml_io import dump_yaml

    header = (
        f"# The EtherCAT chain of {prefix} as `fastcs-ethercat init` found it\n"
        "# (the simulator's chain format): `fastcs-ethercat sim --chain FILE`\n"
        "# plays it with the terminal YAML of `terminal_dirs` beside it.\n"
    )
    data = {"terminal_dirs": [layout.TERMINALS_DIR], **chain_data(plan)}
    return dump_yaml(data, header=header)


def write_chain(folder: Path, plan: SystemPlan, prefix: str) -> None:
    layout.write_text(folder / layout.CHAIN_FILE, chain_text(plan, prefix))


def write_terminals(
    folder: Path, described: list[Described], changes: list[RackChange]
) -> list[str]:
    """Every YAML with a file of its own, the running group selected (a kept
    file only where the rack changed group under the engineer's choice);
    what a human must decide."""
    from fastcs_ethercat.terminals.files import terminal_file_text
    from fastcs_ethercat.terminals.saving import file_text
    from fastcs_ethercat.terminals.schema import write_schema

    (folder / layout.TERMINALS_DIR).mkdir(exist_ok=True)
    write_schema(folder / layout.TERMINALS_DIR)  # the files' `$schema` line
    regrouped = {
        change.after.name: change.before.pdo_group
        for change in changes
        if change.kind is ChangeKind.PDO_GROUP and change.after and change.before
    }
    decisions: list[str] = []
    for item in described:
        terminal, name = item.terminal, item.file_name
        if terminal is None or name is None or not item.slaves:
            continue
        label = f"{item.type_name} revision 0x{item.revision:08x}"
        running = running_choice(label, terminal, item.slaves)
        decisions += running.decisions
        chosen = selected_group(terminal)
        if item.origin is Origin.KEPT and running.group != chosen:
            earlier = {regrouped.get(s.slave.name, s.active_group) for s in item.slaves}
            if earlier != {chosen}:  # the engineer chose another group: theirs
                decisions.append(
                    f"{label}: {name} selects PDO group {chosen!r}, the rack runs "
                    f"{running.group!r}: kept (`terminals select-group` changes it)"
                )
                continue
        updated = with_running(terminal, running)
        path = folder / layout.TERMINALS_DIR / name
        if item.text is not None and updated == terminal:
            text = item.text
        elif item.text is not None:
            text, _dropped = file_text({item.type_name: updated}, item.text)
        else:
            text = terminal_file_text({item.type_name: updated})
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            layout.write_text(path, text)
        item.terminal = updated
    return decisions


def write_config(folder: Path, settings: layout.Settings) -> None:
    layout.write_new(folder / layout.IOC_FILE, layout.ioc_yaml(settings))
    layout.write_text(folder / layout.SCHEMA_FILE, config_schema_text())


def serve(folder: Path) -> Served:
    screens = folder / layout.SCREENS_DIR
    shutil.rmtree(screens, ignore_errors=True)  # no page of a terminal gone
    return serve_preview(
        Preview(
            config=folder / layout.IOC_FILE,
            chain=folder / layout.CHAIN_FILE,
            screens=screens,
            pv_lists=folder / layout.PV_LISTS_DIR,
        )
    )


def write_instance(folder: Path, settings: layout.Settings) -> None:
    """The services-repo instance: values and config written once (then
    the engineer's), terminals and chain copied from DIR every run."""
    instance = folder / layout.INSTANCE_DIR / layout.instance_name(settings.prefix)
    config = instance / layout.CONFIG_DIR
    layout.write_new(instance / layout.VALUES_FILE, layout.values_yaml(settings))
    layout.write_new(config / layout.IOC_FILE, layout.instance_ioc_yaml(settings))
    layout.write_text(config / layout.SCHEMA_FILE, config_schema_text())
    shutil.rmtree(config / layout.TERMINALS_DIR, ignore_errors=True)
    if (folder / layout.TERMINALS_DIR).is_dir():
        shutil.copytree(folder / layout.TERMINALS_DIR, config / layout.TERMINALS_DIR)
    shutil.copyfile(folder / layout.CHAIN_FILE, config / layout.CHAIN_FILE)
