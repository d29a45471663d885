"""``bladewear``: run a scene, list the shipped scenes, show a resolved scene.

    bladewear run SCENE [--out DIR] [--set section.key=value ...] [--fresh] [--quiet] [--cache DIR]
    bladewear scenes
    bladewear show SCENE [--set ...] [--out DIR] [--cache DIR]

SCENE is a path or the name of a shipped scene (``bladewear run quick``).

Exit status (also in ``bladewear --help`` and the README):

* 0 — finished, every result converged;
* 2 — error: bad scene, bundle, option or output folder, or a solve that
  cannot give any result; one line ``error: …`` on stderr naming the key or
  file, nothing of the previous run folder changed;
* 3 — finished, with unconverged results: every file is written, and
  ``summary.json["unconverged"]`` (also the log and the report) says which
  results did not converge and why;
* 130 — interrupted (Ctrl-C, SIGTERM): completed stages stay cached, and so
  do the finished pieces of the stage it stopped in (a Monte Carlo's patterns,
  a contact-convergence study's meshes; :mod:`workflow.progress`).

Other exceptions are bugs and keep their traceback (exit 1). Ctrl-C or
SIGTERM stop the run between two writes: cache entries and the run folder's
summary are written whole or not at all.

Under MPI (``mpirun -n 2 bladewear run SCENE``) every rank runs this; only
rank 0 prints (its log, the summary path, the error line), and every rank
exits with the same status (see :mod:`workflow.mpi`).
"""
from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from pathlib import Path

from workflow.errors import BladewearError

EXIT_ERROR = 2
EXIT_UNCONVERGED = 3
EXIT_INTERRUPTED = 130

EPILOG = """exit status:
  0    finished, every result converged (a check above its tolerance, or one that could not
       run, is a warning: printed, and listed in summary.json "warnings")
  2    error (bad scene key, bundle file, option or output folder; one line 'error: ...')
  3    finished, with unconverged results (listed in summary.json "unconverged", the log and the report)
  130  interrupted (Ctrl-C / SIGTERM); completed stages stay cached (and a long stage's finished pieces)
"""


class _Parser(argparse.ArgumentParser):
    """argparse with the CLI's error format: one line ``error: …`` and status 2."""

    def error(self, message):
        print(f"error: {self.prog}: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(EXIT_ERROR)


def _parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="bladewear", description="Friction-damped vibration and fretting wear of a "
                                 "turbine-blade dovetail (Salles et al. 2012).", epilog=EPILOG,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, metavar="{run,scenes,show}", parser_class=_Parser)

    def common(p):
        p.add_argument("scene", help="scene file, or the name of a shipped scene (see `bladewear scenes`)")
        p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                       help="override a scene key; VALUE is parsed as TOML (repeatable)")
        p.add_argument("--out", type=Path, default=None,
                       help="run folder (default: results/<scene name>)")
        p.add_argument("--cache", type=Path, default=None,
                       help="cache folder (default: $BLADEWEAR_CACHE, else .cache beside the run folder)")

    r = sub.add_parser("run", help="run the stages a scene's outputs need", epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    common(r)
    r.add_argument("--fresh", action="store_true", help="ignore the cache: recompute every stage")
    r.add_argument("--quiet", action="store_true", help="no progress on the terminal (run.log still written)")
    sub.add_parser("scenes", help="list the shipped scenes")
    s = sub.add_parser("show", help="print the resolved scene (defaults filled) and the stages it runs")
    common(s)
    return ap


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bladewear`` console script; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        with _sigterm_as_interrupt(), _sigint_watch(), _mpi_exit():
            return {"run": cmd_run, "scenes": cmd_scenes, "show": cmd_show}[args.command](args)
    except BladewearError as exc:
        if _rank() == 0:
            print(f"error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        if _rank() == 0:
            print(f"error: {INTERRUPTED}", file=sys.stderr)
        return EXIT_INTERRUPTED


#: Seconds Ctrl-C waits for the main thread to stop by itself before the process ends at once.
INTERRUPT_GRACE = 5.0
INTERRUPTED = ("interrupted; completed stages stay cached (and a long stage's finished pieces), "
               "the next run resumes from them")


@contextlib.contextmanager
def _sigint_watch():
    """Ctrl-C, whatever a library has done to SIGINT's handler.

    Importing gmsh sets SIGINT to SIG_DFL (so that Ctrl-C can stop its C
    code) until ``gmsh.finalize``: Ctrl-C in the geometry or remap stage
    killed the process with no message. Here SIGINT is blocked in the main
    thread and a watcher thread waits for it: it raises KeyboardInterrupt
    in the main thread (through SIGUSR1's Python handler, which no library
    touches); if the main thread is stuck inside a library call and does
    not stop within INTERRUPT_GRACE seconds, the watcher prints the same
    line and ends the process with status 130 (every write is atomic, so
    nothing is half-written; the next run removes the temporaries). Serial
    runs in the main thread only: under MPI the launcher owns the signals.

    Threads started before the block (OpenBLAS's pool, at NumPy's import)
    still take SIGINT; :func:`_sigint_noted` makes that harmless and tells
    the watcher.
    """
    import threading

    from workflow.mpi import launched

    if threading.current_thread() is not threading.main_thread() or launched():
        yield
        return
    import _thread
    import os

    def raise_interrupt(signum, frame):
        raise KeyboardInterrupt

    old_usr1 = signal.signal(signal.SIGUSR1, raise_interrupt)
    noted = _sigint_noted()
    woken = next(noted)
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    stop = threading.Event()
    guard = threading.Lock()       # the watcher leaves only under it: see the finally below
    done = []

    def watch():
        while True:
            got = signal.sigtimedwait({signal.SIGINT}, 0.2) or (woken() or None)
            with guard:
                if stop.is_set() or got is not None:
                    done.append(True)
                    if stop.is_set():
                        return
            if got is not None:
                break
        _thread.interrupt_main(signal.SIGUSR1)
        if not stop.wait(INTERRUPT_GRACE):
            print(f"error: {INTERRUPTED} (stopped inside a library call)", file=sys.stderr, flush=True)
            os._exit(EXIT_INTERRUPTED)

    watcher = threading.Thread(target=watch, name="bladewear-sigint", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        with guard:
            stop.set()
            if not done:
                # wake the watcher now, not at its next 0.2 s poll (0.2 s per CLI call, 0.6 s per
                # bad-input test); it is alive here: it cannot leave without taking the guard
                signal.pthread_kill(watcher.ident, signal.SIGINT)
        watcher.join()
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
        noted.close()
        signal.signal(signal.SIGUSR1, old_usr1)


def _sigint_noted():
    """SIGINT made harmless in any thread, and told: a generator whose first ``next`` installs
    it and yields ``woken()`` (True once a SIGINT arrived since the last call), and whose
    ``close`` restores what it replaced.

    Threads started before SIGINT is blocked (OpenBLAS's pool, at NumPy's import) still take
    it, and under the SIG_DFL that importing gmsh leaves it ended the process (measured
    2026-11-29: Ctrl-C while gmsh meshed, OpenBLAS threads on, status −2 and no message). So
    gmsh is imported first, and SIGINT's disposition is then a handler that does nothing but
    write its byte to the wakeup pipe (``signal.set_wakeup_fd``), which ``woken`` reads."""
    import os

    def noted(signum, frame):       # the wakeup byte is the message; the watcher acts on it
        pass

    old_int = signal.signal(signal.SIGINT, noted)
    try:
        import gmsh  # noqa: F401 (its import sets SIG_DFL once, and finalize restores `noted`)
    except (ImportError, OSError):  # no gmsh, or its library does not load: the stages that need it say so
        pass
    signal.signal(signal.SIGINT, noted)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_r, False)
    os.set_blocking(wake_w, False)
    old_wake = signal.set_wakeup_fd(wake_w, warn_on_full_buffer=False)

    def woken() -> bool:
        try:
            return signal.SIGINT in os.read(wake_r, 512)
        except BlockingIOError:
            return False

    try:
        yield woken
    finally:
        signal.set_wakeup_fd(old_wake)
        os.close(wake_r)
        os.close(wake_w)
        signal.signal(signal.SIGINT, old_int)


@contextlib.contextmanager
def _mpi_exit():
    """Under MPI: end PETSc on every rank together before exit (else a hang; :func:`workflow.mpi.finish`)."""
    try:
        yield
    finally:
        from workflow.mpi import finish, world

        if world() is not None:
            finish()


def _rank() -> int:
    from workflow.mpi import rank

    return rank()


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """Turn SIGTERM (``kill``) into KeyboardInterrupt so temporaries are cleaned up."""
    def handler(signum, frame):
        raise KeyboardInterrupt
    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (e.g. called from a test runner thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _default_out(args, scene) -> Path:
    if args.out is not None:
        return args.out
    stem = scene.path.stem if scene.path else "scene"
    return Path("results") / stem


def cmd_run(args) -> int:
    from workflow.pipeline import run_scene
    from workflow.scene import load_scene

    scene = load_scene(args.scene, args.overrides)
    out = _default_out(args, scene)
    # Libraries' logging (the form compiler's gcc lines) goes to run.log, not here, quiet or
    # not (workflow.runlog.library_logging, installed by run_scene).
    summary = run_scene(scene, out, cache=args.cache, fresh=args.fresh, quiet=args.quiet)
    if not summary:
        return EXIT_ERROR
    bad = summary.get("unconverged") or {}
    if not args.quiet and _rank() == 0:
        print(f"{out / 'summary.json'}")
    checks = summary.get("warnings") or {}
    if checks and _rank() == 0:
        for name, lines in checks.items():
            for line in lines:
                print(f"warning: {name}: {line}", file=sys.stderr)
    if bad:
        if _rank() == 0:
            n = sum(len(v) for v in bad.values())
            print(f"warning: finished with {n} unconverged result(s) in {', '.join(bad)} "
                  f"(summary.json \"unconverged\"); exit status {EXIT_UNCONVERGED}", file=sys.stderr)
        return EXIT_UNCONVERGED
    return 0


def cmd_scenes(args) -> int:
    from workflow.scene import SHIPPED, shipped_scenes

    rows = shipped_scenes()
    width = max((len(n) for n, _ in rows), default=0)
    for name, title in rows:
        print(f"{name.ljust(width)}  {title}")
    if not rows:
        print(f"(no scenes in {SHIPPED})")
    return 0


def cmd_show(args) -> int:
    from workflow import progress
    from workflow.pipeline import check_entry, default_cache, plan, progress_folder
    from workflow.scene import format_scene, load_scene

    scene = load_scene(args.scene, args.overrides)
    p = plan(scene)  # first: it marks the sections a model bundle replaces
    print(format_scene(scene))
    out = _default_out(args, scene)
    cache = args.cache.resolve() if args.cache else default_cache(out)
    print(f"\n# stages for outputs {scene['run'].outputs} (cache {cache}):")
    if "bundle" in p.external:
        from reduction.bundle import read_bundle

        b = read_bundle(p.external["bundle"])       # a missing or damaged file: the error run would stop on
        print(f"#   model bundle: {p.external['bundle']} ({b.n_dofs} DOFs, {b.contact.n_pairs} contact pairs; "
              "replaces geometry + assembly)")
    for name in p.stages:
        module = p.modules[name]
        got, damage = check_entry(cache / name / p.keys[name]) if getattr(module, "CACHE", True) else (None, None)
        state = "cached" if got is not None else "damaged" if damage else "to compute"
        reads = f"; reads [{'], ['.join(module.SECTIONS)}]" if module.SECTIONS else ""
        kept = progress.kept(progress_folder(cache / name / p.keys[name])) if got is None else 0
        print(f"#   {name:<16} {state:<11} needs {', '.join(module.NEEDS) or '-'}{reads}"
              + (f" (cache entry damaged: {damage}; will recompute)" if damage else "")
              + (f" ({kept} finished piece{'s' if kept > 1 else ''} kept from an interrupted run)" if kept else ""))
    if "reduction" in p.stages and ("hb" in p.stages or "wear" in p.stages):
        entry = cache / "reduction" / p.keys["reduction"]
        got, _ = check_entry(entry)
        print("\n" + _penalty_line(scene, None if got is None else entry / "reduced.npz"))
    return 0


def _penalty_line(scene, reduced) -> str:
    """The DLFT penalties this scene will use: the values when the reduced model is
    cached, else the rule (they need the reduced model's static stiffness)."""
    ct = scene["contact"]
    if ct.eps_n > 0 and ct.eps_t > 0:
        return f"# DLFT penalties: given, ε_N = {ct.eps_n:g}, ε_T = {ct.eps_t:g} N/m"
    rule = (f"{ct.penalty_factor:g} × each pair's static condensed stiffness (contact.penalty_factor)"
            if ct.penalty_factor > 0 else "the stiffness each pair shows the unresolved harmonics, within "
            "1…1000 × its static condensed stiffness (workflow/engine/penalty.py)")
    from workflow.errors import BladewearError

    if reduced is None or not Path(reduced).is_file():
        return f"# DLFT penalties: automatic, {rule}; values once the reduced model exists"
    from workflow.engine.model import ReducedModel
    from workflow.engine import contact_law

    try:
        model = ReducedModel.load(reduced)
    except BladewearError as exc:
        return f"# DLFT penalties: automatic, {rule} (the cached reduced model cannot be read: {exc})"
    law = contact_law(model, mu=model.friction(ct.mu)[0], eps_n=ct.eps_n, eps_t=ct.eps_t,
                      factor=ct.penalty_factor)
    return (f"# DLFT penalties: automatic, {rule}: ε_N {law.eps_n.min():.3g}…{law.eps_n.max():.3g}, "
            f"ε_T {law.eps_t.min():.3g}…{law.eps_t.max():.3g} N/m over {model.n_pairs} pairs")


if __name__ == "__main__":
    sys.exit(main())
