"""Running the pipeline under ``mpirun``/``srun``: who does what, and failing together.

Serial runs never import mpi4py from here: :func:`group` returns a
:class:`Serial` group whose methods just call the function. Under an MPI
launcher with more than one rank it returns a :class:`Group` over
``MPI.COMM_WORLD``:

* :meth:`Group.on_root` — rank 0 runs the function (planning, cache reads and
  writes, the run folder, the serial stages); the other ranks wait *politely*
  (a non-blocking barrier polled with sleeps, so an idle rank does not spin a
  core that rank 0's BLAS threads could use) and receive its result — or its
  exception, which they then raise too.
* :meth:`Group.together` — every rank runs the function (a collective stage:
  assembly, reduction, modes); afterwards the ranks agree on success. If one
  rank failed, every rank raises the same exception (the lowest failing
  rank's). A rank that failed while the others are blocked inside a
  collective call (MPI cannot interrupt them) waits ``BLADEWEAR_MPI_GRACE``
  seconds (default 60) for them, then prints its error and calls
  ``MPI_Abort``: the job exits non-zero instead of hanging.

The control messages go over a duplicate of the world communicator, so they
never match a collective call of dolfinx/PETSc inside a stage.

While rank 0 runs a function through :meth:`Group.on_root` the other ranks
are outside MPI, and no timeout can tell a long stage from a stuck one: such
a function must never make a collective call on COMM_WORLD (the remap stage
reads its mesh on COMM_SELF), and PETSc — whose initialisation is
collective — is initialised on every rank when a run starts
(:func:`init_petsc`). Both used to hang ``mpirun -n 2 bladewear run quick``.
"""
from __future__ import annotations

import os
import pickle
import sys
import time
import traceback

from workflow.engine.blas import launched

#: Exit status of an aborted MPI job (same as the CLI's for a BladewearError).
ABORT_STATUS = 2


def world():
    """``MPI.COMM_WORLD`` when running on more than one rank, else None (no mpi4py import)."""
    if not launched():
        return None
    from mpi4py import MPI

    return MPI.COMM_WORLD if MPI.COMM_WORLD.Get_size() > 1 else None


def rank() -> int:
    """This process's rank (0 when not under MPI)."""
    comm = world()
    return 0 if comm is None else comm.Get_rank()


class Serial:
    """One process: every method simply runs the function."""

    parallel = False
    root = True
    rank = 0
    size = 1
    comm = None

    def on_root(self, fn, *args, **kwargs):
        return fn(*args, **kwargs)

    def root_only(self, fn, *args, **kwargs):
        return fn(*args, **kwargs)

    def together(self, fn, *args, **kwargs):
        return fn(*args, **kwargs)

    def bcast(self, value):
        return value


class Group:
    """The ranks of an MPI job running one scene (see the module docstring)."""

    parallel = True

    def __init__(self, comm, grace: float | None = None):
        self.comm = comm
        self.ctl = comm.Dup()  # control messages never mix with a stage's collectives
        self.rank = comm.Get_rank()
        self.size = comm.Get_size()
        self.root = self.rank == 0
        self.grace = float(os.environ.get("BLADEWEAR_MPI_GRACE", 60.0) if grace is None else grace)

    # ------------------------------------------------------------ rank 0 only
    def root_only(self, fn, *args, **kwargs):
        """Run ``fn`` on rank 0 and return its result there (None elsewhere); failures are shared."""
        kept = []
        self.on_root(lambda: kept.append(fn(*args, **kwargs)))
        return kept[0] if kept else None

    def on_root(self, fn, *args, **kwargs):
        """Run ``fn`` on rank 0; every rank returns its result or raises its exception."""
        own = msg = None
        if self.root:
            try:
                msg = ("ok", fn(*args, **kwargs))
            except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt too: the others must not wait
                own, msg = exc, ("error", _portable(exc))
            self.ctl.Ibarrier().Wait()
        else:
            self._idle(self.ctl.Ibarrier())
        kind, value = self.ctl.bcast(msg, root=0)
        if kind == "error":
            raise own if own is not None else value  # rank 0 keeps its traceback
        return value

    def bcast(self, value):
        return self.ctl.bcast(value, root=0)

    # ------------------------------------------------------------ every rank
    def together(self, fn, *args, **kwargs):
        """Run ``fn`` on every rank; if any rank fails, every rank raises the same error."""
        err = None
        try:
            value = fn(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001
            err, value = exc, None
        req = self.ctl.Ibarrier()
        if err is None:
            self._idle(req)
        elif not self._idle(req, timeout=self.grace):
            self._abort(err)
        errors = self.ctl.allgather(None if err is None else _portable(err))
        failed = [e for e in errors if e is not None]
        if failed:
            if err is not None and errors[self.rank] is not None and failed[0] is errors[self.rank]:
                raise err  # this rank's own exception, with its traceback
            raise failed[0]
        collect_garbage()
        return value

    # ------------------------------------------------------------ helpers
    @staticmethod
    def _idle(req, timeout: float | None = None) -> bool:
        """Poll ``req`` with short sleeps; False when ``timeout`` [s] passes first."""
        t0 = time.monotonic()
        pause = 1e-4
        while not req.Test():
            if timeout is not None and time.monotonic() - t0 > timeout:
                return False
            time.sleep(pause)
            pause = min(2 * pause, 0.02)
        return True

    def _abort(self, err: BaseException) -> None:
        from workflow.errors import BladewearError

        if isinstance(err, BladewearError):
            print(f"error (rank {self.rank}): {' '.join(str(err).split())}", file=sys.stderr, flush=True)
        else:
            traceback.print_exception(type(err), err, err.__traceback__, file=sys.stderr)
        print(f"error (rank {self.rank}): the other ranks did not finish within {self.grace:.0f} s "
              "(blocked in a collective call?); aborting the MPI job", file=sys.stderr, flush=True)
        self.comm.Abort(ABORT_STATUS)


def collect_garbage() -> None:
    """Destroy, on every rank together, the PETSc objects Python has dropped (collective).

    PETSc ≥ 3.18 defers destroying parallel objects that the garbage collector
    frees (it may free them at different times on different ranks) and
    cleans them up collectively; left to interpreter exit, that cleanup can
    run on one rank while another is already in ``MPI_Finalize`` — a hang.
    Call on every rank of the job, after each collective stage and at exit.
    """
    if "petsc4py.PETSc" not in sys.modules:
        return
    import gc

    from petsc4py import PETSc

    gc.collect()
    PETSc.garbage_cleanup(PETSc.COMM_WORLD)


def init_petsc() -> None:
    """Initialise PETSc now (call on every rank together, before any stage).

    ``PetscInitialize`` is collective over COMM_WORLD. A serial stage that is
    the first to import dolfinx/petsc4py on rank 0 (remap, when assembly and
    reduction came from the cache) would initialise it there alone and wait
    forever for the idle ranks; and :func:`finish` must find PETSc on every
    rank or on none. Measured: ``mpirun -n 2 bladewear run quick`` with hb,
    wear and remap to compute and the rest cached hung in remap without this.
    """
    from petsc4py import PETSc  # noqa: F401 - the import initialises PETSc (collective)


def finish() -> None:
    """End PETSc on every rank together, while all ranks are alive (call last, on every rank).

    Measured here (Open MPI 4.1, PETSc 3.18): after a MUMPS factorisation on
    ``COMM_SELF`` on rank 0 alone — the prestress solve and the modal-damping
    eigen-solve of the assembly, any serial stage — petsc4py's own
    ``PetscFinalize`` at interpreter exit duplicates a communicator on rank
    0 while rank 1 is already inside ``MPI_Finalize``, and the job hangs.
    Finalising PETSc explicitly and collectively first avoids it.
    """
    if "petsc4py.PETSc" not in sys.modules:
        return
    from petsc4py import PETSc

    collect_garbage()
    PETSc.COMM_WORLD.barrier()
    finalize = getattr(PETSc, "_finalize", None)
    if finalize is not None:
        finalize()


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling (to be sent to the other ranks), else a RuntimeError naming it."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(exc).__name__}: {exc}")


def group(comm=None):
    """The :class:`Group` of this MPI job, or a :class:`Serial` one."""
    comm = comm if comm is not None else world()
    if comm is None or comm.Get_size() == 1:
        return Serial()
    return Group(comm)


def mpirun_command(n: int) -> list[str] | None:
    """``[mpirun, -n, N, …]`` for launching ``n`` ranks from a script or a test; None without mpirun.

    Open MPI gets ``--oversubscribe`` (more ranks than cores is fine for a
    test) and, as root, ``--allow-run-as-root``.
    """
    import shutil
    import subprocess

    exe = shutil.which("mpirun") or shutil.which("mpiexec")
    if exe is None:
        return None
    cmd = [exe, "-n", str(int(n))]
    try:
        version = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        version = ""
    if "Open MPI" in version or "OpenRTE" in version:
        cmd.insert(1, "--oversubscribe")
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            cmd.insert(1, "--allow-run-as-root")
    return cmd


def single_thread_env(env: dict | None = None) -> dict:
    """``env`` (default: this process's) with one BLAS/OpenMP thread per rank (no oversubscription)."""
    env = dict(os.environ if env is None else env)
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[k] = "1"
    return env
