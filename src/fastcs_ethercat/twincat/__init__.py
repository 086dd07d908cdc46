"""A model of a TwinCAT 3 system with EtherCAT masters, from a chain file:
what its PLC answers over ADS, sans-I/O.

Two readers: the simulator (`sim/`) serves it over AMS/TCP and UDP; the IOC
discovers a chain file through it without the PLC (`inprocess`), by the same
discovery code as the PLC, so the tree served offline is the tree the PLC of
that chain gives (see docs/architecture.md, "The chain file and the model").

- `chain.file`: `load_chain(path) -> Chain` reads a chain file (see its
  docstring for the format; examples in `ioc/*-chain.yaml`); problems are
  one-line `UserError`s naming file and line.
- `twincat.target.SimTarget`, built by
  `SimTarget.from_chain(chain_or_path, terminals_dir, seed=0)`:

  - `system_net_id: AmsNetId`, `net_ids: set[AmsNetId]` (the system NetId
    and each master's device NetId);
  - `handle(packet: AmsPacket) -> AmsPacket | None`: the response to any ADS
    request addressed to one of its NetIds (addresses swapped, same invoke
    id, state flags 0x0005; AMS error 0x6 for an unknown port, 0x7 for a
    foreign NetId; service results in the payload). Add/Delete-
    DeviceNotification are the I/O layer's: it samples values with
  - `read(address, group, offset, length) -> (result, data)`;
  - `tick(now)`: advance the I/O task (cycle `system.task_cycle_ms`,
    default 10 ms) to monotonic time `now`;
  - faults and control: `set_slave_state(address_or_name, state,
    device=None)`, `set_link_lost(address_or_name, lost, device=None)`
    (`address_or_name=None`: every slave; `state`: "INIT", "PREOP",
    "SAFEOP", "OP" or the raw AL byte), `online_change(pdo_groups=None)`,
    `set_run_state(running)`, `force_error(code, group=None)`,
    `set_sum_commands(served)` (False: 0xF080-0xF082 answer 0x701),
    `fail_symbols(code, symbols)` (reads touching those symbols fail, per
    item in a sum read; `twincat.itemfaults`), `clear_faults()`,
    `get_symbol_value(name)`, `set_symbol_value(name, value)` (TwinCAT
    names; structures as dicts, arrays as lists; an input set this way
    keeps its value until `clear_faults`), `describe() -> dict` (masters,
    slaves, symbol counts).
- `sim.probe.SimProbe` (in `sim/`): an in-process client (codec in, codec out) for
  tests, benchmarks and tools.
- `twincat.inprocess.sim_clients(target)`: real `AdsClient`s over a connection
  whose stream is a `SimTarget` of the same process (no socket): the IOC
  discovers a chain file with it as if it were the PLC.
- `SimTarget.from_chain(..., revisions=load_revisions(dirs))`: a slave whose
  chain entry gives another revision is played from the YAML of that
  revision (`SimTarget.notes` names those played from another one).

Model modules: `resolve` (chain + terminal YAML -> names, addresses,
identities, active PDOs), `tctypes` (TwinCAT types and their names),
`layout` (symbols and offsets), `image` (process images, values per type),
`symtab` (upload bytes, lookup by name), `generators` (input signals),
`coe` (SDO dictionary), `master` (EtherCAT master), `device` (one I/O
device kept consistent across online changes), `services` (the ADS services
of each port), `target`.

What it plays, and the evidence for each rule
(facts = `../shared/reference/ads-twincat-facts.md`; "rack dump" = catio's
symbol dump of a real 105-terminal rack, `hardware-output.txy`):

- Ports (facts 6): I/O server on the system NetId port 300 (device list,
  names, NetIds, type 94); system service port 10000 (ReadState,
  WriteControl RUN/STOP); device n's symbols and images on port 27904 + n;
  master n on its device NetId (system NetId, 5th byte n + 1) port 0xFFFF;
  each slave's CoE on port = its address (1001, 1002, ... in bus order).
- Names (facts 7, rack dump): `Term <k> (<type>).<PDO name>`; the master's
  `Device <n> (EtherCAT).Inputs` / `.Outputs`; per terminal with process
  data `.WcState.WcState` and, with inputs, `.WcState.InputToggle`; plus
  `SyncUnits._default_._unreferenced_.WcState.WcState`. InfoData
  (`.InfoData.State`, `.InfoData.AdsAddr`) only with `info_data: true` on a
  master: the rack dump has none (TwinCAT's default).
- Types (facts 4 and 7, `tctypes`): one-entry PDO = plain variable
  (a 1-bit one is a BIT in the bit image: rack dump `Term 54
  (EL1014).Channel 1`; `AI Compact Channel 1` INT per facts); several
  entries = BIGTYPE `<PDO>_TYPE` with `Status__X` entries grouped into a
  member `Status` (`AI Standard Channel 1_TYPE`: Status bits at +0, Value
  INT at +2); one type per layout (all channels share `..._Channel 1_TYPE`,
  a clash is numbered `_2_TYPE`); oversampled PDO = `<PDO> 0_TYPE_ARR`. The
  entry path of a one-entry PDO (`Channel 1.Input`) also resolves by name,
  as a real TwinCAT accepts it (pyads issue #456).
- Groups and offsets (rack dump, `layout`): inputs 0xF030 / 0xF031,
  outputs 0xF020 / 0xF021; byte PDOs packed in bus order, then BITs packed
  bit by bit; WcState / InputToggle are bits of the master's Frm0WcState /
  Frm0InputToggle, one per datagram (in+out: 1, out: 2, in: 3), shared by
  the terminals in it.
- Dynamic PDOs: only the selected PDO group's PDOs exist (chain
  `pdo_group`, else the YAML's `selected_pdo_group`, else the default).
- Sum commands (facts 3): 0xF080 / 0xF082 with per-item results; more than
  `system.max_sum_items` (500) sub-commands refuse the whole request with
  0x705 (Beckhoff's limit; the client is meant to split, as pyads does).
  0xF081 on the device port answers 0x701 as a real TwinCAT does (pyads
  issue #456) unless `system.sum_write_on_device_port: true`.
- Online change: symbol version (0xF008) + 1, every offset moves, handles
  taken before answer 0x711, values of surviving symbols are kept.
- Inputs: every input leaf has a generator, from the chain (`signal` per
  terminal, `signals` per symbol or member) or by default: counters count,
  toggles toggle, timestamps advance, digital channels are random bits held
  100 cycles, status bits stay 0, other values follow a sine. Values are
  functions of the cycle number and a per-leaf key from the seed, so runs
  repeat. Outputs keep what clients write.
- STOP: ReadState answers 6 on every port and inputs freeze.
- Slaves not in SAFEOP/OP or without link: their inputs freeze and their
  datagram's WcState bit is 1 (outputs need OP); CoE needs PREOP (0x707
  before, 0x719 without link). A lost slave's link byte is NOT_PRESENT, the
  slave before it shows MISSING_LINK on port B (Beckhoff ST_EcSlaveState);
  the master's Inputs show fewer slaves and DevState 1. Writing group 0x03
  with a state as offset moves the master and its slaves there (Beckhoff
  "ADS Interface" of the EtherCAT device).
"""
