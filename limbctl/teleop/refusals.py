"""Why command lines were refused: counts by reason, the first examples, the latest ones."""

from __future__ import annotations

import re
import threading
from dataclasses import dataclass, field

#: Examples kept per reason: enough to recognise the pattern, few enough for one summary line.
EXAMPLES_PER_REASON = 3
#: Characters of a refused line kept as an example (a line may be up to 1 KiB of garbage).
EXAMPLE_CHARS = 60
#: Refusals kept for the next telemetry row: a flood between two cycles is counted, not listed.
MAX_RECENT = 100

#: A number standing alone (not the 8 of "UTF-8" or the 2 of "q2").
_NUMBER = re.compile(r"(?<![\w.+-])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")


def reason_of(message: str) -> str:
    """The reason a parser message stands for: its head, numbers replaced by ``N``."""
    head = message.split(": ", 1)[0].split(", got ", 1)[0]
    return _NUMBER.sub("N", head).strip()


@dataclass(frozen=True)
class Example:
    """One refused line: its number in the stream (from 1), an excerpt, the full message."""

    line_no: int
    text: str
    message: str


@dataclass
class Refusals:
    """Thread-safe account of refused lines (written by a reader thread, read by the loop)."""

    total: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    examples: dict[str, list[Example]] = field(default_factory=dict)
    _recent: list[str] = field(default_factory=list, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def add(self, message: str, line: bytes | str = b"", line_no: int = 0) -> str:
        """Count one refused line; returns its reason."""
        reason = reason_of(message)
        if isinstance(line, bytes):
            line = line.decode("utf-8", "backslashreplace")
        text = line.strip()
        if len(text) > EXAMPLE_CHARS:
            text = text[: EXAMPLE_CHARS - 3] + "..."
        with self._lock:
            self.total += 1
            self.counts[reason] = self.counts.get(reason, 0) + 1
            kept = self.examples.setdefault(reason, [])
            if len(kept) < EXAMPLES_PER_REASON:
                kept.append(Example(line_no, text, message))
            if len(self._recent) < MAX_RECENT:
                self._recent.append(reason)
        return reason

    def take_recent(self) -> list[str]:
        """The reasons refused since the previous call, oldest first (at most MAX_RECENT)."""
        with self._lock:
            recent, self._recent = self._recent, []
        return recent

    def lines(self) -> list[str]:
        """One line per reason, most frequent first: count, reason, first examples."""
        with self._lock:
            counts = sorted(self.counts.items(), key=lambda item: (-item[1], item[0]))
            examples = {reason: list(kept) for reason, kept in self.examples.items()}
        out = []
        for reason, count in counts:
            shown = ", ".join(
                (f"line {e.line_no}: " if e.line_no else "") + repr(e.text)
                for e in examples[reason]
            )
            out.append(f"refused {count:>6} x {reason} (e.g. {shown})")
        return out
