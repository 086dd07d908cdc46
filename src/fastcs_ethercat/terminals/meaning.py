"""What a terminal's values mean: engineering units, alarm severities, texts.

The ESI says it in names and attributes, not in numbers, so the rules live
here, once, for the generator's report, the editor, the CLI and the IOC:

- **Scaling.** A PDO entry's `DScale` names the range its full-scale count
  stands for. Beckhoff's analog terminals (legacy range, the default of the
  terminals described here) put the nominal full scale at the largest
  positive count of the signed type: 0x7FFF for an INT, 0x7FFFFFFF for a
  DINT; the range's low end at 0. So `+/-10` on an INT is 10 V / 32767 per
  count, `4-20` is 4 mA at 0 and 20 mA at 32767, `0.1°` is 0.1 °C per count.
  A range names no unit except `+/-75mV`: Beckhoff's current ranges are
  `0-20` and `4-20` (mA), every other range is volts.
- **Severity.** A status bit (or bit field) that is set means what its name
  says: `Error`, `Sync error`, `TxPDO State` (the data are invalid),
  `Data invalid` and TwinCAT's `WcState` (the terminal's working counter is
  wrong) are MAJOR; `Underrange`, `Overrange` and the limit fields `Limit 1`,
  `Limit 2` (0 = inside, 1 = over, 2 = under) are MINOR. Outputs carry none.
- **Units of CoE objects.** The ESI `Unit` is the CiA 303-2 code: byte 3 the
  power of ten, byte 2 the SI unit, byte 1 a unit it is divided by.
- **Descriptions.** A value's DESC is built from the ESI names of its
  terminal type, PDO and entry, to fit a record's 40 characters.

Per symbol member, the terminal YAML may override scale, offset, unit,
precision and severity (`terminals units`, `terminals severity`, the editor);
`member_scaling` and `member_severity` give the result.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Final, Literal

from fastcs_ethercat.terminals.model import SeverityName, SymbolMember

RAW_SUFFIX: Final = " Raw"
"""Added to a scaled value's name for its raw count's PV (`...ValueRaw`)."""
MAX_PRECISION: Final = 6
"""Decimals shown at most: a DINT's count is nV, below any real resolution."""
MAX_DESCRIPTION: Final = 40
"""A record's DESC field holds 40 bytes."""
SEVERITY_LEVELS: Final[dict[SeverityName, int]] = {"none": 0, "minor": 1, "major": 2}
"""YAML severity -> EPICS alarm severity (menuAlarmSevr)."""

_FULL_SCALE: Final = {"SINT": 2**7 - 1, "INT": 2**15 - 1, "DINT": 2**31 - 1}
"""Largest positive count of the signed types Beckhoff scales."""
_NUMBER = r"\d+(?:\.\d+)?"
_SYMMETRIC = re.compile(rf"^\+/-\s*(?P<high>{_NUMBER})\s*(?P<unit>[A-Za-z]*)$")
_RANGE = re.compile(
    rf"^(?P<low>{_NUMBER})\s*-\s*(?P<high>{_NUMBER})\s*(?P<unit>[A-Za-z]*)$"
)
_STEP = re.compile(rf"^(?P<step>{_NUMBER})\s*°\s*(?P<unit>[CFK]?)$")
_CURRENT_LOOPS: Final = frozenset({(0.0, 20.0), (4.0, 20.0)})
"""Ranges Beckhoff uses for current inputs and outputs (mA)."""

_MAJOR = re.compile(r"^(error|sync error|txpdo state|data invalid|(frm\d+)?wcstate)$")
_MINOR = re.compile(r"^(underrange|overrange|limit \d+)$")

Direction = Literal["input", "output"]


@dataclass(frozen=True, slots=True)
class Scaling:
    """engineering = raw * scale + offset, shown in `unit` with `precision`
    decimals."""

    scale: float = 1.0
    offset: float = 0.0
    unit: str = ""
    precision: int | None = None
    """None: what the scale shows one count with (a float: its type's)."""

    @property
    def converts(self) -> bool:
        """Whether the engineering value differs from the raw one (and the raw
        count gets a PV of its own)."""
        return self.scale != 1.0 or self.offset != 0.0

    @property
    def decimals(self) -> int:
        """PREC: as set, else enough to show one count."""
        return precision_of(self.scale) if self.precision is None else self.precision

    def text(self) -> str:
        """`x 0.000488 +4 mA, 4 decimals`: for listings."""
        parts = [f"x {self.scale:.6g}"]
        if self.offset:
            parts.append(f"{self.offset:+.6g}")
        if self.unit:
            parts.append(self.unit)
        plural = "" if self.decimals == 1 else "s"
        return " ".join(parts) + f", {self.decimals} decimal{plural}"


def has_raw_twin(scaling: Scaling | None) -> bool:
    """Whether a value served with `scaling` gets its raw count's PV beside."""
    return scaling is not None and scaling.converts


def dscale_scaling(dscale: str, type_name: str) -> Scaling | None:
    """The scaling a Beckhoff `DScale` gives a value of `type_name`; None
    when the text or the type is not one whose meaning is known."""
    text = " ".join(dscale.split())
    if step := _STEP.match(text):
        scale = float(step["step"])
        unit = "deg" + (step["unit"] or "C")
        return Scaling(scale, 0.0, unit)
    full_scale = _FULL_SCALE.get(type_name)
    if full_scale is None:
        return None
    if symmetric := _SYMMETRIC.match(text):
        low, high, unit = 0.0, float(symmetric["high"]), symmetric["unit"] or "V"
    elif span := _RANGE.match(text):
        low, high = float(span["low"]), float(span["high"])
        unit = span["unit"] or ("mA" if (low, high) in _CURRENT_LOOPS else "V")
    else:
        return None
    return Scaling((high - low) / full_scale, low, unit)


def precision_of(scale: float) -> int:
    """Decimals that show one count (at most `MAX_PRECISION`)."""
    if scale <= 0 or not math.isfinite(scale):
        return 0
    return max(0, min(MAX_PRECISION, math.ceil(-math.log10(scale) - 1e-9)))


def member_scaling(member: SymbolMember) -> Scaling | None:
    """What the member's value is served as: its `DScale` with the YAML's
    overrides on top; None for a raw value without a unit, and for a status
    bit or bit field."""
    if is_status(member):
        return None
    derived = dscale_scaling(member.dscale, member.type_name) if member.dscale else None
    overridden = (member.scale, member.offset, member.unit, member.precision)
    if all(value is None for value in overridden):
        return derived
    base = derived or Scaling()
    return Scaling(
        scale=base.scale if member.scale is None else member.scale,
        offset=base.offset if member.offset is None else member.offset,
        unit=base.unit if member.unit is None else member.unit,
        precision=base.precision if member.precision is None else member.precision,
    )


def is_status(member: SymbolMember) -> bool:
    """A status or control bit or bit field (`BIT`, `BIT2`): a state, not a
    value with units."""
    return member.type_name.startswith("BIT")


def severity_of_name(name: str, direction: Direction = "input") -> SeverityName:
    """The severity of a status bit or field that is set, from its ESI name
    (`Status__Error`, `Limit 1`, `WcState`); outputs carry none."""
    if direction != "input":
        return "none"
    last = re.split(r"__|\.", name)[-1]
    word = " ".join(last.split()).lower()
    if _MAJOR.match(word):
        return "major"
    if _MINOR.match(word):
        return "minor"
    return "none"


def member_severity(member: SymbolMember, direction: Direction) -> SeverityName:
    """The member's severity when set: the YAML's override, else its name's."""
    if member.severity is not None:
        return member.severity
    if member.bit_size > 8:  # a value, not a status bit or field
        return "none"
    return severity_of_name(member.name, direction)


# -- CoE units (CiA 303-2) -------------------------------------------------------

_SI_UNITS: Final = {
    0x00: "",
    0x01: "m",
    0x02: "kg",
    0x03: "s",
    0x04: "A",
    0x05: "K",
    0x06: "mol",
    0x07: "cd",
    0x10: "rad",
    0x11: "sr",
    0x20: "Hz",
    0x21: "N",
    0x22: "Pa",
    0x23: "J",
    0x24: "W",
    0x25: "C",
    0x26: "V",
    0x27: "F",
    0x28: "Ohm",
    0x29: "S",
    0x2A: "Wb",
    0x2B: "T",
    0x2C: "H",
    0x2D: "degC",
    0x2E: "lm",
    0x2F: "lx",
    0x30: "Bq",
    0x31: "Gy",
    0x32: "Sv",
}
"""CiA 303-2's base, supplementary and derived SI units, ASCII-spelt (EGU)."""
_PREFIXES: Final = {-9: "n", -6: "u", -3: "m", 0: "", 3: "k", 6: "M", 9: "G"}


def coe_unit(code: str | None) -> str:
    """The EGU text of an ESI `Unit` (`#xfd040000` -> `mA`); "" when unknown."""
    if not code:
        return ""
    try:
        value = int(code.strip().lower().removeprefix("#x").removeprefix("0x"), 16)
    except ValueError:
        return ""
    exponent = (value >> 24) & 0xFF
    exponent = exponent - 0x100 if exponent >= 0x80 else exponent
    numerator = _SI_UNITS.get((value >> 16) & 0xFF)
    denominator = _SI_UNITS.get((value >> 8) & 0xFF)
    if numerator is None or denominator is None:
        return ""
    power = 3 * math.floor(exponent / 3)
    mantissa = "" if exponent == power else str(10 ** (exponent - power))
    prefix = _PREFIXES.get(power)
    if prefix is None:
        return ""
    text = f"{mantissa}{prefix}{numerator}" if numerator or prefix or mantissa else ""
    if denominator:
        text = f"{text or '1'}/{denominator}"
    return text


# -- descriptions ---------------------------------------------------------------

_CHANNEL_WORD = re.compile(r"\bChannel\s+(\d+)\b")


def describe(type_name: str | None, symbol: str, member: str | None = None) -> str:
    """A DESC from ESI names within 40 characters: `EL3104 AI Standard Ch1
    Underrange` (type, PDO, the entry's last name part); the type goes first
    when there is room for it."""
    words = _CHANNEL_WORD.sub(r"Ch\1", symbol).replace(".", " ").split()
    if member:
        words += member.split("__")[-1].replace(".", " ").split()
    kept: list[str] = []
    for word in words:  # `WcState.WcState` once
        if not kept or kept[-1] != word:
            kept.append(word)
    text = " ".join(kept)
    if type_name and len(type_name) + 1 + len(text) <= MAX_DESCRIPTION:
        return f"{type_name} {text}"
    return text[:MAX_DESCRIPTION].rstrip()
