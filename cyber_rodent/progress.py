"""Progress of long commands: a bar on a terminal, a plain line a minute in a log.

A tqdm bar redraws itself several times a second with carriage returns. On a terminal that is
one live line; written to a file or a pipe (a batch job's log, ``nohup``, CI) every redraw is
kept, some 18 KB a minute. So :func:`progress_bar` gives a tqdm bar only where stderr is a
terminal (or a notebook, which draws its own widget), and otherwise a :class:`LineProgress`
with the same calls that prints one self-contained line at most every :data:`LINE_INTERVAL`
seconds.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Mapping
from typing import Any, TextIO

#: Seconds between two lines of :class:`LineProgress`.
LINE_INTERVAL = 60.0


def _format_time(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class LineProgress:
    """The calls of a tqdm bar that the package uses, printed as plain lines.

    A line (``desc: n/total unit (p%), elapsed, ~left, postfix``) is printed when an update
    or refresh comes at least ``interval`` seconds after the previous line (or the start);
    nothing is printed at the start or at :meth:`close`, so a command shorter than the
    interval prints no progress at all.

    Args:
        total: the count at completion.
        desc: what is progressing.
        unit: the unit of the count.
        initial: the count already done (a resumed run).
        file: where lines go (default: ``sys.stderr`` at each line).
        interval: seconds between lines.
        **options: tqdm's other options, ignored (``dynamic_ncols``, ...).
    """

    def __init__(
        self,
        total: float | None = None,
        *,
        desc: str = "",
        unit: str = "it",
        initial: float = 0,
        file: TextIO | None = None,
        interval: float = LINE_INTERVAL,
        **options: Any,
    ) -> None:
        self.total = total
        self.desc = desc
        self.unit = unit
        self.n: float = initial
        self.file = file
        self.interval = interval
        self._initial = initial
        self._postfix = ""
        self._started = self._last = time.monotonic()
        self.closed = False

    def update(self, n: float = 1) -> None:
        """Add ``n`` to the count."""
        self.n += n
        self.refresh()

    def set_postfix(
        self, ordered_dict: Mapping[str, Any] | None = None, refresh: bool = True, **kwargs: Any
    ) -> None:
        """Show ``key=value`` pairs after the count (the latest numbers of the work)."""
        items = {**(ordered_dict or {}), **kwargs}
        self._postfix = ", ".join(f"{k}={v}" for k, v in items.items())
        if refresh:
            self.refresh()

    def refresh(self) -> None:
        """Print a line if the interval has passed since the previous one."""
        now = time.monotonic()
        if self.closed or now - self._last < self.interval:
            return
        self._last = now
        print(self.line(now - self._started), file=self.file or sys.stderr, flush=True)

    def line(self, elapsed: float) -> str:
        """The progress as one line, ``elapsed`` seconds after the start."""
        n = f"{self.n:g}" if isinstance(self.n, float) else str(self.n)
        parts = [f"{self.desc}: {n}" if self.desc else n]
        if self.total:
            parts[0] += f"/{self.total:g} {self.unit} ({100 * self.n / self.total:.0f}%)"
        else:
            parts[0] += f" {self.unit}"
        parts.append(f"{_format_time(elapsed)} elapsed")
        done = self.n - self._initial
        if self.total and done > 0 and self.n < self.total:
            left = elapsed * (self.total - self.n) / done
            parts.append(f"~{_format_time(left)} left")
        if self._postfix:
            parts.append(self._postfix)
        return ", ".join(parts)

    def close(self) -> None:
        """Stop printing."""
        self.closed = True


def _on_terminal() -> bool:
    """Is stderr a terminal, or a notebook's output (which draws tqdm's widget)?"""
    if "ipykernel" in sys.modules:
        return True
    try:
        return sys.stderr is not None and sys.stderr.isatty()
    except (AttributeError, ValueError):  # a replaced or closed stream
        return False


def progress_bar(
    total: float | None = None, *, desc: str = "", unit: str = "it", initial: float = 0,
    **options: Any,
) -> Any:  # fmt: skip
    """A tqdm bar (``tqdm.auto``) where stderr is a terminal, else a :class:`LineProgress`.

    Both take the same calls: ``update``, ``set_postfix``, ``refresh``, ``close`` and
    assigning ``n``.
    """
    if _on_terminal():
        from tqdm.auto import tqdm

        return tqdm(total=total, desc=desc, unit=unit, initial=initial, **options)
    return LineProgress(total, desc=desc, unit=unit, initial=initial, **options)


__all__ = ["LINE_INTERVAL", "LineProgress", "progress_bar"]
