"""The pipeline: run the stages a scene's outputs need, once, from a cache.

Plan
    ``[run] outputs`` lists products; each product has one producing stage
    (:mod:`workflow.stages`), whose ``NEEDS`` are products in turn. The plan
    is the closure of that relation in dependency order — and no other
    stage. ``[model] bundle`` supplies the ``bundle`` product from a folder,
    replacing geometry + assembly. The report stage, when asked for, runs
    last and sees every other product.

Cache
    A stage's cache key hashes its name, the resolved values of its
    ``SECTIONS``, the keys of its inputs and the code version (the source of
    the geometry/, reduction/ and workflow/ packages and of the stage module).
    An entry is a folder ``<cache>/<stage>/<key>/`` written whole with
    :func:`workflow.io.atomic_dir`: a run killed inside a stage leaves the
    previous entry or none, plus a ``.tmp`` folder that the next run removes.
    Each entry holds the stage's files and ``.stage.json`` (its summary and
    the size and SHA-256 of every file, :func:`workflow.io.manifest`). An
    entry is used only if every file still matches (:func:`check_entry`); a
    damaged one (truncated, edited, deleted file) is recomputed with a
    warning. Several runs may share a cache: each holds a shared lock, and
    two runs computing the same entry each write it whole (the last rename
    wins; both are the same result). While it computes, a stage may keep
    finished pieces of its work in ``<cache>/<stage>/<key>.progress/``
    (:mod:`workflow.progress`: a Monte Carlo's patterns, a contact-convergence
    study's meshes), which a run
    interrupted inside it leaves for the next; the folder is removed once
    the entry is written.

Unconverged results
    A stage's summary may hold ``"unconverged": [str, …]``, one line per
    result that did not converge (what and why). The run still finishes;
    ``summary.json`` gets ``"unconverged": {stage: [...]}`` (empty when all
    converged), the lines are logged as warnings and the CLI exits 3. Its
    ``"warnings"`` (converged results whose checks exceed their tolerance, or
    checks that could not run) go to ``summary.json`` ``"warnings"`` the same
    way and to the terminal; the exit status stays 0.

Run folder
    ``<out>/<stage>`` are relative symbolic links to the cache entries,
    ``<out>/report`` (uncached) a folder, ``<out>/summary.json`` and
    ``<out>/scene.json`` (the resolved scene): all written under temporary
    names once every stage has succeeded, then renamed in together
    (:func:`_switch`; a failed rename undoes the others, so the folder is
    the previous run whole or this one whole, never half of each). Then
    ``<out>/run.log`` (written as ``.run.log.tmp`` while the run goes on). A
    failed or interrupted run leaves the previous run folder byte for byte
    as it was; its log goes to ``<cache>/failed-run.log``. One run at a time
    per run folder (:func:`lock_out`).

Under MPI (``mpirun -n N bladewear run …``; :mod:`workflow.mpi`)
    Every rank plans (the plan is deterministic); rank 0 alone decides what is
    cached, holds the cache lock and writes every file (cache entries, run
    folder, summary, log) and broadcasts its decisions. A stage declaring
    ``MPI = True`` (assembly, reduction, modes) is collective: every rank runs
    it into the temporary entry folder that rank 0 opened, and only rank 0
    writes there. Any other stage runs on rank 0 while the others wait. A
    failure on any rank makes every rank raise the same error.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import hashlib
import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from types import ModuleType
from typing import Iterator

from workflow import mpi, progress
from workflow import stages as registry
from workflow.errors import OutputError, SceneError
from workflow.engine.files import current_umask, write_error
from workflow.io import atomic_dir, manifest, record_problem, seal_record, verify_manifest, write_json
from workflow.runlog import RunLog, heartbeat, library_logging
from workflow.scene import Scene

#: Entry file holding a stage's summary inside its output folder.
STAGE_FILE = ".stage.json"
#: Packages whose source is the code version of every cache key.
CODE_PACKAGES = ("geometry", "reduction", "workflow")


# ---------------------------------------------------------------- plan

@dataclass
class Plan:
    """The stages a scene needs, in the order they run, and their cache keys."""

    stages: list[str]
    modules: dict[str, ModuleType]
    external: dict[str, Path] = field(default_factory=dict)  # product → folder supplied by the scene
    keys: dict[str, str] = field(default_factory=dict)  # stage → cache key
    product_keys: dict[str, str] = field(default_factory=dict)  # product → key of its producer

    def producer_of(self, product: str) -> str | None:
        for name in self.stages:
            if product in self.modules[name].PRODUCES:
                return name
        return None


def plan(scene: Scene) -> Plan:
    """Closure of ``[run] outputs`` over NEEDS → producer, dependency order.

    Only the modules of the stages in the closure are imported.
    """
    outputs = list(scene["run"].outputs)
    if not outputs:
        raise SceneError("run.outputs is empty: nothing to compute")
    external: dict[str, Path] = {}
    bundle = scene["model"].bundle
    if bundle:
        external["bundle"] = Path(bundle)
    order: list[str] = []
    modules: dict[str, ModuleType] = {}
    visiting: list[str] = []

    def visit(product: str, wanted_by: str) -> None:
        if product in external:
            return
        name = registry.producer(product)
        if name in order:
            return
        if name in visiting:
            raise TypeError(f"stage cycle: {' → '.join(visiting + [name])}")
        visiting.append(name)
        module = modules[name] = registry.load(name)
        if product not in module.PRODUCES:
            raise TypeError(f"stage {name} is registered for {product!r} but PRODUCES {module.PRODUCES}")
        if not getattr(module, "NEEDS_ALL", False):
            for need in module.NEEDS:
                visit(need, name)
        visiting.pop()
        order.append(name)

    last = [p for p in outputs if _needs_all(p)]
    for product in [p for p in outputs if p not in last] + last:
        visit(product, "run.outputs")
    # A stage that sees every product (the report) must run after all others.
    order.sort(key=lambda n: bool(getattr(modules[n], "NEEDS_ALL", False)))
    p = Plan(order, modules, external)
    scene.unused = unused_sections(p)
    _assign_keys(scene, p)
    return p


#: Sections the assembly turns into the bundle; a user's bundle replaces them.
BUNDLE_SECTIONS = ("material", "rotation", "damping", "excitation")


def unused_sections(p: Plan) -> set[str]:
    """Sections that no stage of the plan reads, because ``[model] bundle`` replaces them.

    A stage lists a section in ``VIA_BUNDLE`` when it reads it only as part
    of the model (hb, wear: the excitation is in the reduced load); with an
    external bundle such a section is not read at all and leaves its key.
    """
    if "bundle" not in p.external:
        return set()
    read = {s for n in p.stages for s in p.modules[n].SECTIONS
            if s not in getattr(p.modules[n], "VIA_BUNDLE", ())}
    return {s for s in BUNDLE_SECTIONS if s not in read}


def _needs_all(product: str) -> bool:
    # Decided from the registry without importing: only the report sees all.
    return registry.PRODUCERS.get(product) == "report"


def _assign_keys(scene: Scene, p: Plan) -> None:
    for product, folder in p.external.items():
        p.product_keys[product] = "external-" + folder_digest(folder)
    for name in p.stages:
        module = p.modules[name]
        unknown = [s for s in module.SECTIONS if s not in scene]
        if unknown:
            raise TypeError(f"stage {name} reads unknown scene section(s) {unknown}")
        needs = sorted(p.product_keys) if getattr(module, "NEEDS_ALL", False) else sorted(module.NEEDS)
        read = [s for s in module.SECTIONS if s not in getattr(scene, "unused", ())]
        ident = {
            "stage": name,
            "sections": json.loads(scene.canonical(read)),
            "inputs": {need: p.product_keys[need] for need in needs},
            "code": code_version(),
            "module": _module_digest(module),
        }
        key = hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()[:24]
        p.keys[name] = key
        for product in module.PRODUCES:
            p.product_keys[product] = key


@lru_cache(maxsize=1)
def code_version() -> str:
    """Hash of every ``.py`` source of geometry/, reduction/ and workflow/."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for pkg in CODE_PACKAGES:
        for f in sorted((root / pkg).rglob("*.py")):
            if "__pycache__" in f.parts:
                continue
            h.update(str(f.relative_to(root)).encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _module_digest(module: ModuleType) -> str:
    # Stage modules outside the packages (plug-ins, test fakes) count too.
    path = getattr(module, "__file__", None)
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16] if path else ""


def folder_digest(folder: Path) -> str:
    """Content hash of every file under ``folder`` (names and bytes)."""
    h = hashlib.sha256()
    for f in sorted(p for p in Path(folder).rglob("*") if p.is_file()):
        h.update(str(f.relative_to(folder)).encode() + b"\0")
        with open(f, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()[:24]


# ---------------------------------------------------------------- cache

def default_cache(out: Path) -> Path:
    """``$BLADEWEAR_CACHE``, else ``.cache`` beside the run folder (``results/.cache``)."""
    env = os.environ.get("BLADEWEAR_CACHE")
    return Path(env) if env else Path(out).resolve().parent / ".cache"


@contextlib.contextmanager
def cache_lock(root: Path) -> Iterator[None]:
    """Hold a shared lock on the cache; clean stale temporaries when alone.

    A run killed hard (SIGKILL, power loss) leaves ``.*.tmp`` folders from
    :func:`atomic_dir`. Only a run that gets the lock *exclusively* (no other
    run is writing) removes them; the lock dies with its process, so a killed
    run never blocks the next one.
    """
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_error(root, exc, "cache folder") from exc
    try:
        fh = open(root / ".lock", "a+")
    except OSError as exc:
        raise write_error(root / ".lock", exc, "the cache's lock file") from exc
    try:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            clean_stale(root, depth=2)
        except BlockingIOError:
            pass
        fcntl.flock(fh, fcntl.LOCK_SH)
        yield
    finally:
        fh.close()


def clean_stale(folder: Path, depth: int = 1) -> list[Path]:
    """Remove ``.*.tmp`` and ``.*.old`` leftovers of atomic writes under ``folder``."""
    removed = []
    level = [Path(folder)]
    for _ in range(depth):
        nxt = []
        for d in level:
            try:
                children = list(d.iterdir())
            except OSError:
                continue
            for c in children:
                if c.name.startswith(".") and (c.name.endswith(".tmp") or c.name.endswith(".old")):
                    if c.is_dir() and not c.is_symlink():
                        shutil.rmtree(c, ignore_errors=True)
                    else:
                        with contextlib.suppress(OSError):
                            c.unlink()
                    removed.append(c)
                elif c.is_dir() and not c.is_symlink():
                    nxt.append(c)
        level = nxt
    return removed


def read_entry(entry: Path) -> dict | None:
    """The ``.stage.json`` of a complete, undamaged cache entry, or None."""
    return check_entry(entry)[0]


def check_entry(entry: Path) -> tuple[dict | None, str | None]:
    """``(record, None)`` for a usable entry; ``(None, why)`` for a damaged one;
    ``(None, None)`` when there is no entry.

    Usable: ``.stage.json`` parses, holds the digest of its own content it was written with
    (:func:`workflow.io.seal_record`), and every file it lists has the size and SHA-256
    recorded when the entry was written.
    """
    f = entry / STAGE_FILE
    try:
        text = f.read_text()
    except FileNotFoundError:
        return None, ("its record .stage.json is missing" if entry.is_dir() else None)
    except OSError as exc:
        if entry.parent.exists() and not entry.parent.is_dir():
            return None, None   # no entry: writing it names the file in the way
        return None, f"its record .stage.json cannot be read ({exc.strerror or exc})"
    try:
        got = json.loads(text)
    except ValueError:
        return None, "its record .stage.json is not valid JSON"
    if not isinstance(got, dict) or "files" not in got:
        return None, "it has no file checksums (written by an older version)"
    problem = record_problem(got) or verify_manifest(entry, got["files"])
    return (None, problem) if problem else (got, None)


# ---------------------------------------------------------------- run

def run_scene(scene: Scene, out: str | os.PathLike, *, cache: str | os.PathLike | None = None,
              fresh: bool = False, quiet: bool = False, stream=None) -> dict:
    """Run the stages ``scene`` needs; write ``out``; return the summary dict."""
    out = Path(out).resolve()
    cache_root = Path(cache).resolve() if cache else default_cache(out)
    if out == cache_root or cache_root in out.parents:
        # the run folder links each stage to its entry in the cache: one inside the other's
        # entries would link to itself (found only after every stage had run)
        raise OutputError(f"the run folder {out} is {'the' if out == cache_root else 'inside the'} cache folder "
                          f"{cache_root}: choose another --out or --cache")
    grp = mpi.group()
    if grp.parallel:
        grp.together(mpi.init_petsc)  # collective: never first inside a rank-0-only stage
    # Plan first: a scene that cannot run must not touch the run folder.
    p = grp.together(plan, scene)
    model = grp.on_root(_check_bundle, p.external["bundle"]) if "bundle" in p.external else None
    lock = grp.root_only(_prepare_out, out)
    # Only rank 0 logs (to the terminal and LIVE_LOG, which becomes run.log when the run
    # finishes); the other ranks' stages talk to no one.
    log = grp.root_only(RunLog, out / LIVE_LOG, quiet=quiet, stream=stream) or RunLog(quiet=True)
    if grp.parallel:
        log.info(f"MPI: {grp.size} ranks")
    done = False
    try:
        # The libraries' own logging (the form compiler's gcc lines, warnings) goes to the log
        # file only; warnings are said once on rank 0's terminal (workflow.runlog.library_logging).
        with library_logging(log, echo=grp.root):
            summary = _run(scene, p, out, cache_root, fresh, log, model, grp)
        done = True
        return summary
    finally:
        log.close()
        if grp.root:
            _keep_log(out, cache_root, done)
        if lock is not None:
            os.close(lock)


#: The running log (in the run folder); ``run.log`` once the run has finished.
LIVE_LOG = ".run.log.tmp"
#: Where the log of a run that failed or was interrupted goes (in the cache folder), so
#: that a failed run leaves the previous run folder as it was.
FAILED_LOG = "failed-run.log"


def _keep_log(out: Path, cache_root: Path, done: bool) -> None:
    live = out / LIVE_LOG
    if not live.exists():
        return
    try:
        if done:
            os.replace(live, out / "run.log")
        else:
            cache_root.mkdir(parents=True, exist_ok=True)
            shutil.move(str(live), str(cache_root / FAILED_LOG))
    except OSError:
        with contextlib.suppress(OSError):
            live.unlink()


def _prepare_out(out: Path) -> int:
    """Create or check the run folder and lock it for this run; returns the lock's descriptor."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        if not os.access(out, os.W_OK | os.X_OK):
            raise PermissionError(13, "Permission denied")
        # Our own leftovers (a first run killed hard leaves .run.log.tmp) do not make it foreign.
        ours = lambda c: c.name.startswith(".") and c.name.endswith((".tmp", ".old"))  # noqa: E731
        foreign = any(not ours(c) for c in out.iterdir()) and \
            not any((out / f).exists() for f in ("run.log", "summary.json"))
    except OSError as exc:
        raise write_error(out, exc, "output folder") from exc
    if foreign:
        # The run replaces <out>/<stage> entries: never do that in someone else's folder.
        raise OutputError(f"output folder {out} is not empty and is not a bladewear run folder "
                          f"(no run.log or summary.json); choose another --out")
    lock = lock_out(out)
    clean_stale(out)  # only once the lock is ours: another run's temporaries are not stale
    return lock


def lock_out(out: Path) -> int:
    """An exclusive lock on the run folder (``flock`` on the folder itself; it dies with the process).

    Two runs into one folder would interleave their links and summaries: the
    second one stops with an :class:`OutputError` instead. Runs sharing a
    *cache* are fine (shared lock, entries written whole; see the module doc).
    """
    try:
        fd = os.open(out, os.O_RDONLY)
    except OSError as exc:
        raise write_error(out, exc, "output folder") from exc
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise OutputError(f"output folder {out} is in use by another bladewear run; wait for it to finish "
                          "or choose another --out") from None
    return fd


def _blas_line() -> str:
    """What the run's dense linear algebra runs on: the kernels of every OpenBLAS loaded (NumPy's,
    SciPy's; :mod:`workflow.blas_kernels`), which set a run's seconds as much as the machine."""
    from workflow.engine.blas import corenames

    cores = sorted({core for _, core in corenames()})
    chosen = os.environ.get("OPENBLAS_CORETYPE")
    return (f"BLAS: OpenBLAS kernels {', '.join(cores) or '(none found)'}"
            + (f" (OPENBLAS_CORETYPE={chosen})" if chosen else ""))


def _run(scene: Scene, p: Plan, out: Path, cache_root: Path, fresh: bool, log: RunLog,
         model: dict | None = None, grp=None) -> dict:
    grp = grp or mpi.Serial()
    t_start = time.monotonic()
    log.info(f"scene {scene.path or '(in memory)'}: {scene.title}")
    log.info("stages: " + " → ".join(p.stages) + (f" (bundle from {p.external['bundle']})"
                                                    if "bundle" in p.external else ""))
    log.info(_blas_line())
    status: dict[str, str] = {}
    timings: dict[str, float] = {}
    summaries: dict[str, dict] = {}
    folders: dict[str, Path] = {}  # stage → folder holding its outputs
    products: dict[str, Path] = dict(p.external)
    if model is not None:
        log.info(f"model bundle {model['bundle']}: {model.get('n_dofs')} DOFs, "
                 f"{model.get('contact_pairs')} contact pairs")
        summaries["model"] = model
        status["model"] = "external"
    with contextlib.ExitStack() as stack:
        grp.root_only(stack.enter_context, cache_lock(cache_root) if grp.root else None)
        for name in p.stages:
            module = p.modules[name]
            if getattr(module, "NEEDS_ALL", False) or not getattr(module, "CACHE", True):
                continue  # runs after the cached stages, before the switch (the report)
            entry = cache_root / name / p.keys[name]
            t0 = time.monotonic()
            got, damage = (None, None) if fresh else grp.on_root(check_entry, entry)
            if damage:
                log.warning(f"{name}: cache entry {entry} is damaged ({damage}); recomputing it")
            if got is not None:
                status[name] = "cached"
                log.info(f"{name}: cached ({entry})")
            else:
                inputs = {need: products[need] for need in module.NEEDS}
                got = _compute(scene, module, inputs, entry, p.keys[name], log, grp)
                status[name] = "computed"
            timings[name] = round(time.monotonic() - t0, 3)
            summaries[name] = got.get("summary", {})
            folders[name] = entry
            for product in module.PRODUCES:
                products[product] = entry
        uncached: dict[str, str] = {}  # uncached stage → its folder, under a temporary name in out
        try:
            for name in p.stages:
                if name in status:
                    continue
                t0 = time.monotonic()
                summaries[name], uncached[name] = grp.on_root(_run_uncached, scene, p, name, out, products, status,
                                                              timings, summaries, log)
                status[name] = "computed"
                timings[name] = round(time.monotonic() - t0, 3)
            return grp.on_root(_finish, scene, p, out, cache_root, status, timings, summaries, log, t_start,
                               folders, uncached)
        finally:
            if grp.root:
                for tmp in uncached.values():  # left only when the run failed before the switch
                    shutil.rmtree(tmp, ignore_errors=True)


def _finish(scene, p, out, cache_root, status, timings, summaries, log, t_start, folders=None,
            uncached=None) -> dict:
    summary = _summary(scene, p, cache_root, status, timings, summaries)
    summary["total_seconds"] = round(time.monotonic() - t_start, 3)
    for name, lines in summary["unconverged"].items():
        for line in lines:
            log.warning(f"{name}: not converged: {line}")
    for name, lines in summary["warnings"].items():
        for line in lines:
            log.warning(f"{name}: check: {line}")
    _switch(out, folders or {}, p, uncached or {},
            {"scene.json": json.loads(scene.canonical()), "summary.json": summary})
    n_bad = sum(len(v) for v in summary["unconverged"].values())
    log.info(f"done in {summary['total_seconds']:.1f} s: "
             + ", ".join(f"{n} {s}" for n, s in status.items()) + f"; summary in {out / 'summary.json'}"
             + (f"; {n_bad} result(s) NOT converged (exit status 3)" if n_bad else ""))
    return summary


def progress_folder(entry: Path) -> Path:
    """Where the stage computing ``entry`` keeps its finished pieces until the entry is committed
    (:mod:`workflow.progress`): beside the entry, named by its key."""
    return entry.parent / f"{entry.name}.progress"


def _compute(scene: Scene, module: ModuleType, inputs: dict, entry: Path, key: str, log: RunLog, grp=None) -> dict:
    """Run one stage into a fresh temporary folder that becomes ``entry`` whole.

    Under MPI a stage with ``MPI = True`` runs on every rank (rank 0 owns the
    folder and the entry file); any other stage runs on rank 0 alone.
    """
    grp = grp or mpi.Serial()
    if not grp.parallel:
        return _compute_here(scene, module, inputs, entry, key, log)
    if not getattr(module, "MPI", False):
        return grp.on_root(_compute_here, scene, module, inputs, entry, key, log)
    name = module.NAME
    cm = atomic_dir(entry) if grp.root else None
    tmp = grp.on_root(lambda: (log.note(f"{name}: computing (collective, {grp.size} ranks)"), cm.__enter__())[1])
    t0 = time.monotonic()
    try:
        with heartbeat(log, name) if grp.root else contextlib.nullcontext(), \
                progress.stage_progress(progress_folder(entry), key):
            summary = grp.together(module.run, scene, dict(inputs), tmp, log.child(name))
    except BaseException as exc:
        if grp.root:
            cm.__exit__(type(exc), exc, exc.__traceback__)  # removes the temporary folder
        raise

    def commit() -> dict:
        got = {"stage": name, "key": key, "summary": summary if summary is not None else {},
               "seconds": round(time.monotonic() - t0, 3), "created": _now(),
               "inputs": {k: str(v) for k, v in inputs.items()},
               "sections": json.loads(scene.canonical(module.SECTIONS)), "mpi_ranks": grp.size}
        try:
            got["files"] = manifest(tmp)
            write_json(tmp / STAGE_FILE, seal_record(got))
        except BaseException as exc:
            cm.__exit__(type(exc), exc, exc.__traceback__)
            raise
        cm.__exit__(None, None, None)
        _remove(progress_folder(entry))
        log.info(f"{name}: computed in {got['seconds']:.1f} s on {grp.size} ranks")
        return json.loads((entry / STAGE_FILE).read_text())

    return grp.on_root(commit)


def _compute_here(scene: Scene, module: ModuleType, inputs: dict, entry: Path, key: str, log: RunLog) -> dict:
    """:func:`_compute` in this process alone (serial runs; non-MPI stages on rank 0)."""
    name = module.NAME
    log.note(f"{name}: computing")
    t0 = time.monotonic()
    with atomic_dir(entry) as tmp, heartbeat(log, name), progress.stage_progress(progress_folder(entry), key):
        summary = module.run(scene, dict(inputs), tmp, log.child(name))
        seconds = time.monotonic() - t0
        got = {"stage": name, "key": key, "summary": summary if summary is not None else {},
               "seconds": round(seconds, 3), "created": _now(),
               "inputs": {k: str(v) for k, v in inputs.items()},
               "sections": json.loads(scene.canonical(module.SECTIONS))}
        # Last file written: an entry without it is never trusted.
        got["files"] = manifest(tmp)
        write_json(tmp / STAGE_FILE, seal_record(got))
    _remove(progress_folder(entry))
    log.info(f"{name}: computed in {seconds:.1f} s")
    return json.loads((entry / STAGE_FILE).read_text())


def _run_uncached(scene, p: Plan, name, out, products, status, timings, summaries, log) -> tuple[dict, str]:
    """An uncached stage (the report): into a temporary folder in ``out`` that
    :func:`_switch` renames to ``out/<name>``; sees all products. Returns
    ``(summary, temporary folder)``."""
    module = p.modules[name]
    inputs = dict(products) if getattr(module, "NEEDS_ALL", False) else {n: products[n] for n in module.NEEDS}
    log.note(f"{name}: computing")
    pre = out / f".{name}.summary.tmp"
    tmp = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".tmp", dir=out))
        os.chmod(tmp, 0o777 & ~current_umask())  # mkdtemp creates 0700
        if getattr(module, "NEEDS_ALL", False):
            # What the report shows: the run so far (this stage's own entry excluded).
            write_json(pre, _summary(scene, p, None, status, timings, summaries))
            inputs["summary"] = pre
        summary = module.run(scene, inputs, tmp, log.child(name)) or {}
    except BaseException as exc:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError):
            raise write_error(out / name, exc) from exc
        raise
    finally:
        with contextlib.suppress(OSError):
            pre.unlink()
    return summary, str(tmp)


def _switch(out: Path, folders: dict[str, Path], p: Plan, uncached: dict[str, str], files: dict) -> None:
    """Switch the run folder from the previous run to this one, whole or not at all.

    First everything that takes space is written under temporary names in
    ``out``: a relative link per stage (to its cache entry) and ``model`` (to
    an external bundle), the uncached stages' folders (:func:`_run_uncached`)
    and ``files`` (``scene.json``, ``summary.json``, as JSON). A failure there
    (disk full) removes them and leaves the previous run as it was. Then only
    renames: each entry of the previous run is renamed aside to ``.<name>.old``
    and the new one renamed in; links of stages this run did not use, an
    earlier run's uncached folder (the report) and a stale ``model`` link are
    renamed aside too (only links and our stage folders, never other files).
    A rename that fails undoes the ones before it, so ``out`` shows the
    previous run whole, or this one once every rename succeeded (summary.json
    last); then the ``.old`` entries are deleted. Only a process killed inside
    the renames (a few system calls) can leave both: the ``.old`` entries
    remain, and the next run removes them (:func:`clean_stale`).
    """
    staged: list[tuple[Path, Path | None]] = []  # (entry in out, this run's under a temporary name | None: remove)
    try:
        try:
            for name, target in folders.items():
                staged.append((out / name, _staged_link(out / name, target)))
            if "bundle" in p.external:
                staged.append((out / "model", _staged_link(out / "model", p.external["bundle"])))
            elif (out / "model").is_symlink():
                staged.append((out / "model", None))
            for name, tmp in uncached.items():
                staged.append((out / name, Path(tmp)))
            for child in sorted(out.iterdir()):
                if child.name in folders or child.name in uncached or child.name not in registry.MODULES:
                    continue
                # A link of a stage this run did not use, or an uncached stage's folder (the report)
                # from an earlier run: either would contradict this run's summary.json.
                if child.is_symlink() or (child.is_dir() and child.name not in p.stages):
                    staged.append((child, None))
            for name, data in files.items():
                staged.append((out / name, _staged_json(out / name, data)))
        except OSError as exc:
            raise write_error(out, exc, "output folder") from exc
        _rename_all(out, staged)
    finally:
        for _, new in staged:
            if new is not None and os.path.lexists(new):
                _remove(new)


def _staged_link(link: Path, target: Path) -> Path:
    """A relative link to ``target`` named ``.<link>.link.tmp`` beside ``link``."""
    if link.exists() and not link.is_symlink():
        # Not ours to replace: a real file or folder where a stage link goes.
        raise OutputError(f"cannot link {link}: a file or folder of that name is in the way")
    tmp = link.with_name(f".{link.name}.link.tmp")
    if os.path.lexists(tmp):
        tmp.unlink()
    os.symlink(os.path.relpath(target, link.parent), tmp)
    return tmp


def _staged_json(path: Path, data) -> Path:
    """``data`` as JSON in ``.<name>.new.tmp`` beside ``path`` (written whole, fsynced)."""
    tmp = path.with_name(f".{path.name}.new.tmp")
    try:
        write_json(tmp, data)
    except OutputError as exc:
        cause = exc.__cause__
        raise OutputError(f"cannot write {path}: {getattr(cause, 'strerror', None) or cause or exc}") from exc
    return tmp


def _rename_all(out: Path, staged: list[tuple[Path, Path | None]]) -> None:
    """The renames of :func:`_switch`; undone in reverse order if one fails."""
    done: list[tuple[Path, Path | None, Path | None]] = []  # (entry, its previous one aside, new)
    entry = out
    try:
        for entry, new in staged:
            old = None
            if os.path.lexists(entry):
                old = entry.with_name(f".{entry.name}.old")
                if os.path.lexists(old):
                    _remove(old)
                if new is not None and (new.is_symlink() or not new.is_dir()) and _copy_aside(entry, old):
                    # A file or link: replaced in one rename, the previous one kept for an undo.
                    try:
                        os.replace(new, entry)
                    except OSError:
                        _remove(old)
                        raise
                    done.append((entry, old, new))
                    continue
                os.replace(entry, old)
            done.append((entry, old, new))
            if new is not None:
                os.replace(new, entry)
    except OSError as exc:
        for back, old, new in reversed(done):
            with contextlib.suppress(OSError):
                if new is not None and not os.path.lexists(new) and os.path.lexists(back):
                    os.replace(back, new)  # this run's entry back to its temporary name (removed by _switch)
                if old is not None:
                    os.replace(old, back)
        raise write_error(entry, exc) from exc
    for _, old, _ in done:
        if old is not None:
            _remove(old)


def _copy_aside(entry: Path, old: Path) -> bool:
    """Keep a file (hard link) or link (same target) as ``old``; False for a folder or if that fails."""
    try:
        if entry.is_symlink():
            os.symlink(os.readlink(entry), old)
        elif entry.is_file():
            os.link(entry, old)
        else:
            return False
    except OSError:
        _remove(old)
        return False
    return True


def _remove(path: Path) -> None:
    """Delete a link, file or folder (best effort)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def _check_bundle(folder: Path) -> dict:
    """Validate a user's bundle before anything is written (BundleError names the file)."""
    from reduction.bundle import check_definite, read_bundle  # lazily: scipy

    b = read_bundle(folder)
    definite = check_definite(b)
    return {"bundle": str(folder), "n_dofs": b.n_dofs, "contact_pairs": b.contact.n_pairs,
            "clamped_dofs": int(len(b.loads.fixed)), "tied_stiffness_check": definite,
            "mu": "per pair (contact.npz)" if b.contact.mu is not None else "scene contact.mu"}


def _summary(scene: Scene, p: Plan, cache_root, status, timings, summaries) -> dict:
    s = {"scene": str(scene.path) if scene.path else None, "title": scene.title,
         "outputs": list(scene["run"].outputs), "overrides": list(scene.overrides),
         "created": _now(), "code_version": code_version(),
         "cache": str(cache_root) if cache_root else None,
         "stages": dict(status), "timings": dict(timings),
         "keys": {n: p.keys[n] for n in status if n in p.keys},
         "unconverged": stage_lines(summaries, "unconverged"), "warnings": stage_lines(summaries, "warnings")}
    for name, entry in summaries.items():
        s[name] = entry
    return s


def stage_lines(summaries: dict, key: str) -> dict[str, list[str]]:
    """``{stage: [line, …]}`` of the stages whose summary lists ``key``: "unconverged" (results
    that did not converge) or "warnings" (converged results whose checks exceed their tolerance
    or could not run)."""
    out = {}
    for name, entry in summaries.items():
        lines = entry.get(key) if isinstance(entry, dict) else None
        if lines:
            out[name] = [str(x) for x in (lines if isinstance(lines, (list, tuple)) else [lines])]
    return out


def _now() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")
