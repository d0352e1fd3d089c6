"""How a batch's rows run on threads: the calling thread and helper threads take chunks of rows.

(Moved from :mod:`redysim.algorithms.dynamics`; the contract follows in a later commit.)
"""

from __future__ import annotations

import os
import queue
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from redysim.algorithms._kernels import spin as _spin
from redysim.algorithms.workspace import Workspace
from redysim.errors import FieldError

# How a batch's rows run on threads (docs/design.md, "Threads under load"): the calling thread
# works through the batch chunk by chunk, taking each next chunk from a shared counter, and helper
# threads (a pool of plain Python threads calling the compiled kernels, which release the GIL)
# take chunks from the same counter if and when the OS runs them, each in arrays of its own. The
# caller never waits for a helper to start; at the end it copies in the helpers' chunks, and
# runs itself any chunk whose helper is late with it: a batch is never held up by a thread the
# OS has not scheduled (numba's threads, a static split, had made the caller wait a scheduler
# time slice for the other half when another process kept a core busy: 13-24x one thread). And a
# batch wakes helpers only for idle cores (helpers_for).
CHUNK_WORK = 8000  # DOF x states a chunk of a batch holds at most (~0.16 ms in SIMD tiles, ~0.35
# ms row by row): a batch under it runs on the calling thread alone (benchmarks/busy_batch.py:
# 2,000 and 4,000 cost 4-5 % and 2 % more than one thread per 64-state batch at 250 DOF, 8,000
# under 1 %)
THREADS_VARIABLE = "REDYSIM_THREADS"  # when set, the default thread count (pool workers: 1)


def default_threads() -> int:
    """Threads a batch uses when ``threads`` is not given: the environment variable
    ``REDYSIM_THREADS`` when it is set (the harness's process pools set 1 in their workers, one
    thread a process), else the cores this process may run on."""
    value = os.environ.get(THREADS_VARIABLE)
    if value:
        count = int(value) if value.strip().isdigit() else 0
        if count < 1:
            raise FieldError("environment", THREADS_VARIABLE, value,
                             "must be a whole number >= 1 (threads of a batch)")
        return count
    now = time.monotonic()
    if now - _CORES[0] > 1.0:  # (looked at once a second: ~1 us a look)
        try:
            _CORES[:] = now, len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            _CORES[:] = now, os.cpu_count() or 1
    return int(_CORES[1])


_CORES = [-2.0, 1]  # (when, cores this process may use) of the last look

def thread_count(threads: int | None, chunks: int) -> int:
    """Threads for ``chunks`` chunks of work: ``threads`` (checked), or :func:`default_threads`
    (not read for one chunk: the environment costs ~1 us a look, 2 % of a robot's batch), and no
    more than there are chunks."""
    if threads is None:
        return 1 if chunks <= 1 else min(default_threads(), chunks)
    if isinstance(threads, bool) or not isinstance(threads, int | np.integer) or threads < 1:
        raise FieldError("dynamics", "threads", threads, "must be a whole number >= 1")
    return max(1, min(int(threads), chunks))


def chunk_edges(units: int, work: int) -> list[int]:
    """Edges of ceil(work / CHUNK_WORK) chunks of ``units`` (rows, or tiles), at most one a
    unit, of sizes as equal as may be (``work``: DOF x states)."""
    chunks = max(1, min(units, -(-work // CHUNK_WORK)))
    return [units * i // chunks for i in range(chunks + 1)]


class _Own:
    """A helper thread's own buffers (scratch, SIMD tile arrays), by size, the last few kept:
    a helper never writes into a workspace or into a batch's outputs, so that one left behind
    by its batch (its chunk taken back by the caller) harms nothing."""

    KEEP = 4

    def __init__(self) -> None:
        self.arrays: dict[tuple, np.ndarray] = {}
        try:  # the helper thread's CPU-time clock, which the caller reads to see it progress
            self.clock: int | None = time.pthread_getcpuclockid(threading.get_ident())
        except (AttributeError, OSError):
            self.clock = None

    def get(self, like: np.ndarray) -> np.ndarray:
        key = (like.size, AB["aligned"])  # (A/B: each variant its own arrays)
        a = self.arrays.pop(key, None)
        if a is None:
            a = np.zeros(like.size)  # (as a workspace's tile arrays start)
            if AB["aligned"]:  # (A/B) on a 64-byte boundary, as Workspace.tile_buffer's
                raw = np.zeros(like.size + 8)
                start = (-raw.ctypes.data // 8) % 8
                a = raw[start:start + like.size]
            while len(self.arrays) >= self.KEEP:
                self.arrays.pop(next(iter(self.arrays)))
        self.arrays[key] = a  # (the most recent last)
        return a


FREE, CALLER, HELPER, DONE, TAKEN_BACK = range(5)  # a chunk's states


class _Chunks:
    """One batch's chunks (``edges``: chunk i is rows edges[i]..edges[i + 1] - 1), handed out in
    order to whichever thread asks next. ``call(first, last, own)`` runs one: on the calling
    thread with ``own`` None, in the caller's buffers and outputs; on a helper with its
    :class:`_Own`. ``commit(first, last, result)``, when given, is how a helper's chunk reaches
    the outputs: a helper's call then returns (value, result) computed in its own arrays, and
    the caller commits it, or, when the helper has not finished it by the time one chunk of the
    caller's would take, runs the chunk itself (a helper held up by the OS holds up nobody).
    Without ``commit`` the caller waits for the helpers' chunks. Once a chunk has raised, no
    chunk is handed out any more."""

    __slots__ = ("call", "commit", "edges", "lock", "next", "state", "started", "clocks",
                 "flags", "values", "results", "errors", "waiter", "per_row", "done")

    def __init__(self, call, edges: list[int], commit=None):
        self.call = call
        self.commit = commit
        self.edges = edges
        self.lock = threading.Lock()
        self.next = 0  # the next chunk to hand out
        n = len(edges) - 1
        self.state = [FREE] * n
        # a helper's chunk: (perf_counter, the helper's CPU time, its CPU-time clock) when taken
        self.started: list[tuple[float, int, int | None]] = [(0.0, 0, None)] * n
        self.flags = np.zeros(1, dtype=np.int64)  # chunks helpers run (waited on without GIL)
        self.values: list = [None] * n
        self.results: list = [None] * n  # a helper's chunk's arrays, for commit
        self.errors: dict[int, BaseException] = {}  # chunk -> what it raised
        self.waiter: threading.Lock | None = None  # (without commit) released when flags is 0
        self.per_row = 0.0  # the caller's seconds a row, from its own chunks
        self.done = threading.Condition(self.lock)  # (A/B: caller_spin off) a helper's chunk done

    def _take(self, state: int, own: _Own | None = None) -> int:
        with self.lock:
            i = self.next
            if i >= len(self.state) or self.errors:
                return -1
            self.next = i + 1
            self.state[i] = state
            if own is not None:
                clock = own.clock
                self.started[i] = (time.perf_counter(),
                                   0 if clock is None else time.clock_gettime_ns(clock), clock)
                self.flags[0] += 1
            return i

    def work(self) -> None:
        """The caller's part: chunks until none are left (or one has raised)."""
        edges, rows, spent = self.edges, 0, 0.0
        while (i := self._take(CALLER)) >= 0:
            t0 = time.perf_counter()
            try:
                self.values[i] = self.call(edges[i], edges[i + 1], None)
            except BaseException as exc:  # re-raised at the end
                with self.lock:
                    self.errors[i] = exc
            spent += time.perf_counter() - t0
            rows += edges[i + 1] - edges[i]
        if rows:
            self.per_row = spent / rows

    def help(self, own: _Own) -> None:
        """A helper's part: chunks, if any are left, in its own arrays."""
        edges = self.edges
        while (i := self._take(HELPER, own)) >= 0:
            value = result = error = None
            try:
                value = self.call(edges[i], edges[i + 1], own)
                if self.commit is not None:
                    value, result = value
            except BaseException as exc:
                error = exc
            with self.lock:
                if self.state[i] == HELPER:  # (not taken back by the caller)
                    self.state[i] = DONE
                    self.flags[0] -= 1
                    self.values[i], self.results[i] = value, result
                    if error is not None:
                        self.errors[i] = error
                    if not AB["caller_spin"]:
                        self.done.notify_all()
                if not self.flags[0] and self.waiter is not None:
                    self.waiter.release()
                    self.waiter = None

    def finish(self) -> list:
        """After :meth:`work`: the helpers' chunks committed (or run here), the values in row
        order; or the exception of the lowest chunk that raised."""
        if self.commit is None:
            self._wait()
        else:
            self._take_back()
        if self.errors:
            raise self.errors[min(self.errors)]
        return self.values

    def _take_back(self) -> None:
        edges, clock = self.edges, None
        for i in range(len(self.state)):
            while self.state[i] == HELPER and not self.errors:
                left = self._left(i)
                if left is not None and not AB["caller_spin"]:
                    with self.lock:
                        if self.state[i] == HELPER:
                            self.done.wait(left)
                    continue
                if left is not None and _SPIN:  # spin while the helper should be about done
                    clock = np.empty(2, dtype=np.int64) if clock is None else clock
                    seen = int(self.flags[0])
                    if seen:
                        _spin.wait_change(self.flags, 0, seen, int(left * 1e9), AWAY_NS, clock,
                                           False)
                        continue  # a helper finished a chunk, or time to look again
                with self.lock:  # late, or this core is wanted: the chunk is the caller's
                    mine = self.state[i] == HELPER
                    if mine:
                        self.state[i] = TAKEN_BACK
                        self.flags[0] -= 1
                if mine:
                    try:
                        self.values[i] = self.call(edges[i], edges[i + 1], None)
                    except BaseException as exc:
                        with self.lock:
                            self.errors[i] = exc
            if self.state[i] == DONE and self.results[i] is not None:
                self.commit(edges[i], edges[i + 1], self.results[i])
                self.results[i] = None

    def _left(self, i: int) -> float | None:
        """Seconds to wait for helper chunk i before looking again, or None: take it back.

        The chunk is the caller's work of ``per_row`` a row, allowed 1.5x on the helper (two
        threads share caches). From the CPU time the helper has had since it took the chunk
        (its CPU-time clock), at the rate it got it: left when the caller would finish sooner
        itself (a helper the OS holds up gets no CPU time); without that clock, from the wall
        time since it took the chunk."""
        t0, cpu0, clock = self.started[i]
        clock = clock if AB["cpu_clock"] else None
        work = 1.5 * self.per_row * (self.edges[i + 1] - self.edges[i]) + 20e-6
        elapsed = time.perf_counter() - t0
        if clock is None:
            left = work - elapsed
            return left if left > 0 else None
        cpu = (time.clock_gettime_ns(clock) - cpu0) * 1e-9
        rate = cpu / elapsed if elapsed > 0 else 1.0
        left = max(work - cpu, 0.1 * work) / max(rate, 1e-3)
        return min(left, 0.1 * work + 10e-6) if left < work / 1.5 else None
    def _wait(self) -> None:
        """Wait for the chunks that helpers run (none can start any more): a while without
        sleeping, as long as no other thread wants this core, then asleep."""
        running = int(self.flags[0])
        if running and _SPIN and AB["caller_spin"]:
            clock = np.empty(2, dtype=np.int64)
            while running and _spin.wait_change(self.flags, 0, running, CALLER_SPIN_NS,
                                                 AWAY_NS, clock, False) == 1:
                running = int(self.flags[0])
        with self.lock:
            if not self.flags[0]:
                return
            waiter = self.waiter = threading.Lock()
            waiter.acquire()
        interrupted = None
        while True:  # an interrupt must not let the caller go while a helper writes its arrays
            try:
                waiter.acquire()
                break
            except BaseException as exc:  # KeyboardInterrupt: re-raised once the helpers stop
                interrupted = exc
        if interrupted is not None:
            raise interrupted


# The helpers: plain Python threads, started on first need, that take batches from _JOBS. A
# helper that has finished a batch watches _POSTED for the next one for HELPER_SPIN_NS without
# sleeping (waking a sleeping thread took ~60-80 us on our VMs, a quarter of a 64-state batch at
# 250 DOF), unless its core is wanted by another thread (AWAY_NS: a sched_yield that kept it off
# its core longer than that), then sleeps in _JOBS.get(). Helpers run SCHED_BATCH (Linux): they
# never preempt a thread when they wake, and keep a normal share of the CPU.
_JOBS: queue.SimpleQueue = queue.SimpleQueue()  # batches waiting for a helper
_POSTED = np.zeros(1, dtype=np.int64)  # batches posted so far (watching helpers see it change)
_WATCHING: list[bool] = []  # helper k is watching _POSTED (on a core of its own, awake)
_HELPERS_LOCK = threading.Lock()
HELPER_SPIN_NS = 200_000
CALLER_SPIN_NS = 1_000_000  # (without commit) the caller's wait for helpers before it sleeps
AWAY_NS = 20_000
IDLE_CHECK_S = 0.002  # how long a look at the machine that found idle cores stays true
BUSY_CHECK_S = 0.02  # and one that found none (a look costs ~10 us; a busy machine stays busy)
_SPIN = _spin.SPIN_OK
_LOADAVG: int | None = None  # a descriptor of /proc/loadavg, opened on first use
_IDLE = [-1.0, 0]  # (when, idle cores) of the last look


def watching_helpers() -> int:
    """Helpers awake on a core of their own, watching for the next batch."""
    return sum(_WATCHING)


def idle_cores() -> int | None:
    """Cores with nothing to run at this instant, from the machine's runnable tasks
    (/proc/loadavg), this thread and our watching helpers not counted; None where that is not
    known (not Linux)."""
    global _LOADAVG
    try:
        if _LOADAVG is None:
            _LOADAVG = os.open("/proc/loadavg", os.O_RDONLY)
        running = int(os.pread(_LOADAVG, 64, 0).split()[3].split(b"/")[0])
    except (OSError, ValueError, IndexError, AttributeError):
        return None
    return (os.cpu_count() or 1) - running + watching_helpers()  # (running counts this thread)


def helpers_for(wanted: int) -> int:
    """How many helpers a batch of the dynamics posts itself to, of ``wanted``: those watching
    for work (awake on cores of their own), and sleeping ones only for cores idle at this
    instant (:func:`idle_cores`, looked at no more than every IDLE_CHECK_S, or BUSY_CHECK_S
    after a look that found none): a helper woken onto a busy core joins late, and shares the
    core, its caches and the GIL with those who run there."""
    if not AB["idle_check"]:
        return wanted
    watching = watching_helpers()
    if watching >= wanted:
        return wanted
    now = time.monotonic()
    if now - _IDLE[0] > (IDLE_CHECK_S if _IDLE[1] > 0 else BUSY_CHECK_S):
        idle = idle_cores()
        _IDLE[:] = now, wanted if idle is None else idle
    return min(wanted, max(watching, int(_IDLE[1])))


class _Speed:
    """Seconds a DOF-state for one kind of batch on one workspace (:attr:`Workspace.batch_speed`),
    alone and with helpers: a batch takes helpers only while they pay."""

    __slots__ = ("alone", "shared", "skip", "backoff", "since_alone")

    def __init__(self) -> None:
        self.alone: float | None = None
        self.shared: list[float] = []  # the last few batches with helpers
        self.skip = 2  # batches to run alone before helpers are tried (again): the first two
        # (the first pays for first touches of its arrays)
        self.backoff = 0  # the last such pause
        self.since_alone = 0  # batches with helpers since the last alone

    def plan(self, count: int) -> int:
        """Threads for the next batch, of ``count``: 1 to measure the time alone (the first two
        batches, every REFRESH-th, and while helpers have not paid), else 1 +
        :func:`helpers_for`."""
        if not ADAPT:
            return 1 + helpers_for(count - 1)
        if self.alone is None or self.skip > 0 or self.since_alone >= REFRESH:
            self.skip = max(0, self.skip - 1)
            return 1
        return 1 + helpers_for(count - 1)

    def record(self, shared: bool, per: float) -> None:
        """A batch's seconds a DOF-state, with helpers or alone. The time alone follows a faster
        batch at once and a slower one by a quarter (what else runs slows a batch, never speeds
        it up: helpers must beat the time alone at its best); with helpers, the median of the
        last SAMPLES batches (one slowed by the OS, or the first after a pause, whose helpers
        wake from sleep, decides nothing) must be under GAIN of it, judged from 3 batches on,
        else helpers pause for 4, 8, ..., 256 batches."""
        if not shared:
            a = self.alone
            self.alone = per if a is None or per < a else a + 0.25 * (per - a)
            self.since_alone = 0
            return
        self.since_alone += 1
        self.shared = [*self.shared[1 - SAMPLES:], per]
        if len(self.shared) < 3 or self.alone is None:
            return
        if float(np.median(self.shared)) > GAIN * self.alone:  # no gain: a pause
            self.backoff = min(max(2 * self.backoff, 4), 256)
            self.skip, self.shared = self.backoff, []
        else:
            self.backoff = 0


ADAPT = True  # batches measure what helpers buy them (_Speed); tests turn it off
GAIN = 0.97  # helpers are kept while a batch with them takes under 0.97 of its time alone
REFRESH = 32  # and one batch in REFRESH runs alone, to keep that time fresh
SAMPLES = 7  # batches with helpers whose median is judged


def _speed(ws: Workspace, key, threads: int | None, chunks: int) -> tuple[int, _Speed | None]:
    """(threads, the speed record to report the batch's time to) for a batch of ``chunks``."""
    count = thread_count(threads, chunks)
    if count == 1:
        return 1, None
    speed = ws.batch_speed.get(key)
    if speed is None:
        speed = ws.batch_speed[key] = _Speed()
    return speed.plan(count), speed


def _policy(local) -> None:
    """(A/B) this helper thread's scheduling policy as AB["batch_sched"] says."""
    want = AB["batch_sched"]
    if getattr(local, "batch", False) != want:
        try:  # never preempt another thread on waking (Linux: SCHED_BATCH, same share of the CPU)
            os.sched_setscheduler(0, os.SCHED_BATCH if want else os.SCHED_OTHER,
                                  os.sched_param(0))
        except (AttributeError, OSError):
            pass
        local.batch = want


def _helper(k: int) -> None:
    local = threading.local()
    _policy(local)
    own, clock = _Own(), np.empty(2, dtype=np.int64)
    while True:
        seen = int(_POSTED[0])
        try:
            job = _JOBS.get_nowait()
        except queue.Empty:
            if _SPIN and AB["spin_watch"]:
                _WATCHING[k] = True
                posted = _spin.wait_change(_POSTED, 0, seen, HELPER_SPIN_NS, AWAY_NS, clock,
                                            True)
                _WATCHING[k] = False
                if posted == 1:
                    continue  # a batch was posted: take it
            job = _JOBS.get()
        _policy(local)
        job.help(own)
        del job  # (not kept alive, with its arrays, until the next batch)


# A/B (benchmarks/ab_threads.py): each piece of the policy on or off, and the helpers a
# concurrent.futures.ThreadPoolExecutor's ("executor") instead of our own ("own")
AB = {"spin_watch": True, "idle_check": True, "batch_sched": True, "caller_spin": True,
      "cpu_clock": True, "pool": "own", "aligned": False}
_EXECUTOR: ThreadPoolExecutor | None = None
_EXEC_LOCAL = threading.local()


def _executor_help(job) -> None:
    local = _EXEC_LOCAL
    if not hasattr(local, "own"):
        local.own = _Own()
    _policy(local)
    job.help(local.own)


def _after_fork() -> None:  # a forked child has no helper threads: it starts its own
    global _JOBS, _HELPERS_LOCK, _WATCHING, _EXECUTOR
    _JOBS, _HELPERS_LOCK, _WATCHING = queue.SimpleQueue(), threading.Lock(), []
    _EXECUTOR = None


os.register_at_fork(after_in_child=_after_fork)


def run_blocks(rows: int, threads: int | None, call, count: int | None = None,
               chunk: int = 1, edges: list[int] | None = None, commit=None) -> list:
    """call(first, last, own) over the rows in chunks of ``chunk`` rows (or the chunks given by
    ``edges``), on the calling thread (``own`` None) and up to ``count`` - 1 helper threads
    (``count``: :func:`thread_count` of ``threads``; ``own``: the helper's :class:`_Own`); the
    chunks' values in row order. With one thread, a single call(0, rows, None).

    The calling thread takes chunks from a shared counter until none are left, and helpers take
    chunks from the same counter when the OS gets round to running them: the caller never waits
    for a helper to start. At the end, with ``commit`` (:class:`_Chunks`), it commits the
    helpers' chunks, taking back those a helper is late with; without, it waits for them (one a
    helper at most). When a chunk raises, no further chunk starts, and the exception of the
    lowest-numbered chunk that raised is re-raised.
    """
    count = thread_count(threads, rows) if count is None else count
    if count == 1:
        return [call(0, rows, None)]
    if edges is None:
        edges = [*range(0, rows, chunk), rows]
    helpers = min(count, len(edges) - 1) - 1
    job = _Chunks(call, edges, commit)
    if helpers > 0 and AB["pool"] == "executor":
        global _EXECUTOR
        if _EXECUTOR is None or _EXECUTOR._max_workers < helpers:
            with _HELPERS_LOCK:
                if _EXECUTOR is None or _EXECUTOR._max_workers < helpers:
                    _EXECUTOR = ThreadPoolExecutor(helpers, thread_name_prefix="redysim-pool")
        for _ in range(helpers):
            _EXECUTOR.submit(_executor_help, job)
    elif helpers > 0:
        if len(_WATCHING) < helpers:
            with _HELPERS_LOCK:
                while len(_WATCHING) < helpers:
                    _WATCHING.append(False)
                    k = len(_WATCHING) - 1
                    threading.Thread(target=_helper, args=(k,), name=f"redysim-batch-{k + 1}",
                                     daemon=True).start()
        for _ in range(helpers):
            _JOBS.put(job)
        _POSTED[0] += 1
    job.work()
    return job.finish()


