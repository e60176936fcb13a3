"""What an impaired datagram path does, written as text: `loss=5%,burst=3,delay=40ms,jitter=10ms`.

Grammar (keys in any order, each at most once, whitespace around items and `=` ignored, keys and
units in any case)::

    spec   = "" | "none" | item *("," item)
    item   = key "=" value
    key    = "loss" | "burst" | "delay" | "jitter" | "reorder" | "gap" | "duplicate" | "corrupt"
    value  = probability (loss, reorder, duplicate, corrupt)
           | time        (delay, jitter, gap)
           | number      (burst)
    probability = number "%" | number          ; "5%" and "0.05" are the same; 0..1
    time        = number ("ms" | "s" | "us") | "0"   ; 0 to 10 s (MOST_TIME)
    number      = digits ["." digits] [("e" | "E") ["+" | "-"] digits]

Every number is finite and in its range: a probability 0..1 (0% to 100%), a time 0 to 10 s, burst
1 to 1,000 datagrams. A longer delay is no impaired path but a broken one, and a test under it
only waits; a mean burst of more than 1,000 losses is an outage (`loss=100%`).

`str(impairment)` gives the canonical spec back: the keys above in that order, only those that are
not at their default, probabilities in percent and times in milliseconds whenever that reads back
as exactly the same float (else a fraction, or seconds), and `none` for no impairment. So
`parse_impairment(str(x)) == x` for every `Impairment`.

What each key means is documented on `Impairment`; the semantics are netem's where netem has one,
and the differences are said there. `channel.ImpairedChannel` applies it to one direction.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields

from rcmlconf.errors import RcmlconfError

__all__ = [
    "DEFAULT_GAP",
    "KEYS",
    "MOST_BURST",
    "MOST_TIME",
    "Impairment",
    "ImpairmentError",
    "parse_impairment",
]

#: The keys of a spec, in canonical order.
KEYS = ("loss", "burst", "delay", "jitter", "reorder", "gap", "duplicate", "corrupt")
_PROBABILITIES = frozenset({"loss", "reorder", "duplicate", "corrupt"})
_TIMES = frozenset({"delay", "jitter", "gap"})
#: A held-back datagram waits at least this much longer when `gap` is not given.
DEFAULT_GAP = 0.010
#: The longest delay, jitter or gap (seconds), and the longest mean burst (datagrams).
MOST_TIME = 10.0
MOST_BURST = 1000.0

_NUMBER = re.compile(r"([+-]?)((?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:e[+-]?[0-9]+)?)(.*)", re.I)
_TIME_UNITS = {"s": 1.0, "ms": 1e3, "us": 1e6, "µs": 1e6}


class ImpairmentError(RcmlconfError):
    """A spec that is not one: why (`reason`) and where (`column`, 1-based; None when the
    `Impairment` was built directly rather than parsed)."""

    def __init__(self, reason: str, column: int | None = None) -> None:
        super().__init__(reason if column is None else f"column {column}: {reason}")
        self.reason = reason
        self.column = column


@dataclass(frozen=True, slots=True)
class Impairment:
    """What happens to each datagram on one direction of a path. The default: nothing.

    Each setting has its own random draw for every datagram, taken whatever the settings (so for
    one seed, the datagrams lost stay the same when only the delay changes):

    - `loss`: the average probability that a datagram is lost (netem `loss`). Without `burst` the
      losses are independent (netem `loss random`).
    - `burst`: with it, losses follow a simple Gilbert model (netem `loss gemodel p r 100% 0%`):
      a Good state that loses nothing and a Bad one that loses everything, the chance to leave
      Bad being `1/burst` per datagram and to enter it chosen so that the average loss is still
      `loss`. So `burst` is the mean length of a run of consecutive losses (at least 1). A run of
      independent losses has mean length 1/(1 - loss) already, and a run cannot be too short for
      its rate: `burst` must be at least loss/(1 - loss) (at most 50% loss with burst=1).
    - `duplicate`: the probability that a datagram that was not lost is delivered twice (netem
      `duplicate`). The copy is the datagram as sent, uncorrupted, with its own delay; it is
      never held back by `reorder`. (netem decides loss once for both copies too.)
    - `corrupt`: the probability that one random bit of the datagram is flipped (netem
      `corrupt`). An empty datagram has no bit to flip.
    - `delay` and `jitter`: each datagram is delayed by `delay` plus a uniform offset in
      [-jitter, +jitter], never less than zero (netem `delay D J` without a correlation or a
      distribution table). Unlike netem, jitter alone never reorders: a datagram is never
      delivered before one sent earlier that is not held back (netem with a FIFO child qdisc).
      That keeps every delay within [delay - jitter, delay + jitter].
    - `reorder`: the probability that a datagram is held back by `gap` beyond its delay, so that
      those sent in the next `gap` overtake it. (netem's `reorder` does the opposite, sending a
      few datagrams at once ahead of the delayed rest; the effect on the order is the same kind.)
    - `gap`: how long a held-back datagram waits beyond its delay. When not given:
      max(delay + jitter, 10 ms) (`reorder_gap`).

    Probabilities are in 0..1, times in seconds up to MOST_TIME, burst 1 to MOST_BURST, all
    finite. An invalid one raises
    `ImpairmentError` (with no column: the spec's parser gives columns).
    """

    loss: float = 0.0
    burst: float | None = None
    delay: float = 0.0
    jitter: float = 0.0
    reorder: float = 0.0
    gap: float | None = None
    duplicate: float = 0.0
    corrupt: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None:
                reason = _check(f.name, value)
                if reason is not None:
                    raise ImpairmentError(reason)
                # One canonical float for each value: 5 and 5.0, -0.0 and 0.0 are the same.
                object.__setattr__(self, f.name, float(value) + 0.0)
        reason = _check_burst(self.loss, self.burst)
        if reason is not None:
            raise ImpairmentError(reason)

    @property
    def is_none(self) -> bool:
        """True when nothing at all happens to a datagram (`burst` and `gap` alone do nothing)."""
        return not (
            self.loss or self.delay or self.jitter or self.reorder or self.duplicate or self.corrupt
        )

    @property
    def reorder_gap(self) -> float:
        """How long a held-back datagram waits beyond its delay (`gap` or its default)."""
        if self.gap is not None:
            return self.gap
        return max(self.delay + self.jitter, DEFAULT_GAP)

    def __str__(self) -> str:
        items = []
        for key in KEYS:
            value = getattr(self, key)
            if value is None or (value == 0 and key != "gap"):
                continue
            if key in _PROBABILITIES:
                text = _format_scaled(value, 100.0, "%") or _number(value)
            elif key in _TIMES:
                text = _format_scaled(value, 1e3, "ms") or f"{_number(value)}s"
            else:
                text = _number(value)
            items.append(f"{key}={text}")
        return ",".join(items) or "none"


def parse_impairment(text: str) -> Impairment:
    """The `Impairment` a spec describes (module docstring); `ImpairmentError` if it is not one."""
    if not text.strip() or text.strip().lower() == "none":
        return Impairment()
    values: dict[str, float] = {}
    columns: dict[str, int] = {}
    offset = 0
    for item in text.split(","):
        start = offset
        offset += len(item) + 1
        stripped = item.strip()
        column = start + len(item) - len(item.lstrip()) + 1
        if not stripped:
            raise ImpairmentError("empty item: expected KEY=VALUE between commas", column)
        key, equals, value = stripped.partition("=")
        if not equals:
            if stripped.lower() == "none":
                raise ImpairmentError("none stands alone: it cannot go with other items", column)
            raise ImpairmentError(f"expected KEY=VALUE, got {stripped!r}", column)
        key = key.rstrip().lower()
        if key not in KEYS:
            raise ImpairmentError(
                f"unknown key {key!r}: the keys are {', '.join(KEYS)}" if key else "missing key",
                column,
            )
        if key in values:
            raise ImpairmentError(f"{key} given twice (first at column {columns[key]})", column)
        value_column = column + len(stripped) - len(value.lstrip())
        value = value.strip()
        parsed = _parse_value(key, value, value_column)
        values[key] = parsed
        columns[key] = value_column
    reason = _check_burst(values.get("loss", 0.0), values.get("burst"))
    if reason is not None:
        raise ImpairmentError(reason, columns["burst"])
    return Impairment(**values)


def _parse_value(key: str, text: str, column: int) -> float:
    match = _NUMBER.fullmatch(text)
    if match is None:
        example = "3" if key == "burst" else "5%" if key in _PROBABILITIES else "40ms"
        what = "empty value" if not text else f"bad number {text!r}"
        raise ImpairmentError(f"{what} for {key} (expected e.g. {key}={example})", column)
    sign, digits, suffix = match.groups()
    suffix = suffix.strip().lower()
    number = float(digits)
    if not math.isfinite(number):
        raise ImpairmentError(f"{key}={text} is too large", column)
    if key in _TIMES:
        if not suffix and number != 0:
            raise ImpairmentError(f"{key}={text} needs a unit: ms, s or us", column)
        if suffix and suffix not in _TIME_UNITS:
            raise ImpairmentError(f"unknown unit {suffix!r} for {key}: use ms, s or us", column)
        if sign == "-" and number != 0:
            raise ImpairmentError(f"{key}={text} is a negative time", column)
        seconds = number / _TIME_UNITS[suffix] if suffix else 0.0
        if seconds > MOST_TIME:
            raise ImpairmentError(f"{key}={text} is {_too_long(key)}", column)
        return seconds
    if key in _PROBABILITIES:
        if suffix not in ("", "%"):
            raise ImpairmentError(
                f"bad probability {text!r} for {key}: a percentage (5%) or a fraction (0.05)",
                column,
            )
        value = number / 100.0 if suffix else number
        if sign == "-" and value != 0:
            value = -value
        if not 0.0 <= value <= 1.0:
            hint = f" (did you mean {key}={text}%?)" if not suffix and 1 < value <= 100 else ""
            raise ImpairmentError(f"{key}={text} is not a probability in 0..1{hint}", column)
        return value
    # burst
    if suffix:
        raise ImpairmentError(f"burst={text}: a number of datagrams, without a unit", column)
    value = -number if sign == "-" else number
    reason = _check("burst", value)
    if reason is not None:
        raise ImpairmentError(reason, column)
    return value


def _check(key: str, value: float) -> str | None:
    """Why `value` is not one of `key`'s, or None when it is."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return f"{key} must be a number, not {type(value).__name__}"
    if not math.isfinite(value):
        return f"{key} must be finite, not {value}"
    if key in _PROBABILITIES and not 0.0 <= value <= 1.0:
        return f"{key}={value} is not a probability in 0..1"
    if key in _TIMES and value < 0:
        return f"{key}={value}s is a negative time"
    if key in _TIMES and value > MOST_TIME:
        return f"{key}={_number(value)}s is {_too_long(key)}"
    if key == "burst" and not 1 <= value <= MOST_BURST:
        return (
            f"burst={_number(value)} is not a mean burst length: it is at least 1 datagram and"
            f" at most {MOST_BURST:,.0f}"
        )
    return None


def _too_long(key: str) -> str:
    return f"longer than {key} may be: a delay, jitter or gap is 0 to {MOST_TIME:g} s"


def _check_burst(loss: float, burst: float | None) -> str | None:
    """Why a Gilbert model cannot have this loss rate and mean burst, or None when it can."""
    if burst is None or loss >= 1.0 or loss <= burst / (1.0 + burst):
        return None
    needed = loss / (1 - loss)
    beyond = f", more than burst may be ({MOST_BURST:,.0f})" if needed > MOST_BURST else ""
    return (
        f"loss={loss * 100:.6g}% with burst={_number(burst)} is impossible: a mean burst of "
        f"{_number(burst)} allows at most {burst / (1 + burst) * 100:.4g}% loss, and "
        f"loss={loss * 100:.6g}% needs burst={needed:.4g} or more{beyond}"
    )


def _number(value: float) -> str:
    """`value` as the shortest text that reads back as the same float."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _format_scaled(value: float, scale: float, unit: str) -> str | None:
    """`value * scale` with `unit`, if that reads back (text / scale) as exactly `value`."""
    scaled = value * scale
    if not math.isfinite(scaled):
        return None
    text = _number(scaled)
    return f"{text}{unit}" if float(text) / scale == value else None
