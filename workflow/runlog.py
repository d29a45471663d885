"""The run log: what stages report through, on screen and in ``run.log``.

:class:`RunLog` writes time-stamped lines to the run's log file and, unless
quiet, to the terminal, where :meth:`RunLog.progress` draws a bar with an ETA
(one line per ~10 % elsewhere, CI logs and files); :func:`heartbeat` says a
silent stage (a library call: gmsh, dolfinx, an eigen-solve) is still alive;
:func:`library_logging` sends the libraries' own ``logging`` records (the form
compiler's gcc lines, ``warnings.warn``) to ``run.log`` instead of the terminal.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import logging
import sys
import time
import warnings
from pathlib import Path
from typing import Iterable, Iterator

from workflow.io import write_error

__all__ = ["HEARTBEAT", "RunLog", "heartbeat", "library_logging"]


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
                raise write_error(file, exc) from exc

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
            self.say(msg)

    def note(self, msg: str) -> None:
        """``msg`` in ``run.log`` only: a detail the terminal does not need (a stage starting,
        each file written), so that a run's terminal stays a screen long."""
        self._file(msg)

    def say(self, msg: str) -> None:
        """``msg`` on the terminal only, quiet or not (the file has it already)."""
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
        if total == 1:
            # one item says nothing a bar could add (its own result line follows): run.log only
            yield from iterable
            self._file(f"{label}: done, 1 item in {time.monotonic() - t0:.1f} s")
            return
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


# ---------------------------------------------------------------- libraries' logging

#: Library records at this level and above reach ``run.log`` (DEBUG would be
#: matplotlib's font search and PIL's PNG chunks: thousands of lines).
LIBRARY_LEVEL = logging.INFO
#: At most this many distinct library warnings are repeated on the terminal per run.
ECHO_MAX = 5


def _console(handler: logging.Handler) -> bool:
    """Whether ``handler`` writes to the terminal (stdout or stderr, whatever object holds them),
    or to a closed stream."""
    if not isinstance(handler, logging.StreamHandler) or isinstance(handler, logging.FileHandler):
        return False
    stream = getattr(handler, "stream", None)
    if stream is None:
        return False
    if getattr(stream, "closed", False):
        return True  # writing there would only print "--- Logging error ---" on stderr
    if any(stream is s for s in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__)):
        return True
    try:
        return stream.fileno() in (1, 2)
    except Exception:  # noqa: BLE001 - StringIO, closed files, pytest's capture buffers
        return False


class _RunLogHandler(logging.Handler):
    """A library's ``logging`` record → a time-stamped line in the run's log file.

    WARNING and above are also said once on the terminal, as ``warning: <logger>: <first
    line>`` (at most :data:`ECHO_MAX` of them, then one line pointing at ``run.log``);
    under ``quiet`` only ERROR and above, and nothing at all when ``echo`` is false
    (the MPI ranks other than 0).
    """

    def __init__(self, log: RunLog, echo: bool):
        super().__init__(LIBRARY_LEVEL)
        self.log = log
        self.echo = echo
        self.said: set[tuple[str, str]] = set()
        self.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s",
                                            datefmt="%Y-%m-%dT%H:%M:%S"))

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record)
        except Exception:  # noqa: BLE001 - a library's malformed message (bad % args)
            text = f"{record.levelname} {record.name}: {record.msg!r} {record.args!r}"
        fh = self.log._fh
        if fh is not None:
            try:
                fh.write(text + "\n")
            except (OSError, ValueError):
                pass  # a full disk (or a closed file) must not hide the stage's own error
        if self.echo and record.levelno >= (logging.ERROR if self.log.quiet else logging.WARNING):
            try:
                self._say(record)
            except (OSError, ValueError):
                pass  # a closed terminal: the library's logging call must not fail

    def _say(self, record: logging.LogRecord) -> None:
        try:
            lines = record.getMessage().strip().splitlines() or [""]
        except Exception:  # noqa: BLE001
            lines = [str(record.msg)]
        key = (record.name, lines[0])
        if key in self.said:
            return
        self.said.add(key)
        kind = "error" if record.levelno >= logging.ERROR else "warning"
        if len(self.said) <= ECHO_MAX:
            more = " (more in run.log)" if len(lines) > 1 or record.exc_info else ""
            self.log.say(f"{kind}: {record.name}: {lines[0]}{more}")
        elif len(self.said) == ECHO_MAX + 1:
            self.log.say("warning: more library warnings: see run.log")


#: The handlers of the runs in progress in this process (innermost last).
_ACTIVE: list[_RunLogHandler] = []


def _call_handlers(self: logging.Logger, record: logging.LogRecord) -> None:
    """``Logger.callHandlers`` during a run: every handler but those writing to the terminal.

    Libraries add terminal handlers of their own, often while the run goes on
    (importing ffcx calls ``logging.basicConfig()``; importing UFL gives its
    logger a stdout handler), so they are skipped when a record is handled,
    not removed beforehand. A record that does not reach the root logger (a
    logger with ``propagate = False``) goes to the run's log too; nothing
    falls back on :data:`logging.lastResort` (stderr).
    """
    c, at_root = self, False
    while c:
        for handler in c.handlers:
            if record.levelno >= handler.level and not _console(handler):
                handler.handle(record)
        at_root = c.parent is None
        c = c.parent if c.propagate else None
    if not at_root and _ACTIVE and record.levelno >= _ACTIVE[-1].level:
        _ACTIVE[-1].handle(record)


def _warning_to_log(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` during a run: the warning as a WARNING of logger ``py.warnings``."""
    text = warnings.formatwarning(message, category, filename, lineno, line)
    logging.getLogger("py.warnings").warning("%s", text)


@contextlib.contextmanager
def library_logging(log: RunLog, echo: bool = True) -> Iterator[None]:
    """During the block, Python ``logging`` writes into ``log``'s file, never on the terminal.

    Every library (ffcx, UFL, dolfinx, setuptools' gcc lines, cffi, numba,
    matplotlib, pyvista …) logs through :mod:`logging`; ``warnings.warn`` is
    routed there too (logger ``py.warnings``). Records of level
    :data:`LIBRARY_LEVEL` and above go to the log file, time-stamped with
    their logger's name and level (when ``log`` has no file, as on the MPI
    ranks other than 0, they go nowhere); handlers that write to the
    terminal are skipped, whoever added them and when; warnings are said
    once on the terminal (see :class:`_RunLogHandler`).

    Afterwards the logging configuration is as it was before: the root
    logger's level and handlers, ``Logger.callHandlers``, whether warnings
    are captured (in-process callers such as the tests run many
    scenes in one interpreter). Handlers a library added during the block
    stay: they are that library's configuration.
    """
    root = logging.getLogger()
    handler = _RunLogHandler(log, echo)
    old_level = root.level
    old_call = logging.Logger.__dict__["callHandlers"]
    old_showwarning = warnings.showwarning
    _ACTIVE.append(handler)
    logging.Logger.callHandlers = _call_handlers
    # Also stops the libraries' logging.basicConfig() adding a stderr handler to the root.
    root.addHandler(handler)
    if old_level == logging.NOTSET or old_level > LIBRARY_LEVEL:
        root.setLevel(LIBRARY_LEVEL)
    # Not logging.captureWarnings: it is a no-op when an import already turned it on, and
    # a test runner's warnings recorder then keeps showwarning to itself.
    warnings.showwarning = _warning_to_log
    try:
        yield
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)  # setuptools changes it at each compile (distutils' set_threshold)
        if handler in _ACTIVE:
            _ACTIVE.remove(handler)
        logging.Logger.callHandlers = old_call
        warnings.showwarning = old_showwarning
        handler.close()
