"""What every benchmark section needs: where things are and how much to do."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True, slots=True)
class BenchPlan:
    """The sizes and repeats of one run (`--quick` or full)."""

    chain_sizes: tuple[int, ...] = (20, 104, 500)
    scan_symbols: tuple[int, ...] = (1000, 5000, 10000)
    latency_rates_hz: tuple[float, ...] = (10.0, 100.0)
    runs: int = 3
    """Repeats of each start-up (CoE: one) and CPU window; medians are kept."""
    window_s: float = 5.0
    """Length of one CPU window and of the update count."""
    latency_samples: int = 200
    start_timeout_s: float = 180.0
    coe_chain_sizes: tuple[int, ...] | None = None
    """Chain sizes also started with every CoE object selected (None: all)."""
    deadband_symbols: int = 1000
    """Symbols of the deadband run (noisy analog values, a client monitoring)."""

    def starts(self) -> list[tuple[int, bool]]:
        """(terminals, with CoE) of every start-up to measure."""
        coe_sizes = self.coe_chain_sizes
        if coe_sizes is None:
            coe_sizes = self.chain_sizes
        return [
            (size, coe)
            for size in self.chain_sizes
            for coe in (False, True)
            if not coe or size in coe_sizes
        ]


QUICK_PLAN = BenchPlan(
    chain_sizes=(20, 104),
    scan_symbols=(1000, 10000),
    latency_rates_hz=(10.0, 100.0),
    runs=1,
    window_s=2.0,
    latency_samples=30,
    start_timeout_s=60.0,
    coe_chain_sizes=(20,),
)
FULL_PLAN = BenchPlan()


@dataclass(frozen=True, slots=True)
class BenchContext:
    """Inputs (terminal YAML, ESI files, demo chain) and a scratch directory."""

    terminals: Path
    esi: Path
    demo_chain: Path
    scratch: Path
    plan: BenchPlan = field(default_factory=BenchPlan)
    extra_esi: tuple[Path, ...] = ()
    """Further ESI files for `terminals regenerate` (e.g. a test fixture)."""
