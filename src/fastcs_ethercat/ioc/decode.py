"""The hot path's bookkeeping: points -> sum-read items -> one numpy view.

Every point is read through the handle of its source symbol (`ioc.handles`):
points of one symbol (its members, the bits of its status word) share one
sum-read item. Each request's answer is viewed with one structured dtype (a
field per point, at the point's byte in the answer); change detection compares
the answer's bytes with the previous answer's, vectorised, and only changed
points are converted to Python values.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from fastcs_ethercat.ads.constants import MAX_SUM_SUB_COMMANDS, IndexGroup
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.sums import SumReadItem, SumReadLayout
from fastcs_ethercat.ads.values import parse_type
from fastcs_ethercat.ioc.plan import Point, PointKind


def plan_items(
    points: Sequence[Point], handles: Mapping[str, int]
) -> tuple[list[SumReadItem], list[tuple[int, int]]]:
    """One sum-read item per source symbol: its read handle (0xF005), read
    from its first byte to the last byte any of its points needs (a read by
    handle shorter than the symbol gets its first bytes).

    Returns the items and, per point, (item index, byte offset in the item).
    Every point's source must have a handle.
    """
    item_of: dict[str, int] = {}
    lengths: list[int] = []
    where: list[tuple[int, int]] = []
    for point in points:
        name = point.source_name
        n = item_of.get(name)
        if n is None:
            n = item_of[name] = len(lengths)
            lengths.append(0)
        end = point.source_offset + max(point.byte_size, 1)
        lengths[n] = max(lengths[n], end)
        where.append((n, point.source_offset))
    items = [
        SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, handles[name], lengths[n])
        for name, n in item_of.items()
    ]
    return items, where


def point_dtype(point: Point) -> np.dtype[Any]:
    """The numpy dtype of a point's bytes (BIT/BITS: the bytes that hold it)."""
    if point.kind in (PointKind.BIT, PointKind.BITS):
        return np.dtype(("u1", (max(point.byte_size, 1),)))
    parsed = parse_type(point.type_name)
    if point.kind is PointKind.ARRAY:
        return np.dtype((parsed.dtype, (point.length,)))
    if parsed.size != point.byte_size:
        return np.dtype(("u1", (point.byte_size,)))
    return parsed.dtype


@dataclass(slots=True)
class ChunkDecoder:
    """One sum request: its items, its answer layout and the previous answer."""

    items: list[SumReadItem]
    points: list[Point]
    point_items: npt.NDArray[np.intp]
    """Per point: its item's index within this request."""
    dtype: np.dtype[Any]
    starts: npt.NDArray[np.intp]
    ends: npt.NDArray[np.intp]
    bit_index: npt.NDArray[np.intp]
    """Points of kind BIT/BITS, and for them: byte, shift and mask."""
    bit_byte: npt.NDArray[np.intp]
    bit_shift: npt.NDArray[np.uint64]
    bit_mask: npt.NDArray[np.uint64]
    answer_size: int
    previous: npt.NDArray[np.uint8] | None = None
    previous_results: npt.NDArray[np.uint32] | None = None
    previous_bits: npt.NDArray[np.uint64] | None = None
    converters: list[Any] = field(default_factory=list)
    bit_position: dict[int, int] = field(default_factory=dict)
    single_bit: list[bool] = field(default_factory=list)
    """Per bit field: one bit (its value a bool), else an int."""
    fields: list[str] = field(default_factory=list)
    """Per point: its field's name in `dtype`."""

    @classmethod
    def build(
        cls,
        items: list[SumReadItem],
        points: list[Point],
        point_items: list[int],
        offsets_in_item: list[int],
    ) -> ChunkDecoder:
        layout = SumReadLayout.of(items)
        starts = layout.data_offsets[np.array(point_items, dtype=np.intp)] + np.array(
            offsets_in_item, dtype=np.intp
        )
        sizes = np.array([max(p.byte_size, 1) for p in points], dtype=np.intp)
        names = [f"p{i}" for i in range(len(points))]
        fields = [
            (name, point_dtype(p), int(start))
            for name, p, start in zip(names, points, starts.tolist(), strict=True)
        ]
        bits = [
            i for i, p in enumerate(points) if p.kind in (PointKind.BIT, PointKind.BITS)
        ]
        bit_byte = np.array(
            [starts[i] + points[i].bit_offset // 8 for i in bits], dtype=np.intp
        )
        bit_shift = np.array([points[i].bit_offset % 8 for i in bits], dtype=np.uint64)
        bit_mask = np.array(
            [(1 << max(points[i].bit_size, 1)) - 1 for i in bits], dtype=np.uint64
        )
        return cls(
            items=items,
            points=points,
            point_items=np.array(point_items, dtype=np.intp),
            dtype=layout.dtype(fields),
            starts=starts,
            ends=starts + sizes,
            bit_index=np.array(bits, dtype=np.intp),
            bit_byte=bit_byte,
            bit_shift=bit_shift,
            bit_mask=bit_mask,
            answer_size=layout.size,
            converters=[_converter(p) for p in points],
            bit_position={p: n for n, p in enumerate(bits)},
            single_bit=[points[i].bit_size <= 1 for i in bits],
            fields=names,
        )

    def invalidate(self) -> None:
        """Report every point on the next answer (after errors, reconnects)."""
        self.previous = None
        self.previous_results = None
        self.previous_bits = None

    def decode(
        self, answer: bytes
    ) -> tuple[list[tuple[Point, object]], list[tuple[Point, int]]]:
        """Changed values and per-point errors of one answer."""
        if len(answer) != self.answer_size:
            raise AdsCodecError(
                f"sum read answer is {len(answer)} bytes, expected {self.answer_size}"
            )
        raw = np.frombuffer(answer, dtype=np.uint8)
        view = np.frombuffer(answer, dtype=self.dtype)[0]
        results: npt.NDArray[np.uint32] = view["results"]
        point_results = results[self.point_items]
        ok = point_results == 0
        # A 16-bit window per bit field (padded so the last byte has a neighbour).
        padded = np.concatenate((raw, np.zeros(1, dtype=np.uint8)))
        low = padded[self.bit_byte].astype(np.uint64)
        high = padded[self.bit_byte + 1].astype(np.uint64)
        words = low | (high << np.uint64(8))
        bit_values = (words >> self.bit_shift) & self.bit_mask
        if self.previous is None or self.previous_results is None:
            changed = ok.copy()
        else:
            changed_bytes = np.concatenate(([0], np.cumsum(raw != self.previous)))
            changed = changed_bytes[self.ends] != changed_bytes[self.starts]
            if self.previous_bits is not None and len(self.bit_index):
                changed[self.bit_index] = bit_values != self.previous_bits
            recovered = self.previous_results[self.point_items] != 0
            changed = (changed | recovered) & ok
        self.previous = raw.copy()
        self.previous_results = results.copy()
        self.previous_bits = bit_values
        changes: list[tuple[Point, object]] = []
        points, bit_position, single = self.points, self.bit_position, self.single_bit
        bits: list[int] = bit_values.tolist()  # one conversion, not one per bit
        for i in np.flatnonzero(changed).tolist():
            n = bit_position.get(i)
            if n is not None:
                value = bits[n]
                changes.append((points[i], bool(value) if single[n] else value))
            else:
                changes.append((points[i], self.converters[i](view[self.fields[i]])))
        errors = [
            (self.points[i], int(point_results[i]))
            for i in np.flatnonzero(~ok).tolist()
        ]
        return changes, errors


def _converter(point: Point) -> Any:
    """numpy field value -> the Python value FastCS gets."""
    if point.kind is PointKind.ARRAY:
        return lambda value: np.array(value, copy=True)
    parsed = parse_type(point.type_name)
    if parsed.size != point.byte_size:
        return lambda value: bytes(value)
    if parsed.kind == "bool":
        return lambda value: bool(value)
    if parsed.kind in ("int", "bits"):
        return lambda value: int(value)
    if parsed.kind == "float":
        return lambda value: float(value)
    if parsed.kind == "string":
        return lambda value: bytes(value).split(b"\0", 1)[0].decode("cp1252", "replace")
    return lambda value: parsed.unpack(bytes(value))


@dataclass(slots=True)
class PollLayout:
    """Every point of one master split into sum requests of <= 500 items."""

    points: list[Point]
    chunks: list[ChunkDecoder]

    @classmethod
    def build(
        cls,
        points: Sequence[Point],
        handles: Mapping[str, int],
        chunk_size: int = MAX_SUM_SUB_COMMANDS,
    ) -> PollLayout:
        """The layout of `points`, each read by its source's handle."""
        items, where = plan_items(points, handles)
        chunks: list[ChunkDecoder] = []
        for first in range(0, len(items), chunk_size):
            chunk_items = items[first : first + chunk_size]
            members = [
                i for i, (n, _) in enumerate(where) if first <= n < first + chunk_size
            ]
            chunks.append(
                ChunkDecoder.build(
                    chunk_items,
                    [points[i] for i in members],
                    [where[i][0] - first for i in members],
                    [where[i][1] for i in members],
                )
            )
        return cls(list(points), chunks)

    def invalidate(self) -> None:
        for chunk in self.chunks:
            chunk.invalidate()
