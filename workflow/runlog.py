"""The run log: what stages report through, on screen and in ``run.log``.

:class:`RunLog` writes time-stamped lines to the run's log file and, unless
quiet, to the terminal, where :meth:`RunLog.progress` draws a bar with an ETA
(one line per ~10 % elsewhere, CI logs and files); :func:`heartbeat` says a
silent stage (a library call: gmsh, dolfinx, an eigen-solve) is still alive.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import sys
import time
from pathlib import Path
from typing import Iterable, Iterator

from workflow.errors import OutputError

__all__ = ["HEARTBEAT", "RunLog", "heartbeat"]


class RunLog:
    """What stages report through: ``.info(msg)``, ``.warning(msg)``, ``.progress(it)``.

    Lines go to ``run.log`` (always, time-stamped) and to ``stream`` unless
    quiet. On a terminal ``progress`` draws a bar with an ETA; elsewhere
    (CI logs, files) it writes one line per ~10 %.
    """

    def __init__(self, file: Path | None = None, quiet: bool = False, stream=None, prefix: str = "",
                 _fh=None):
        self.quiet = quiet
        self.stream = sys.stderr if stream is None else stream
        self.prefix = prefix
        self._fh = _fh
        if _fh is None and file is not None:
            try:
                self._fh = open(file, "w", encoding="utf-8", buffering=1)
            except OSError as exc:
                raise OutputError(f"cannot write {file}: {exc.strerror or exc}") from exc

    def child(self, prefix: str) -> "RunLog":
        """The same log with ``[prefix]`` on every line (one per stage)."""
        return RunLog(quiet=self.quiet, stream=self.stream, prefix=prefix, _fh=self._fh)

    @property
    def tty(self) -> bool:
        return not self.quiet and hasattr(self.stream, "isatty") and self.stream.isatty()

    def _tag(self, msg: str) -> str:
        return f"[{self.prefix}] {msg}" if self.prefix else msg

    def _file(self, msg: str) -> None:
        if self._fh is not None:
            stamp = _dt.datetime.now().isoformat(timespec="seconds")
            try:
                self._fh.write(f"{stamp} {self._tag(msg)}\n")
            except OSError:
                pass  # a full disk must not hide the stage's own error

    def info(self, msg: str) -> None:
        self._file(msg)
        if not self.quiet:
            print(self._tag(msg), file=self.stream, flush=True)

    def warning(self, msg: str) -> None:
        self.info(f"warning: {msg}")

    def progress(self, iterable: Iterable, total: int | None = None, label: str = "",
                 weights: Iterable[float] | None = None) -> Iterator:
        """Yield from ``iterable``, reporting progress (and an ETA when ``total`` is known).

        ``weights``: the expected cost of each item (any unit); the percentage
        and the ETA then count work, not items — items of very different cost
        in increasing order (HB variants by Nh) made a count-based ETA far too
        short (said 0:08 at 70 %, took 31 s).
        """
        if total is None:
            try:
                total = len(iterable)  # type: ignore[arg-type]
            except TypeError:
                total = None
        w = [float(x) for x in weights] if weights is not None else None
        if w is not None and (len(w) != total or min(w, default=1.0) < 0 or sum(w) <= 0):
            w = None  # a cost model that does not fit the items: fall back on counting them
        label = label or "progress"
        t0 = time.monotonic()
        last_draw, last_decile, n, done = 0.0, 0, 0, 0.0
        tty = self.tty
        for n, item in enumerate(iterable, 1):
            yield item
            now = time.monotonic()
            done = done + w[n - 1] if w is not None else n
            frac = min(done / sum(w), 1.0) if w is not None else (n / total if total else None)
            if tty and (now - last_draw > 0.2 or n == total):
                last_draw = now
                self.stream.write("\r" + self._tag(_bar(label, n, total, now - t0, frac=frac)) + "\033[K")
                self.stream.flush()
            if total:
                decile = int(10 * frac + 1e-9)
                if decile > last_decile:
                    last_decile = decile
                    self._line(_bar(label, n, total, now - t0, bar=False, frac=frac), tty)
            elif n & (n - 1) == 0:  # unknown length: 1, 2, 4, 8, … items
                self._line(_bar(label, n, None, now - t0, bar=False), tty)
        if tty:
            self.stream.write("\n")
            self.stream.flush()
        if not total or last_decile < 10:
            self._line(f"{label}: done, {n} items in {time.monotonic() - t0:.1f} s", tty)

    def _line(self, msg: str, tty: bool) -> None:
        # On a terminal the bar already shows it; the file always gets it.
        self._file(msg)
        if not self.quiet and not tty:
            print(self._tag(msg), file=self.stream, flush=True)

    def close(self) -> None:
        if self._fh is not None and self.prefix == "":
            with contextlib.suppress(OSError):
                self._fh.close()
            self._fh = None


def _bar(label: str, n: int, total: int | None, elapsed: float, bar: bool = True,
         frac: float | None = None) -> str:
    """One progress line; ``frac`` is the share of the work done (default: of the items)."""
    if not total:
        return f"{label}: {n} items, {elapsed:.1f} s"
    frac = min(n / total, 1.0) if frac is None else frac
    eta = elapsed / frac * (1 - frac) if frac > 0 else 0.0
    text = f"{label}: {n}/{total} ({100 * frac:3.0f} %), elapsed {_hms(elapsed)}, ETA {_hms(eta)}"
    if bar:
        width = 24
        full = int(round(width * frac))
        text = f"{label} [{'#' * full}{'.' * (width - full)}] {n}/{total} ETA {_hms(eta)}"
    return text


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


#: Seconds between two "still computing" lines of a stage that says nothing itself.
HEARTBEAT = 30.0


@contextlib.contextmanager
def heartbeat(log: RunLog, name: str, every: float | None = None) -> Iterator[None]:
    """Log ``<name>: still computing, m:ss elapsed`` every ``every`` seconds until the block ends.

    Stages built on library calls (gmsh meshing, dolfinx assembly, the
    eigen-solves) cannot report progress themselves; this says the run is alive.
    """
    import threading

    every = HEARTBEAT if every is None else every
    stop = threading.Event()
    t0 = time.monotonic()

    def beat():
        while not stop.wait(every):
            log.info(f"{name}: still computing, {_hms(time.monotonic() - t0)} elapsed")

    thread = threading.Thread(target=beat, name=f"heartbeat-{name}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
