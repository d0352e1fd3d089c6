"""The batch thread runtime: a batch's rows in chunks, on the calling thread and helper threads.

A batch of the dynamics (:func:`redysim.forward_dynamics`, :func:`redysim.inverse_dynamics` on
(B, n) arrays) and :func:`redysim.simulate_batch` hand their rows to :func:`run_blocks`, which
calls ``call(first, last, own)`` once for each chunk of rows ``first`` .. ``last - 1``.

What a caller gets
    - Every chunk run once into the outputs: on the calling thread (``own`` None) in the
      caller's arrays, or on a helper thread (``own`` the helper's :class:`Own` buffers) in
      arrays of the helper's own, which the caller hands to ``commit``. The chunks are the
      caller's (``edges``) and depend neither on the threads nor on the machine's load: a
      batch's results are bit for bit those of one thread.
    - The chunks' values in row order. When chunks raise, no chunk starts after the first has,
      and the lowest-numbered one's exception is raised on the calling thread.
    - With ``commit``, the caller never waits for a helper to start, nor long for one to finish:
      a helper's chunk not done by :data:`LATE` times the caller's own time for it (plus
      :data:`LATE_S`) is run again by the caller and the helper's result dropped (a helper
      writes nothing the caller reads until it is committed). Without ``commit`` (a chunk
      writes the outputs itself: ``simulate_batch``'s rows, each a whole simulation), the
      caller waits, asleep, for the chunks helpers have started (one a helper at most) before
      it returns or raises, a KeyboardInterrupt included.
    - One thread (``threads=1``, ``REDYSIM_THREADS=1``, or a batch of one chunk): a single
      ``call(0, rows, None)`` on the calling thread, and nothing else here runs.
    - Helpers are plain Python threads (daemons named ``redysim-batch-k``, started on first
      need): a chunk gains from them only as far as it releases the GIL, as the compiled kernels
      do. A chunk may run a batch itself: the inner caller works through its own chunks and
      waits for no helper to start. A child made by ``os.fork`` starts helpers of its own.

Under load: about one thread's time (within a few per cent in the note's runs)
    The OS may keep a helper off its core for a time slice (milliseconds) while another process
    runs. The caller does not wait for that (above): a batch with helpers costs at most about
    its time alone plus LATE times a chunk. And each workspace records, kind of batch by kind
    (:class:`Speed`, kept in ``Workspace.batch_speed``), its time a DOF-state alone and with
    helpers: helpers that do not bring a batch under :data:`GAIN` of its time alone are paused
    for 4, 8, ..., 256 batches, then tried again. Measured side by side in one process, quiet,
    beside a busy process and beside one busy half the time (``benchmarks/ab_threads.py`` at
    bcb28b0): docs/notes/2026-12-07-threads.md, which also says what was measured and removed.

Quiet: what it costs
    Where helpers pay, no batch waits for a sleeping thread to wake: after each batch a helper
    watches for the next for :data:`HELPER_SPIN_NS` without sleeping, yielding its core to any
    thread that wants it, and the caller waits for a helper's last chunk the same way, keeping
    its core. Both spin in compiled code without the GIL on a flag read and written atomically
    (:mod:`redysim.algorithms._kernels.spin`); where that primitive is not available they sleep
    instead (``threading``): the same results, slower. Where helpers do not pay, a batch runs
    alone but for three with helpers after each pause and the bookkeeping of its time: a few
    per cent over one thread (64 states in tiles at 250 DOF, in the note).
"""

from __future__ import annotations

import os
import queue
import threading
import time

import numpy as np

from redysim.algorithms._kernels import spin as _spin
from redysim.algorithms.workspace import ALIGN
from redysim.errors import FieldError

CHUNK_WORK = 8000  # DOF x states a chunk of a batch holds at most: a batch under it runs on the
# calling thread alone; smaller chunks cost a batch measurably more than one thread even with no
# helper (benchmarks/busy_batch.py; docs/notes/2026-11-27-threads-under-load.md)
THREADS_VARIABLE = "REDYSIM_THREADS"  # when set, the default thread count (pool workers: 1)
LATE = 1.5  # a helper's chunk is late after LATE x the caller's time for it (+ LATE_S): two
LATE_S = 20e-6  # threads share the caches, and the OS's timers are coarse
HELPER_SPIN_NS = 200_000  # a helper watches this long for the next batch before sleeping
AWAY_NS = 20_000  # a spinning thread kept off its core this long stops (its core is wanted)
GAIN = 0.97  # helpers are kept while a batch with them takes under GAIN of its time alone
REFRESH = 32  # and one batch in REFRESH runs alone, to keep that time fresh
SAMPLES = 7  # batches with helpers whose median is judged
ADAPT = True  # batches measure what helpers buy them (Speed); tests turn it off


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
    if now - _CORES[0] > 1.0:  # (looked at once a second, not at every batch)
        try:
            _CORES[:] = now, len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            _CORES[:] = now, os.cpu_count() or 1
    return int(_CORES[1])


_CORES = [-2.0, 1]  # (when, cores this process may use) of the last look


def thread_count(threads: int | None, chunks: int) -> int:
    """Threads for ``chunks`` chunks of work: ``threads`` (checked), or :func:`default_threads`
    (not read for one chunk, which runs on the caller whatever it says), and no more than there
    are chunks."""
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


class Own:
    """A helper thread's own buffers (scratch, SIMD tile arrays), by size, the last few kept:
    a helper never writes into a workspace or into a batch's outputs, so that one left behind
    by its batch (its chunk taken back by the caller) harms nothing."""

    KEEP = 4

    def __init__(self) -> None:
        self.arrays: dict[int, np.ndarray] = {}

    def get(self, like: np.ndarray) -> np.ndarray:
        """A float64 array of ``like``'s size, zeros when new, on a 64-byte boundary (as
        ``Workspace.tile_buffer``: where the SIMD tiles' arrays lie moves their speed)."""
        a = self.arrays.pop(like.size, None)
        if a is None:
            raw = np.zeros(like.size + ALIGN)  # (zeros: as a workspace's tile arrays start)
            start = (-raw.ctypes.data // 8) % ALIGN
            a = raw[start:start + like.size]
            while len(self.arrays) >= self.KEEP:
                self.arrays.pop(next(iter(self.arrays)))
        self.arrays[like.size] = a  # (the most recent last)
        return a


FREE, CALLER, HELPER, DONE, TAKEN_BACK = range(5)  # a chunk's states


class _Chunks:
    """One batch's chunks (``edges``: chunk i is rows edges[i]..edges[i + 1] - 1), handed out in
    order to whichever thread asks next (:func:`run_blocks`). The Python state is the lock's;
    ``finished`` (helper chunks let go of so far) is the atomic flag a spinning caller watches."""

    __slots__ = ("call", "commit", "edges", "lock", "done", "next", "state", "started",
                 "running", "finished", "values", "results", "errors", "per_row")

    def __init__(self, call, edges: list[int], commit=None):
        self.call = call
        self.commit = commit
        self.edges = edges
        self.lock = threading.Lock()
        self.done = threading.Condition(self.lock)  # notified when a helper lets go of a chunk
        self.next = 0  # the next chunk to hand out
        n = len(edges) - 1
        self.state = [FREE] * n
        self.started = [0.0] * n  # when a helper took the chunk (perf_counter)
        self.running = 0  # chunks helpers run
        self.finished = np.zeros(1, dtype=np.int64)  # (written by _spin.add only)
        self.values: list = [None] * n
        self.results: list = [None] * n  # a helper's chunk's arrays, for commit
        self.errors: dict[int, BaseException] = {}  # chunk -> what it raised
        self.per_row = 0.0  # the caller's seconds a row, from its own chunks

    def _take(self, state: int) -> int:
        with self.lock:
            i = self.next
            if i >= len(self.state) or self.errors:
                return -1
            self.next = i + 1
            self.state[i] = state
            if state == HELPER:
                self.started[i] = time.perf_counter()
                self.running += 1
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

    def help(self, own: Own) -> None:
        """A helper's part: chunks, if any are left, in its own arrays."""
        edges = self.edges
        while (i := self._take(HELPER)) >= 0:
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
                    self.running -= 1
                    self.values[i], self.results[i] = value, result
                    if error is not None:
                        self.errors[i] = error
                self.done.notify_all()
            _spin.add(self.finished, 0, 1)

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
        spin = _spin.ready()
        for i in range(len(self.state)):
            while True:
                seen = _spin.load(self.finished, 0)
                if self.state[i] != HELPER or self.errors:
                    break
                left = self.started[i] + LATE * self.per_row * (
                    edges[i + 1] - edges[i]) + LATE_S - time.perf_counter()
                if left > 0 and spin:  # spin while the helper should be about done
                    clock = np.empty(2, dtype=np.int64) if clock is None else clock
                    _spin.wait_change(self.finished, 0, seen, int(left * 1e9), AWAY_NS, clock,
                                      False)
                    continue  # a helper let go of a chunk, or time to look again
                if left > 0:
                    with self.lock:
                        if self.state[i] == HELPER:
                            self.done.wait(left)
                    continue
                with self.lock:  # late: the chunk is the caller's
                    mine = self.state[i] == HELPER
                    if mine:
                        self.state[i] = TAKEN_BACK
                        self.running -= 1
                if mine:
                    try:
                        self.values[i] = self.call(edges[i], edges[i + 1], None)
                    except BaseException as exc:
                        with self.lock:
                            self.errors[i] = exc
                break
            if self.state[i] == DONE and self.results[i] is not None:
                self.commit(edges[i], edges[i + 1], self.results[i])
                self.results[i] = None

    def _wait(self) -> None:
        """Wait, asleep, for the chunks helpers run (none can start any more): an interrupt
        must not let the caller go while a helper writes the outputs."""
        interrupted = None
        with self.lock:
            while self.running:
                try:
                    self.done.wait()
                except BaseException as exc:  # KeyboardInterrupt: re-raised once they stop
                    interrupted = exc
        if interrupted is not None:
            raise interrupted


class Speed:
    """Seconds a DOF-state for one kind of batch on one workspace (``Workspace.batch_speed``),
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
        batches, every REFRESH-th, and while helpers have not paid), else ``count``."""
        if ADAPT and (self.alone is None or self.skip > 0 or self.since_alone >= REFRESH):
            self.skip = max(0, self.skip - 1)
            return 1
        return count

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


def plan(speeds: dict, key, threads: int | None, chunks: int) -> tuple[int, Speed | None]:
    """(threads, the record to report the batch's time to, or None) for a batch of ``chunks``
    chunks of kind ``key`` on a workspace whose records are ``speeds``."""
    count = thread_count(threads, chunks)
    if count == 1:
        return 1, None
    speed = speeds.get(key)
    if speed is None:
        speed = speeds[key] = Speed()
    return speed.plan(count), speed


# The helpers: plain Python threads, started on first need, that take batches from _JOBS. A
# helper that has finished a batch watches _POSTED (batches posted so far) for the next one for
# HELPER_SPIN_NS without sleeping, unless its core is wanted by another thread (AWAY_NS), then
# sleeps in _JOBS.get().
_JOBS: queue.SimpleQueue = queue.SimpleQueue()  # batches waiting for a helper
_POSTED = np.zeros(1, dtype=np.int64)  # (written by _spin.add only)
_HELPERS: list[threading.Thread] = []
_HELPERS_LOCK = threading.Lock()


def _helper() -> None:
    own, clock, spin = Own(), np.empty(2, dtype=np.int64), _spin.ready()
    while True:
        seen = _spin.load(_POSTED, 0)
        try:
            job = _JOBS.get_nowait()
        except queue.Empty:
            if spin and _spin.wait_change(_POSTED, 0, seen, HELPER_SPIN_NS, AWAY_NS, clock,
                                          True) == 1:
                continue  # a batch was posted: take it
            job = _JOBS.get()
        job.help(own)
        del job  # (not kept alive, with its arrays, until the next batch)


def _after_fork() -> None:  # a forked child has no helper threads: it starts its own
    global _JOBS, _HELPERS_LOCK, _HELPERS
    _JOBS, _HELPERS_LOCK, _HELPERS = queue.SimpleQueue(), threading.Lock(), []


os.register_at_fork(after_in_child=_after_fork)


def run_blocks(rows: int, threads: int | None, call, count: int | None = None,
               chunk: int = 1, edges: list[int] | None = None, commit=None) -> list:
    """call(first, last, own) over the rows in chunks of ``chunk`` rows (or the chunks given by
    ``edges``), on the calling thread (``own`` None) and up to ``count`` - 1 helper threads
    (``count``: :func:`thread_count` of ``threads``; ``own``: the helper's :class:`Own`); the
    chunks' values in row order. With one thread, a single call(0, rows, None). With
    ``commit(first, last, result)``, a helper's call returns (value, result), computed in its own
    arrays, and the caller commits ``result``. The module docstring says what it promises."""
    count = thread_count(threads, rows) if count is None else count
    if count == 1:
        return [call(0, rows, None)]
    if edges is None:
        edges = [*range(0, rows, chunk), rows]
    helpers = min(count, len(edges) - 1) - 1
    job = _Chunks(call, edges, commit)
    if helpers > 0:
        if len(_HELPERS) < helpers:
            _spin.ready()  # (loaded before a helper could take the first chunks meanwhile)
            with _HELPERS_LOCK:
                while len(_HELPERS) < helpers:
                    thread = threading.Thread(target=_helper, daemon=True,
                                              name=f"redysim-batch-{len(_HELPERS) + 1}")
                    _HELPERS.append(thread)
                    thread.start()
        for _ in range(helpers):
            _JOBS.put(job)
        _spin.add(_POSTED, 0, 1)
    job.work()
    return job.finish()
