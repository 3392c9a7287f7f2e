"""Progress reports that suit where they are read.

On a terminal, a tqdm bar. Anywhere else (standard error redirected to a log file, a
batch job, a pipe) a bar's carriage-return redraws are noise, so a few plain lines are
written instead: one each time another ``1 / lines`` of the work is done, e.g.::

    netsim run: 25% (75/300 sim s), 1.4 s elapsed
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, Any, Self, TextIO

if TYPE_CHECKING:
    from tqdm import tqdm


def progress_bar(
    total: float,
    desc: str,
    unit: str,
    enabled: bool = True,
    initial: float = 0,
    lines: int = 4,
    stream: TextIO | None = None,
    tty: bool | None = None,
    **tqdm_options: Any,
) -> tqdm | _Silent:
    """A progress reporter with tqdm's ``update``, ``set_postfix``, ``close``, ``n`` and
    ``total``, usable as a context manager. ``tty`` forces the choice (default: whether
    ``stream``, standard error by default, is a terminal)."""
    stream = sys.stderr if stream is None else stream
    if not enabled:
        return _Silent(total, initial)
    if tty is None:
        isatty = getattr(stream, "isatty", None)
        tty = bool(isatty and isatty())
    if tty:
        return _estimating_bar()(total=total, initial=initial, desc=desc, unit=unit, file=stream, **tqdm_options)
    return PlainLines(total, desc, unit, initial, lines, stream)


def _estimating_bar() -> type:
    """tqdm's bar, whose estimate of the time left waits for the first unit of work (a
    simulated second, a run) to be done and then counts from there: the first unit carries
    the start-up (compiling the loops, starting workers), which would make the rate of the
    rest look far slower than it is."""
    from tqdm.auto import tqdm

    class EstimatingBar(tqdm):
        _since: tuple[float, float] | None = None  # (work done, time) when the first unit was done

        @property
        def format_dict(self) -> dict:
            values = super().format_dict
            done, now = values["n"] - values["initial"], values["elapsed"]
            if self._since is None and done >= 1:
                self._since = (done, now)
            if self._since is None or done <= self._since[0] or now <= self._since[1]:
                values["rate"] = 0  # tqdm shows no rate and no time left ("?")
            else:
                values["rate"] = (done - self._since[0]) / (now - self._since[1])
            return values

    return EstimatingBar


class _Silent:
    def __init__(self, total: float, initial: float = 0) -> None:
        self.total, self.n = total, initial

    def update(self, n: float = 1) -> None:
        self.n += n

    def set_postfix(self, refresh: bool = True, **values: object) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PlainLines(_Silent):
    """Progress as a few whole lines, for log files: at most ``lines`` of them, each when
    the next ``1 / lines`` of the work is done."""

    def __init__(
        self, total: float, desc: str, unit: str, initial: float = 0, lines: int = 4, stream: TextIO | None = None
    ) -> None:
        super().__init__(total, initial)
        self.desc, self.unit, self.lines = desc, unit, max(1, int(lines))
        self.stream = sys.stderr if stream is None else stream
        self.start = time.perf_counter()
        self.postfix = ""
        self.reported = self._step()

    def _step(self) -> int:
        if not self.total or self.total <= 0:
            return self.lines
        return min(self.lines, int(self.lines * self.n / self.total + 1e-9))

    def set_postfix(self, refresh: bool = True, **values: object) -> None:
        self.postfix = ", ".join(f"{k} {v}" for k, v in values.items())

    def update(self, n: float = 1) -> None:
        self.n += n
        step = self._step()
        if step > self.reported:
            self.reported = step
            pct = 100 * self.n / self.total
            elapsed = time.perf_counter() - self.start
            extra = f", {self.postfix}" if self.postfix else ""
            print(
                f"{self.desc}: {pct:.0f}% ({self.n:g}/{self.total:g} {self.unit}){extra}, {elapsed:.1f} s elapsed",
                file=self.stream,
                flush=True,
            )
