"""The editor's two pages (NiceGUI): the list of types, and one type.

Every element a test or a person needs to find carries `data-test=...`.
A choice that cannot be made shows its reason next to the field it came
from; nothing is written until "Save" in the diff dialog.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

from nicegui import ui

from fastcs_ethercat.editor.filters import FILTER_STATES, RowFilter
from fastcs_ethercat.editor.live import LiveTerminal
from fastcs_ethercat.editor.pv_preview import (
    EXAMPLE_PREFIX,
    MAX_PV_LENGTH,
    PvPreview,
    preview_pvs,
)
from fastcs_ethercat.editor.session import EditedType, EditorSession
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.meaning import (
    is_status,
    member_scaling,
    member_severity,
    severity_of_name,
)
from fastcs_ethercat.terminals.model import (
    UNIT_CHOICES,
    CoeObject,
    SymbolMember,
    SymbolNode,
    TerminalType,
)
from fastcs_ethercat.terminals.selection import (
    SelectionError,
    rename_coe,
    rename_symbol,
    select_coe,
    select_group,
    select_symbols,
    set_oversampling,
    set_severity,
    set_units,
)

ERROR = "text-negative text-sm"
MUTED = "text-grey-7 text-sm"


def _pv_text(preview: PvPreview) -> str:
    text = preview.pv + (" (+_RBV)" if preview.writable else "")
    text += f"  [{preview.longest} chars]"
    return text + (f"  shortened: {preview.shortened}" if preview.shortened else "")


def _test(element: Any, name: str) -> Any:
    return element.props(f'data-test="{name}"')


def _header(session: EditorSession, title: str) -> None:
    with ui.row().classes("w-full items-baseline gap-4"):
        ui.link("Terminal types", "/").classes("text-lg")
        ui.label(title).classes("text-xl font-bold")
        ui.label(str(session.directory)).classes(MUTED)


def index_page(session: EditorSession) -> None:
    """Every type of the directory, and adding one from the ESI catalog."""
    _header(session, "")
    columns = [
        {"name": "type", "label": "Type", "field": "type", "align": "left"},
        {"name": "revision", "label": "Revision", "field": "revision"},
        {"name": "group", "label": "PDO group", "field": "group", "align": "left"},
        {"name": "symbols", "label": "Symbols selected", "field": "symbols"},
        {"name": "coe", "label": "CoE objects selected", "field": "coe"},
        {"name": "state", "label": "", "field": "state"},
        {"name": "description", "label": "Description", "field": "description",
         "align": "left"},
    ]  # fmt: skip
    rows = []
    for name in sorted(session.types):
        edited = session.types[name]
        on, total, coe_on, coe_total = edited.counts()
        terminal = edited.current
        rows.append(
            {
                "type": name,
                "revision": f"0x{terminal.identity.revision_number:08x}",
                "group": terminal.selected_pdo_group or "-",
                "symbols": f"{on} of {total}",
                "coe": f"{coe_on} of {coe_total}",
                "state": "new, not saved"
                if edited.new
                else "unsaved"
                if edited.changed
                else "",
                "description": terminal.description,
            }
        )
    pending = sorted(name for name, edited in session.types.items() if edited.changed)
    if pending:
        _test(
            ui.label(
                f"Edits not saved yet: {', '.join(pending)} (open a type to "
                "review and save, or discard)"
            ),
            "pending",
        ).classes("text-warning")
    _add_type_panel(session)
    table = _test(ui.table(columns=columns, rows=rows, row_key="type"), "types")
    table.classes("w-full")
    table.add_slot(
        "body-cell-type",
        '<q-td :props="props"><a :href="\'/type/\' + props.value" '
        ':data-test="\'open-\' + props.value" class="text-primary">'
        "{{ props.value }}</a></q-td>",
    )


def _add_type_panel(session: EditorSession) -> None:
    ui.label("Add a type from the ESI catalog").classes("text-lg")
    with ui.row().classes("items-start gap-2"):
        search = _test(ui.input("type, description or group"), "search")
        search.classes("w-96")
    message = _test(ui.label(""), "add-error").classes(ERROR)
    results = ui.column().classes("gap-1 mb-4")

    def add(type_name: str) -> None:
        try:
            session.add_type(type_name)
        except UserError as error:
            message.text = str(error)
            return
        ui.navigate.to(f"/type/{type_name}")

    def show() -> None:
        results.clear()
        message.text = ""
        if len(search.value.strip()) < 2:
            return
        try:
            found = session.search(search.value)
        except UserError as error:
            message.text = str(error)
            return
        with results:
            if not found:
                ui.label("no match").classes(MUTED)
            for entry in found:
                with ui.row().classes("items-center gap-3"):
                    button = ui.button("Add", on_click=partial(add, entry.type_name))
                    _test(button.props("dense flat"), f"add-{entry.type_name}")
                    ui.label(entry.type_name).classes("font-mono w-32")
                    ui.label(f"0x{entry.revision:08x}").classes("font-mono")
                    ui.label(entry.group_type or "-").classes("w-24")
                    ui.label(entry.description)

    search.on("update:model-value", show, throttle=0.3)


def type_page(
    session: EditorSession, name: str, live: Callable[[], list[LiveTerminal]] | None
) -> None:
    """One type: group, symbols, CoE objects, oversampling, names, save."""
    try:
        edited = session.get(name)
    except UserError as error:
        _header(session, name)
        _test(ui.label(str(error)), "page-error").classes(ERROR)
        return
    _header(session, name)
    _TypeView(session, edited, live).build()


class _TypeView:
    def __init__(
        self,
        session: EditorSession,
        edited: EditedType,
        live: Callable[[], list[LiveTerminal]] | None,
    ) -> None:
        self.session = session
        self.edited = edited
        self.live = live
        self.prefix = EXAMPLE_PREFIX
        self.opened: set[int] = set()
        """Symbols whose units and severities are open (kept across redraws)."""
        self.opened_pdos: set[int] = set()
        """Symbols whose members are shown (collapsed otherwise)."""
        self.filter = RowFilter()

    @property
    def terminal(self) -> TerminalType:
        return self.edited.current

    def apply(self, edit: Callable[[TerminalType], TerminalType], message: Any) -> None:
        """Make a choice; its error goes to `message`, else redraw."""
        try:
            self.session.apply(self.edited.name, edit)
        except SelectionError as error:
            message.text = str(error)
            return
        message.text = ""
        self.body.refresh()

    def build(self) -> None:
        terminal = self.terminal
        identity = terminal.identity
        ui.label(
            f"{terminal.description} - revision 0x{identity.revision_number:08x}"
            f", product 0x{identity.product_code:08x}"
            + (f", from {terminal.esi_file}" if terminal.esi_file else "")
        ).classes(MUTED)
        with ui.row().classes("items-center gap-4 my-2"):
            _test(ui.button("Review and save", on_click=self._review), "review")
            _test(ui.button("Revert", on_click=self._revert).props("flat"), "revert")
            self.state = _test(ui.label(""), "state").classes(MUTED)
        self.pending = ui.row().classes("items-center gap-4")
        if self.edited.changed:
            self._announce_pending()
        self._filter_bar()
        self.body()

    def _announce_pending(self) -> None:
        """Edits made before this page opened (another tab, an earlier visit),
        or a type added from the catalog: said once, with a way back."""
        with self.pending:
            text = (
                "New type from the ESI catalog: its file is written when you save."
                if self.edited.new
                else "This type has edits not saved yet, made before this page "
                "opened (another tab or an earlier visit)."
            )
            _test(ui.label(text), "pending").classes("text-warning")
            discard = ui.button("Discard", on_click=self._revert).props("flat dense")
            _test(discard, "discard")

    def _filter_bar(self) -> None:
        """Narrow the symbols, members and CoE objects to the matching rows."""
        with ui.row().classes("items-center gap-4"):
            box = ui.input("Filter symbols, members, CoE objects")
            box.props("clearable debounce=500")  # one redraw per pause in typing
            _test(box.classes("w-96"), "filter")
            state = ui.toggle(list(FILTER_STATES), value=self.filter.state)
            _test(state.props("dense no-caps"), "filter-state")

        def changed() -> None:
            self.filter = RowFilter(box.value or "", state.value or "all")
            self.body.refresh()

        box.on_value_change(changed)
        state.on_value_change(changed)

    def _live_panel(self) -> None:
        assert self.live is not None
        with ui.card().classes("w-full"):
            ui.label("Live terminals of this type").classes("font-bold")
            try:
                found = [t for t in self.live() if t.type_name == self.edited.name]
            except UserError as error:
                _test(ui.label(str(error)), "live-error").classes(ERROR)
                return
            if not found:
                ui.label("none on the target").classes(MUTED)
            wanted = self.terminal.selected_pdo_group
            for terminal in found:
                runs = terminal.active_group or "-"
                text = f"{terminal.name}: runs {runs}"
                mismatch = wanted is not None and terminal.active_group not in (
                    None,
                    wanted,
                )
                if mismatch:
                    text += f" - the file selects {wanted}: MISMATCH"
                label = _test(ui.label(text), f"live-{terminal.name}")
                label.classes(ERROR if mismatch else "")

    @ui.refreshable_method
    def body(self) -> None:
        self.state.text = (
            "new, not saved"
            if self.edited.new
            else "unsaved changes"
            if self.edited.changed
            else "saved"
        )
        if self.live is not None:
            self._live_panel()
        self._group_and_oversampling()
        self._prefix_field()
        try:
            previews = preview_pvs(self.terminal, self.edited.name, self.prefix)
        except UserError as error:
            self.prefix_error.text = str(error).removeprefix("prefix: ")
            previews = []
        self._symbols(previews)
        self._coe(previews)

    def _group_and_oversampling(self) -> None:
        terminal = self.terminal
        with ui.row().classes("items-start gap-8"):
            if terminal.pdo_groups:
                options = {
                    g.name: g.name + (" (default)" if g.is_default else "")
                    for g in terminal.pdo_groups
                }
                with ui.column().classes("gap-0"):
                    select = ui.select(
                        options, value=terminal.selected_pdo_group, label="PDO group"
                    )
                    _test(select.classes("w-64"), "group")
                    message = _test(ui.label(""), "group-error").classes(ERROR)
                select.on_value_change(
                    lambda e, m=message: self.apply(
                        partial(select_group, group_name=e.value), m
                    )
                )
            over = terminal.oversampling
            if over is not None:
                with ui.column().classes("gap-0"):
                    factor = ui.select(
                        over.factors, value=over.selected_factor,
                        label="Oversampling factor",
                    )  # fmt: skip
                    _test(factor.classes("w-48"), "factor")
                    if over.by_group:
                        factor.disable()
                        ui.label("follows the PDO group").classes(MUTED)
                    message = _test(ui.label(""), "factor-error").classes(ERROR)
                factor.on_value_change(
                    lambda e, m=message: self.apply(
                        partial(set_oversampling, factor=int(e.value)), m
                    )
                )

    def _prefix_field(self) -> None:
        with ui.row().classes("items-start gap-2 mt-2"):
            field = ui.input("PV prefix of one terminal", value=self.prefix)
            _test(field.classes("w-96"), "prefix")
            self.prefix_error = _test(ui.label(""), "prefix-error").classes(ERROR)

        def changed() -> None:
            self.prefix = field.value or ""
            self.body.refresh()

        field.on("change", changed)

    def _symbols(self, previews: list[PvPreview]) -> None:
        terminal = self.terminal
        by_node: dict[int, list[PvPreview]] = {}
        for preview in previews:
            if preview.node is not None:
                by_node.setdefault(preview.node, []).append(preview)
        group = terminal.active_group
        ui.label("Symbols" + (f" of PDO group {group.name}" if group else "")).classes(
            "text-lg mt-4"
        )
        offered = [
            position
            for position in range(len(terminal.symbol_nodes))
            if not terminal.groups_of(position) or terminal.selectable(position)
        ]
        shown = [
            position
            for position in offered
            if self.filter.shows_symbol(terminal.symbol_nodes[position])
        ]
        if len(shown) < len(offered):
            _test(
                ui.label(f"{len(shown)} of {len(offered)} symbols match the filter"),
                "symbols-count",
            ).classes(MUTED)
        with _test(ui.column().classes("w-full gap-1"), "symbols"):
            for position in shown:
                self._symbol_row(position, by_node.get(position, []))
        too_long = [p for p in previews if p.longest > MAX_PV_LENGTH]
        if too_long:
            ui.label(
                f"{len(too_long)} PV names over {MAX_PV_LENGTH} characters"
            ).classes(ERROR)

    def _symbol_row(self, position: int, previews: list[PvPreview]) -> None:
        node = self.terminal.symbol_nodes[position]
        with ui.row().classes("w-full items-start gap-3 border-t pt-1"):
            box = ui.checkbox(node.name_template, value=node.selected)
            _test(box.classes("w-72 font-bold"), f"symbol-{position}")
            box.props(f'data-row="{node.name_template}"')
            samples = self.terminal.sample_count(node)
            facts = (
                f"{node.type_name} | {node.bit_size} bit"
                + (f" x {samples} samples" if node.oversampled else "")
                + f" | channels {','.join(map(str, node.channels)) or '-'}"
                + f" | {node.access}"
            )
            label = ui.label(facts).classes("w-80 text-sm font-mono")
            _test(label, f"symbol-facts-{position}")
            with ui.column().classes("gap-0"):
                name = ui.input("fastcs_name", value=node.fastcs_name)
                _test(name.classes("w-64").props("dense"), f"name-{position}")
                message = _test(ui.label(""), f"symbol-error-{position}")
                message.classes(ERROR)
            if previews:
                longest = max(preview.longest for preview in previews)
                summary = ui.label(
                    f"{len(previews)} PVs, longest {longest} of {MAX_PV_LENGTH} "
                    "characters"
                    + (", shortened" if any(p.shortened for p in previews) else "")
                )
                _test(summary.classes("text-sm"), f"pv-summary-{position}")
                if longest > MAX_PV_LENGTH:
                    summary.classes(ERROR)
        self._member_table(position, previews)
        box.on_value_change(
            lambda e: self.apply(
                partial(select_symbols, wanted=[node.fastcs_name], on=bool(e.value)),
                message,
            )
        )
        name.on(
            "change",
            lambda _: self.apply(
                partial(rename_symbol, position=position, name=name.value or ""),
                message,
            ),
        )

    def _member_table(self, position: int, previews: list[PvPreview]) -> None:
        """The symbol's members with the PV of its first channel each."""
        node = self.terminal.symbol_nodes[position]
        first = node.channels[0] if node.channels else None
        pv_of: dict[str | None, PvPreview] = {}
        for preview in previews:  # a value's own PV before its raw twin's
            if preview.channel == first:
                pv_of.setdefault(preview.member, preview)
        whole = pv_of.get(None)
        members = self.filter.members(node)
        rows = []
        for member in members:
            preview = pv_of.get(member.name) or whole
            scaling = member_scaling(member)
            rows.append(
                {
                    "member": member.shown_name,
                    "type": member.type_name,
                    "offset": member.bit_offset,
                    "bits": member.bit_size,
                    "served": scaling.text() if scaling else "raw",
                    "severity": member_severity(member, node.direction),
                    "pv": _pv_text(preview) if preview else "(not selected)",
                }
            )
        columns = [
            {"name": n, "label": label, "field": n, "align": "left"}
            for n, label in (
                ("member", "Member"),
                ("type", "Type"),
                ("offset", "Bit offset"),
                ("bits", "Bits"),
                ("served", "Served as"),
                ("severity", "Severity when set"),
                ("pv", f"PV (channel {first})" if first is not None else "PV"),
            )
        ]
        title = f"{len(node.members)} members" + (
            f", {len(members)} match the filter"
            if len(members) < len(node.members)
            else ""
        )
        pdo = ui.expansion(
            title,
            value=position in self.opened_pdos
            or (self.filter.narrows and len(members) < len(node.members)),
        ).classes("w-full pl-8")
        _test(pdo.props("dense"), f"pdo-toggle-{position}")
        pdo.on_value_change(
            lambda e: (self.opened_pdos.add if e.value else self.opened_pdos.discard)(
                position
            )
        )
        with pdo:
            table = ui.table(columns=columns, rows=rows).props("dense flat wrap-cells")
            _test(table.classes("w-full text-xs"), f"members-{position}")
            expansion = ui.expansion(
                "Units and alarm severities", value=position in self.opened
            )
            _test(expansion.classes("w-full"), f"meaning-toggle-{position}")
            expansion.on_value_change(
                lambda e: (self.opened.add if e.value else self.opened.discard)(
                    position
                )
            )
            with expansion, _test(ui.column().classes("gap-1"), f"meaning-{position}"):
                for index, member in enumerate(node.members):
                    if member in members:
                        self._member_meaning(position, node, index, member)

    def _member_meaning(
        self, position: int, node: SymbolNode, index: int, member: SymbolMember
    ) -> None:
        """A member's overrides: units of a value, severity of a status bit."""
        where = f"{position}-{index}"
        symbol = node.fastcs_name
        with ui.row().classes("items-start gap-2"):
            ui.label(member.shown_name).classes("w-48 font-mono")
            if is_status(member):
                derived = severity_of_name(member.name, node.direction)
                options = {"default": f"default ({derived})"}
                options.update({level: level for level in ("none", "minor", "major")})
                select = ui.select(options, value=member.severity or "default")
                _test(select.classes("w-40").props("dense"), f"severity-{where}")
                message = _test(ui.label(""), f"meaning-error-{where}").classes(ERROR)
                select.on_value_change(
                    lambda e: self.apply(
                        partial(
                            set_severity,
                            symbol=symbol,
                            member=member.fastcs_name,
                            severity=None if e.value == "default" else e.value,
                        ),
                        message,
                    )
                )
                return
            fields = {}
            for key in UNIT_CHOICES:
                value = getattr(member, key)
                box = ui.input(key, value="" if value is None else str(value))
                fields[key] = _test(
                    box.classes("w-28").props("dense"), f"{key}-{where}"
                )
            message = _test(ui.label(""), f"meaning-error-{where}").classes(ERROR)

            def changed(_: Any) -> None:
                try:
                    wanted = _unit_overrides({k: f.value for k, f in fields.items()})
                except ValueError as error:
                    message.text = str(error)
                    return
                self.apply(
                    partial(
                        set_units,
                        symbol=symbol,
                        member=member.fastcs_name,
                        reset=True,
                        **wanted,
                    ),
                    message,
                )

            for box in fields.values():
                box.on("change", changed)

    def _coe(self, previews: list[PvPreview]) -> None:
        objects = self.terminal.coe_objects
        shown = [obj for obj in objects if self.filter.shows_coe(obj)]
        count = f"{len(shown)} of {len(objects)}" if len(shown) < len(objects) else ""
        ui.label(f"CoE objects ({count or len(objects)})").classes("text-lg mt-4")
        by_object: dict[str, list[PvPreview]] = {}
        for preview in previews:
            if preview.node is None:
                by_object.setdefault(preview.source[:10], []).append(preview)
        with _test(ui.column().classes("w-full gap-0"), "coe"):
            for obj in shown:
                self._coe_row(obj, by_object.get(f"CoE 0x{obj.index:04x}", []))

    def _coe_row(self, obj: CoeObject, previews: list[PvPreview]) -> None:
        address = f"0x{obj.index:04x}"
        with ui.row().classes("w-full items-start gap-3 border-b"):
            box = ui.checkbox(f"{address} {obj.name}", value=obj.selected)
            _test(box.classes("w-80"), f"coe-{address}")
            box.props(f'data-row="{address} {obj.name}"')
            ui.label(f"{obj.type_name} | {obj.access or '-'}").classes(
                "w-40 text-sm font-mono"
            )
            with ui.column().classes("gap-0"):
                name = ui.input("fastcs_name", value=obj.fastcs_name)
                _test(name.classes("w-64").props("dense"), f"coe-name-{address}")
                message = _test(ui.label(""), f"coe-error-{address}").classes(ERROR)
            if previews:
                with _test(ui.column().classes("gap-0"), f"coe-pvs-{address}"):
                    longest = max(p.longest for p in previews)
                    ui.label(
                        f"{len(previews)} PVs, longest {longest} of {MAX_PV_LENGTH}"
                    ).classes("text-sm" if longest <= MAX_PV_LENGTH else ERROR)
                    ui.label(_pv_text(previews[0])).classes("text-xs font-mono")
            subs = self.filter.sub_items(obj)
            if subs:
                title = f"{len(obj.sub_items)} sub-indices" + (
                    f", {len(subs)} match" if len(subs) < len(obj.sub_items) else ""
                )
                narrowed = self.filter.narrows and len(subs) < len(obj.sub_items)
                with ui.expansion(title, value=narrowed).classes("w-96"):
                    for sub in subs:
                        target = f"{address}:{sub.subindex:02x}"
                        sub_box = ui.checkbox(
                            f"{sub.subindex:02x} {sub.name} ({sub.type_name})",
                            value=obj.selected and sub.selected,
                        )
                        _test(sub_box.props("dense"), f"coe-{target}")
                        sub_box.on_value_change(
                            lambda e, t=target: self.apply(
                                partial(select_coe, targets=[t], on=bool(e.value)),
                                message,
                            )
                        )
        box.on_value_change(
            lambda e: self.apply(
                partial(select_coe, targets=[address], on=bool(e.value)), message
            )
        )
        name.on(
            "change",
            lambda _: self.apply(
                partial(rename_coe, index=obj.index, name=name.value or ""), message
            ),
        )

    def _review(self) -> None:
        diff = self.session.diff(self.edited.name)
        with ui.dialog() as dialog, ui.card().classes("w-[64rem] max-w-full"):
            ui.label(f"Changes to {self.edited.path.name}").classes("text-lg")
            if diff:
                _test(ui.code(diff, language="diff").classes("w-full"), "diff")
            else:
                _test(ui.label("no changes: the file stays as it is"), "diff")
            message = _test(ui.label(""), "save-error").classes(ERROR)
            with ui.row():
                _test(
                    ui.button("Save", on_click=lambda: self._save(dialog, message)),
                    "save",
                )
                ui.button("Cancel", on_click=dialog.close).props("flat")
        dialog.open()

    def _save(self, dialog: Any, message: Any) -> None:
        try:
            saved = self.session.save(self.edited.name)
        except UserError as error:
            message.text = str(error)
            return
        dialog.close()
        self.pending.clear()
        notes = "; ".join(str(d) for d in saved.dropped)
        ui.notify(
            f"saved {saved.path.name}"
            if saved.changed
            else "nothing to save" + (f" ({notes})" if notes else "")
        )
        self.body.refresh()

    def _revert(self) -> None:
        self.session.revert(self.edited.name)
        self.pending.clear()
        if self.edited.new:  # discarded: the type is gone
            ui.navigate.to("/")
            return
        self.body.refresh()


def _unit_overrides(texts: dict[str, str]) -> dict[str, Any]:
    """The editor's unit fields as `set_units` takes them (empty: not set)."""
    wanted: dict[str, Any] = {}
    for key, text in texts.items():
        text = (text or "").strip()
        if not text:
            continue
        if key == "unit":
            wanted[key] = text
            continue
        try:
            wanted[key] = int(text) if key == "precision" else float(text)
        except ValueError:
            raise ValueError(f"{key}: {text!r} is not a number") from None
    return wanted
