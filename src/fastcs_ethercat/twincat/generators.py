"""Deterministic signal generators that drive the input image each cycle.

Every input leaf (a scalar symbol, a structure member or an array element)
gets one generator: the chain's per-symbol or per-terminal choice, else a
default by name (counters count, toggles toggle, channel bits flip now and
then, analog values follow a sine, status bits stay 0). Values are pure
functions of the cycle number and a per-leaf key drawn from the seed, so a
run is reproducible however often `tick` is called; all leaves are computed
at once with numpy.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt

from fastcs_ethercat.chain.file import SignalSpec
from fastcs_ethercat.twincat.layout import SymbolDef
from fastcs_ethercat.twincat.tctypes import TcType

KINDS: Final = ("constant", "counter", "ramp", "sine", "random_bits")
CHANNEL_BIT_HOLD_CYCLES: Final = 100
"""Default: a digital input channel changes at most every 100 cycles (1 s)."""
_GOLDEN: Final = np.uint64(0x9E3779B97F4A7C15)
_ARRAY_INDEX: Final = re.compile(r"\[-?\d+\]")


@dataclass(frozen=True, slots=True)
class Leaf:
    """One scalar place in the input image that a generator drives."""

    name: str
    """Full name below the device (`Term 5 (EL3104).AI Standard Channel 1.Value`)."""
    relative: str
    """Name below the terminal (`AI Standard Channel 1.Value`)."""
    bit_address: int
    kind: TcType
    slave: int
    top_level: bool
    """The leaf is a whole symbol (a one-entry PDO)."""
    sample: float = 0.0
    """For array elements: position within the cycle (oversampling)."""
    signal_name: str = ""
    """Name the generator is keyed by: an array's elements share one."""


def input_leaves(
    symbols: Iterable[SymbolDef], slave_names: Mapping[int, str]
) -> list[Leaf]:
    """Every scalar below the terminals' input symbols (runtime ones excluded)."""
    leaves: list[Leaf] = []
    for symbol in symbols:
        if symbol.runtime or symbol.slave is None or symbol.area.name != "inputs":
            continue
        prefix = f"{slave_names[symbol.slave]}."
        relative = symbol.name.removeprefix(prefix)
        for name, address, kind, sample in _scalars(
            relative, symbol.bit_address, symbol.type
        ):
            leaves.append(
                Leaf(
                    name=f"{prefix}{name}",
                    relative=name,
                    bit_address=address,
                    kind=kind,
                    slave=symbol.slave,
                    top_level=kind is symbol.type,
                    sample=sample,
                    signal_name=f"{prefix}{_ARRAY_INDEX.sub('', name)}",
                )
            )
    return leaves


def _scalars(
    name: str, address: int, kind: TcType, sample: float = 0.0
) -> Iterator[tuple[str, int, TcType, float]]:
    if kind.members:
        for member in kind.members:
            yield from _scalars(
                f"{name}.{member.name}",
                address + member.bit_offset,
                member.type,
                sample,
            )
    elif kind.element is not None:
        step = kind.element.byte_size * 8
        for i in range(kind.count):
            yield from _scalars(
                f"{name}[{kind.lower_bound + i}]",
                address + i * step,
                kind.element,
                i / kind.count,
            )
    else:
        yield name, address, kind, sample


def default_signal(leaf: Leaf, cycle_s: float) -> SignalSpec:
    """What a leaf does when the chain does not say (see module docstring)."""
    last = leaf.relative.rsplit(".", 1)[-1].casefold().replace(" ", "")
    path = leaf.relative.casefold()
    if "toggle" in last:
        return SignalSpec(kind="counter", step=1)
    if leaf.kind.is_bit:
        if leaf.top_level:
            return SignalSpec(kind="random_bits", hold_cycles=CHANNEL_BIT_HOLD_CYCLES)
        return SignalSpec(kind="constant")
    if "counter" in last or "cyclecount" in last:
        return SignalSpec(kind="counter", step=1)
    if "time" in path and last not in {"hi", "high"}:
        return SignalSpec(kind="counter", step=round(cycle_s * 1e9))
    if ".status" in path or last in {"status", "state"}:
        return SignalSpec(kind="constant")
    return SignalSpec(kind="sine", period_s=2.0)


def leaf_key(seed: int, device: str, name: str) -> int:
    """A stable 64-bit key per leaf (independent of Python's hash seed)."""
    digest = hashlib.blake2b(f"{seed}\0{device}\0{name}".encode(), digest_size=8)
    return int.from_bytes(digest.digest(), "little")


def _range(kind: TcType) -> tuple[float, float]:
    scalar = kind.scalar
    assert scalar is not None
    if kind.is_bit:
        return 0.0, float((1 << kind.bit_size) - 1)
    if scalar.kind == "float":
        return -10.0, 10.0
    if scalar.kind == "bool":
        return 0.0, 1.0
    info = np.iinfo(scalar.dtype)
    return float(info.min), float(info.max)


class SignalBank:
    """All generators of one device, evaluated together each cycle."""

    def __init__(
        self,
        leaves: list[Leaf],
        specs: list[SignalSpec],
        keys: list[int],
        cycle_s: float,
    ) -> None:
        self.leaves = leaves
        self.cycle_s = cycle_s
        count = len(leaves)
        self.names = {leaf.name.casefold(): i for i, leaf in enumerate(leaves)}
        self._kind = np.array([KINDS.index(s.kind) for s in specs], dtype=np.int8)
        lows, highs = (
            zip(*(_range(leaf.kind) for leaf in leaves), strict=True)
            if count
            else ((), ())
        )
        floats = [_is_float(leaf.kind) for leaf in leaves]
        self._low = np.array(
            [-np.inf if f else lo for f, lo in zip(floats, lows, strict=True)],
            dtype=np.float64,
        )
        self._high = np.array(
            [np.inf if f else hi for f, hi in zip(floats, highs, strict=True)],
            dtype=np.float64,
        )
        self._value = np.array([s.value for s in specs], dtype=np.float64)
        self._start = np.array([s.start for s in specs], dtype=np.float64)
        self._step = np.array([s.step for s in specs], dtype=np.float64)
        self._ramp_low = np.array(
            [
                lo if s.minimum is None else s.minimum
                for s, lo in zip(specs, lows, strict=True)
            ],
            dtype=np.float64,
        )
        self._ramp_high = np.array(
            [
                hi if s.maximum is None else s.maximum
                for s, hi in zip(specs, highs, strict=True)
            ],
            dtype=np.float64,
        )
        self._period = np.array([s.period_s for s in specs], dtype=np.float64)
        self._amplitude = np.array(
            [
                _amplitude(s, lo, hi)
                for s, lo, hi in zip(specs, lows, highs, strict=True)
            ],
            dtype=np.float64,
        )
        self._offset = np.array(
            [_centre(s, lo, hi) for s, lo, hi in zip(specs, lows, highs, strict=True)],
            dtype=np.float64,
        )
        self._key = np.array(keys, dtype=np.uint64)
        self._phase = np.array(
            [
                math.radians(s.phase_deg)
                if s.phase_deg is not None
                else (k % 3600) * math.pi / 1800
                for s, k in zip(specs, keys, strict=True)
            ],
            dtype=np.float64,
        )
        self._hold = np.array([s.hold_cycles for s in specs], dtype=np.uint64)
        self._sample = np.array([leaf.sample for leaf in leaves], dtype=np.float64)
        self._slave = np.array([leaf.slave for leaf in leaves], dtype=np.int64)
        self._pinned = np.zeros(count, dtype=bool)
        self._live = np.ones(count, dtype=bool)
        self._groups = _storage_groups(leaves)

    def __len__(self) -> int:
        return len(self.leaves)

    def set_live_slaves(self, live: set[int]) -> None:
        """Only slaves exchanging process data get new input values."""
        self._live = np.isin(self._slave, np.array(sorted(live), dtype=np.int64))

    def pin(self, names: Iterable[str]) -> None:
        """Stop driving these leaves (a value set from outside stays)."""
        for name in names:
            index = self.names.get(name.casefold())
            if index is not None:
                self._pinned[index] = True

    def unpin_all(self) -> None:
        self._pinned[:] = False

    def values(
        self, cycle: int
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint64]]:
        """Analog values (float) and raw integer values (uint64) per leaf."""
        t = (cycle + self._sample) * self.cycle_s
        angle = 2 * np.pi * t / self._period
        analog = np.where(
            self._kind == 0,
            self._value,
            np.where(
                self._kind == 2,
                self._ramp_low
                + (self._ramp_high - self._ramp_low) * np.mod(t / self._period, 1.0),
                self._offset + self._amplitude * np.sin(angle + self._phase),
            ),
        )
        with np.errstate(over="ignore"):
            counter = (self._start + self._step * cycle).astype(np.float64)
            draws = _splitmix64(self._key ^ (np.uint64(cycle) // self._hold) * _GOLDEN)
        analog = np.clip(analog, self._low, self._high)
        return np.where(self._kind == 1, counter, analog), draws

    def apply(self, buffer: bytearray, cycle: int) -> None:
        """Write every driven leaf's value for `cycle` into the image."""
        if not len(self.leaves):
            return
        analog, draws = self.values(cycle)
        driven = self._live & ~self._pinned
        image = np.frombuffer(buffer, dtype=np.uint8)
        for group in self._groups:
            chosen = group.indices[driven[group.indices]]
            if not len(chosen):
                continue
            group.write(
                image, chosen, analog[chosen], draws[chosen], self._kind[chosen] == 4
            )


def _is_float(kind: TcType) -> bool:
    return kind.scalar is not None and kind.scalar.kind == "float"


def _amplitude(spec: SignalSpec, low: float, high: float) -> float:
    if spec.amplitude is not None:
        return spec.amplitude
    return 0.8 * (high - low) / 2


def _centre(spec: SignalSpec, low: float, high: float) -> float:
    if spec.amplitude is None and spec.offset == 0.0:
        return (high + low) / 2
    return spec.offset


def _splitmix64(values: npt.NDArray[np.uint64]) -> npt.NDArray[np.uint64]:
    """A counter-based 64-bit mixer: same input, same output, well spread."""
    with np.errstate(over="ignore"):
        z = values + _GOLDEN
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


class _StorageGroup:
    """Leaves stored the same way: one numpy dtype at byte offsets, or bits."""

    def __init__(
        self, leaves: list[Leaf], indices: list[int], dtype: np.dtype | None
    ) -> None:
        self.indices = np.array(indices, dtype=np.int64)
        self.dtype = dtype
        self.float = dtype is not None and dtype.kind == "f"
        self.bits = (
            np.array([leaves[i].kind.bit_size for i in indices], dtype=np.uint64)
            if dtype is None
            else None
        )
        self.address = np.array(
            [leaves[i].bit_address for i in indices], dtype=np.int64
        )
        self.width = 8 * dtype.itemsize if dtype is not None else 0

    def write(
        self,
        image: npt.NDArray[np.uint8],
        chosen: npt.NDArray[np.int64],
        analog: npt.NDArray[np.float64],
        draws: npt.NDArray[np.uint64],
        random: npt.NDArray[np.bool_],
    ) -> None:
        positions = np.searchsorted(self.indices, chosen)
        address = self.address[positions]
        if self.dtype is None:
            assert self.bits is not None
            widths = self.bits[positions]
            raw = _integers(analog, draws, random, widths)
            _write_bits(image, address, widths, raw)
            return
        if self.float:
            values = np.where(
                random, (draws >> np.uint64(11)) / 2.0**53 * 20.0 - 10.0, analog
            )
            data = values.astype(self.dtype)
        else:
            width = np.full(len(chosen), self.width, dtype=np.uint64)
            raw = _integers(analog, draws, random, width)
            data = raw.astype(np.dtype(f"<u{self.dtype.itemsize}"))
        size = self.dtype.itemsize
        targets = (address // 8)[:, None] + np.arange(size)
        image[targets] = data.view(np.uint8).reshape(-1, size)


def _integers(
    analog: npt.NDArray[np.float64],
    draws: npt.NDArray[np.uint64],
    random: npt.NDArray[np.bool_],
    widths: npt.NDArray[np.uint64],
) -> npt.NDArray[np.uint64]:
    """Raw two's-complement bits of each value, wrapped to its width."""
    rounded = np.floor(analog + 0.5)
    limit = 2.0**63
    clipped = np.clip(rounded, -limit, limit - 1024)
    as_int = clipped.astype(np.int64).view(np.uint64)
    raw = np.asarray(np.where(random, draws, as_int), dtype=np.uint64)
    shift = np.minimum(widths, np.uint64(63))
    mask = np.asarray(
        np.where(
            widths >= 64,
            np.uint64(0xFFFF_FFFF_FFFF_FFFF),
            (np.uint64(1) << shift) - np.uint64(1),
        ),
        dtype=np.uint64,
    )
    return np.bitwise_and(raw, mask)


def _write_bits(
    image: npt.NDArray[np.uint8],
    address: npt.NDArray[np.int64],
    widths: npt.NDArray[np.uint64],
    raw: npt.NDArray[np.uint64],
) -> None:
    for bit in range(int(widths.max()) if len(widths) else 0):
        use = widths > bit
        where = address[use] + bit
        byte = where >> 3
        shift = (where & 7).astype(np.uint8)
        value = ((raw[use] >> np.uint64(bit)) & np.uint64(1)).astype(np.uint8)
        np.bitwise_and.at(image, byte, ~(np.uint8(1) << shift))
        np.bitwise_or.at(image, byte, value << shift)


def _storage_groups(leaves: list[Leaf]) -> list[_StorageGroup]:
    by_dtype: dict[str, list[int]] = {}
    for index, leaf in enumerate(leaves):
        scalar = leaf.kind.scalar
        assert scalar is not None
        aligned = leaf.bit_address % 8 == 0 and leaf.kind.bit_size % 8 == 0
        if leaf.kind.is_bit or not aligned or scalar.kind not in {"int", "float"}:
            by_dtype.setdefault("bits", []).append(index)
        else:
            by_dtype.setdefault(scalar.dtype.str, []).append(index)
    return [
        _StorageGroup(leaves, indices, None if key == "bits" else np.dtype(key))
        for key, indices in by_dtype.items()
    ]


__all__ = ["Leaf", "SignalBank", "default_signal", "input_leaves", "leaf_key"]
