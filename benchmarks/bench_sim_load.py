"""Simulator start-up and hot-path speed on a rack of 100+ terminals.

Usage: python benchmarks/bench_sim_load.py [CHAIN] [--terminals DIR] [--runs N]

Prints the median of N runs (default 5) of:
- loading the chain and its terminal YAML and building the model, the way
  `fastcs-ethercat sim` starts (target: < 1 s for >= 100 terminals),
- building the model alone from already parsed terminal types,
- one task cycle (`tick`) of the whole rack,
- one sum read of 500 symbols through `handle` (encode, serve, decode),
the symbol count and the table sizes. Default chain: ioc/rack-chain.yaml.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from fastcs_ethercat.ads.constants import IndexGroup
from fastcs_ethercat.ads.sums import SumReadItem, SumReadRequest
from fastcs_ethercat.chain.file import load_chain
from fastcs_ethercat.sim.probe import device_probe
from fastcs_ethercat.twincat.resolve import registry_for
from fastcs_ethercat.twincat.target import SimTarget

REPO = Path(__file__).resolve().parents[1]
DEFAULT_CHAIN = REPO / "ioc" / "rack-chain.yaml"
DEFAULT_TERMINALS = REPO / "terminals"


def median_seconds(action: Callable[[], object], runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description="simulator load benchmark")
    parser.add_argument("chain", nargs="?", type=Path, default=DEFAULT_CHAIN)
    parser.add_argument("--terminals", type=Path, default=DEFAULT_TERMINALS)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()

    load = median_seconds(
        lambda: SimTarget.from_chain(args.chain, args.terminals), args.runs
    )
    chain = load_chain(args.chain)
    types = {slave.type for master in chain.masters for slave in master.slaves}
    registry = registry_for(args.terminals, types)
    build = median_seconds(lambda: SimTarget(chain, registry), args.runs)
    target = SimTarget(chain, registry)
    summary = target.describe()

    now = [0.0]

    def tick() -> None:
        now[0] += target.cycle_s
        target.tick(now[0])

    cycle = median_seconds(tick, max(args.runs, 50))

    probe = device_probe(target, target.system_net_id)
    symbols = target.devices[0].table.symbols
    items = tuple(
        SumReadItem(s.index_group, s.index_offset, s.size)
        for s in (symbols * (500 // len(symbols) + 1))[:500]
    )
    request = SumReadRequest(items)
    payload = request.encode()

    def sum_read() -> None:
        answer = probe.read_write(
            IndexGroup.SUMUP_READ, len(items), request.read_length, payload
        )
        assert answer.result == 0

    read = median_seconds(sum_read, max(args.runs, 20))
    table = target.devices[0].table
    print(
        f"chain {args.chain.name}: {summary['slaves']} slaves, {len(types)} types, "
        f"{summary['symbols']} symbols, symbol table {len(table.upload)} B, "
        f"data types {len(table.data_types)} B"
    )
    print(
        f"load chain + terminal YAML + build: {load * 1000:8.1f} ms  (target < 1000 ms)"
    )
    print(f"build model from parsed YAML:       {build * 1000:8.1f} ms")
    print(f"one task cycle (tick):              {cycle * 1e6:8.1f} us")
    print(f"sum read of 500 symbols via handle: {read * 1e6:8.1f} us")


if __name__ == "__main__":
    main()
