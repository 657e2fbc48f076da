"""The processes of one distributed bake, and how they join, agree, wait for each other and leave.

Why this module exists: JAX's C++ client ends the process with SIGABRT and a C++ stack trace whenever its
coordination agent meets an error (a peer that never registers, a coordinator that goes away, a process id
registered twice), and its shutdown barrier waits minutes for a peer that is gone.  A bake must instead end
each of these as one hairlut error that names this process, the peer and the cause, and keep its finished
parts for a rerun.  So a :class:`Session` goes through JAX's coordination service (``jax.distributed``) like
this:

- before JAX starts, what can be checked is: process 0's port must be free (a second process 0 would bind it
  too, through gRPC's ``SO_REUSEPORT``), and the others wait up to ``timeout_s`` for the coordinator to answer;
- it joins in JAX's *recoverable* mode (``jax_enable_recoverability``): the service then does not broadcast
  one process's loss to the others as a fatal error, and a second process under a taken id is let in, so
  that hairlut's own claim (one key-value entry per process id) can name it.  The preemption service is off:
  it would swallow SIGTERM, and a bake resumes from its parts instead;
- it agrees with every peer before any work (:meth:`Session.agree`): the process count when joining, and the
  recipe, ``--out`` and blocks when a bake starts; a difference is refused at once, naming it;
- it waits on key-value entries in short slices (:meth:`Session.barrier`), watching each awaited peer's
  heartbeat (a counter that this module's thread sets every few seconds) and failure notices: a dead peer is
  named after ``timeout_s`` without a beat, a failed one at once, with its own message;
- it leaves explicitly (:meth:`Session.leave`): a failing process posts its message for the others; process
  0, which hosts the service, shuts it down only after the others have disconnected;
- what stays fatal in JAX's client (a coordinator process that dies: the others' error poll aborts them at
  once; a join that times out) is caught as SIGABRT by a C-level handler (ctypes) that calls ``on_fatal``
  with the reason: the command line prints its one line there and exits with status 2 on its own.  While
  joining, JAX's log is held back, so that a failed join shows hairlut's line alone.

The library itself neither prints nor exits: without ``on_fatal`` no handler is installed.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import json
import math
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from dataclasses import dataclass

from .. import errors

#: Seconds a process waits for a peer that has not come, or that has stopped answering (``--timeout``).
TIMEOUT_S = 120

_ROOT = "hairlut"
_HANDLER = ctypes.CFUNCTYPE(None, ctypes.c_int)
_session: Session | None = None


@dataclass(frozen=True)
class Process:
    """This process's place in a (possibly one-process) bake."""

    index: int = 0
    count: int = 1

    @property
    def leader(self) -> bool:
        return self.index == 0


def active() -> Session | None:
    """The session this process joined through :func:`join`, if any."""
    return _session


def _status(exc: BaseException) -> str:
    """The gRPC status that starts a JAX runtime error's text (``DEADLINE_EXCEEDED``, ``NOT_FOUND``, ...)."""
    return str(exc).strip().split(":", 1)[0].strip()


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _host_port(address: str) -> tuple[str, int]:
    host, _, port = str(address).rpartition(":")
    return host.strip("[]"), int(port)


def _answers(address: str, wait_s: float = 1.0) -> bool:
    """Whether something accepts TCP connections at ``address`` (the coordinator's gRPC port)."""
    try:
        with socket.create_connection(_host_port(address), timeout=wait_s):
            return True
    except OSError:
        return False


#: A line JAX's service logs on every start in recoverable mode, which a user of hairlut can do nothing about.
_NOISE = b"recoverable task feature"


@contextlib.contextmanager
def _held_stderr(session: Session):
    """Hold file descriptor 2 (JAX's C++ log) in a temporary file while JAX joins, then pass it on without
    :data:`_NOISE`.  If JAX aborts the join instead, the handler gives the descriptor back and drops the hold:
    hairlut's line says what happened, without the C++ stack trace."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        session.held_stderr = saved
        try:
            yield
        finally:
            session.held_stderr = None
            os.dup2(saved, 2)
            os.close(saved)
            held.seek(0)
            kept = b"".join(line for line in held.read().splitlines(keepends=True) if _NOISE not in line)
            if kept:
                os.write(2, kept)


class Session:
    """This process among its peers: see the module docstring."""

    def __init__(self, proc: Process, coordinator, timeout_s: float, on_fatal=None):
        self.proc, self.coordinator, self.timeout_s, self.on_fatal = proc, coordinator, float(timeout_s), on_fatal
        self.client = None
        self.phase = "joining"  # joining → running → closing: what a fatal abort means (see _fatal_reason)
        self.started = time.monotonic()
        self._verdict: str | None = None  # the failure this process is leaving with
        self._uses: dict[str, int] = {}
        self._stop = threading.Event()
        self._beats: threading.Thread | None = None
        self._left = False
        self._handler = self._libc = self._previous = None
        self.held_stderr: int | None = None  # the real stderr while JAX joins (see _held_stderr)
        self._slice = min(5.0, max(0.25, self.timeout_s / 4))  # heartbeat period and wait slice, seconds

    # ------------------------------------------------------------------ naming
    def error(self, cause: str) -> errors.DistributedError:
        return errors.DistributedError(self.proc.index, self.proc.count, cause)

    def lost(self, exc: BaseException) -> errors.DistributedError:
        """An RPC to the coordination service failed (other than a wait running out)."""
        if self.proc.leader:
            return self.error(f"the coordination service failed: {_first_line(exc)}")
        return self.error(f"lost the coordinator, process 0 at {self.coordinator}: {_first_line(exc)}")

    def _peers(self) -> list[int]:
        return [j for j in range(self.proc.count) if j != self.proc.index]

    def _key(self, kind: str, name: str = "") -> str:
        """A fresh key prefix for the n-th use of (kind, name) in this session: the same on every process."""
        tag = f"{kind}/{name}"
        self._uses[tag] = self._uses.get(tag, 0) + 1
        return f"{_ROOT}/{tag}/{self._uses[tag]}"

    # ------------------------------------------------------------------ key-value store
    def _set(self, key: str, value: str) -> None:
        try:
            self.client.key_value_set(key, value, allow_overwrite=True)
        except Exception as exc:
            raise self.lost(exc) from None

    def _try_get(self, key: str) -> str | None:
        try:
            return self.client.key_value_try_get(key)
        except Exception as exc:
            if _status(exc) == "NOT_FOUND":
                return None
            raise self.lost(exc) from None

    def _check_failures(self) -> None:
        """Raise if another process has posted that it failed."""
        try:
            posted = self.client.key_value_dir_get(f"{_ROOT}/failed/")
        except Exception as exc:
            raise self.lost(exc) from None
        for key, message in sorted(posted):
            peer = int(key.rsplit("/", 1)[1])  # this process's own id: a second process under it posted
            raise self.error(message if peer == self.proc.index else f"process {peer} failed: {message}")

    def _await(self, key: str, peer: int, what: str, limit_s: float | None = None) -> str:
        """The value of ``key``, which ``peer`` sets; raises once the peer fails, stops beating for
        ``timeout_s``, or ``limit_s`` passes."""
        start = last = time.monotonic()
        beat = None
        while True:
            try:
                return self.client.blocking_key_value_get(key, int(self._slice * 1000))
            except Exception as exc:
                if _status(exc) != "DEADLINE_EXCEEDED":
                    raise self.lost(exc) from None
            self._check_failures()
            now = time.monotonic()
            seen = self._try_get(f"{_ROOT}/beat/{peer}")
            if seen != beat:
                beat, last = seen, now
            elif now - last >= self.timeout_s:
                raise self.error(
                    f"process {peer} stopped answering while this one waited for it ({what}): no "
                    f"heartbeat for {self.timeout_s:g} s (--timeout); it died, was killed or hangs. "
                    "Finished parts are kept: run every process again to resume"
                )
            if limit_s is not None and now - start >= limit_s:
                raise self.error(f"waited {limit_s:g} s for process {peer} ({what})")

    def _beat(self) -> None:
        count = 0
        while not self._stop.wait(self._slice):
            count += 1
            try:
                self.client.key_value_set(f"{_ROOT}/beat/{self.proc.index}", str(count), allow_overwrite=True)
            except Exception:
                return  # the coordinator is gone: the waits name it, or JAX's client stops the process

    # ------------------------------------------------------------------ the protocol
    def check_port_free(self) -> None:
        """Process 0 binds ``[::]:PORT`` (JAX's default); refuse now if something listens there already."""
        port = _host_port(self.coordinator)[1]
        for family, host in ((socket.AF_INET6, "::"), (socket.AF_INET, "0.0.0.0")):
            try:
                probe = socket.socket(family, socket.SOCK_STREAM)
            except OSError:
                continue  # no IPv6 on this host: try IPv4
            with probe:
                probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # connections in TIME_WAIT do not count
                try:
                    probe.bind((host, port))
                except OSError as exc:
                    raise self.error(
                        f"the coordinator's port {port} is in use on this host ({exc.strerror}): "
                        "another process 0 (a repeated --process-id 0) or another program holds it; "
                        "pick a free port for --coordinator"
                    ) from None
            return

    def await_coordinator(self) -> None:
        """A process other than 0: wait up to ``timeout_s`` for the coordinator's port to answer."""
        while not _answers(self.coordinator):
            if time.monotonic() - self.started >= self.timeout_s:
                raise self.error(
                    f"no coordinator answered at {self.coordinator} within {self.timeout_s:g} s "
                    "(--timeout): start process 0 (it hosts the coordinator) with --coordinator "
                    f"{self.coordinator} --num-processes {self.proc.count}"
                )
            time.sleep(0.25)

    def claim(self) -> None:
        """Take this process id in the key-value store.  A second process under a taken id is refused; JAX's
        runtime has let it replace the first one's registration, so the bake stops (its failure notice, under
        that id, tells every process why)."""
        me = {"host": socket.gethostname(), "pid": os.getpid()}
        try:
            self.client.key_value_set(f"{_ROOT}/process/{self.proc.index}", json.dumps(me))
        except Exception as exc:
            if _status(exc) != "ALREADY_EXISTS":
                raise self.lost(exc) from None
            first = json.loads(self._try_get(f"{_ROOT}/process/{self.proc.index}") or "{}")
            raise self.error(
                f"process {self.proc.index} was started twice: pid {first.get('pid')} on "
                f"{first.get('host')} joined first, pid {me['pid']} on {me['host']} second, and JAX's "
                "runtime keeps one process per id: run the bake again with each --process-id from 0 to "
                f"{self.proc.count - 1} once"
            ) from None
        self._beats = threading.Thread(target=self._beat, name="hairlut-heartbeat", daemon=True)
        self._beats.start()

    def agree(self, fields: dict, recipe: dict | None = None) -> None:
        """Every process must give the same ``fields`` (and ``recipe``); refuse the first difference with a peer,
        naming the field and both values (for a recipe, the keys that differ)."""
        key = self._key("agree")
        self._set(f"{key}/{self.proc.index}", json.dumps({"fields": fields, "recipe": recipe}, default=str))
        for peer in self._peers():  # process 0 first: a peer counting other processes is found before waiting
            theirs = json.loads(self._await(f"{key}/{peer}", peer, "agreeing on the bake"))
            for name, mine in json.loads(json.dumps(fields, default=str)).items():
                if theirs["fields"].get(name) != mine:
                    raise self.error(_difference(name, mine, theirs["fields"].get(name), peer, recipe, theirs.get("recipe")))

    def barrier(self, name: str, limit_s: float | None = None) -> None:
        """Wait until every process has reached ``name`` (see :meth:`_await` for what ends the wait)."""
        key = self._key("at", name)
        self._set(f"{key}/{self.proc.index}", "")
        for peer in self._peers():
            self._await(f"{key}/{peer}", peer, f"at {name}", limit_s)
        self._check_failures()  # a failure posted while every key came in time (a process id given twice)

    def leave(self, exc: BaseException | None = None) -> None:
        """Leave the bake: post ``exc`` (the failure) for the others, stop the heartbeat, and shut JAX's client
        down; process 0 also the service, once the others have disconnected (at most ``timeout_s`` later, 5 s
        after a failure).  Idempotent; errors of a gone peer are ignored."""
        global _session
        if self._left:
            return
        self._left = True
        if exc is not None:
            self._verdict = str(exc) or type(exc).__name__
            cause = exc.cause if isinstance(exc, errors.DistributedError) else self._verdict
            if self.client is not None:
                with contextlib.suppress(Exception):
                    self.client.key_value_set(f"{_ROOT}/failed/{self.proc.index}", cause.splitlines()[0], allow_overwrite=True)
        self.phase = "closing"
        self._stop.set()
        if self._beats is not None:
            self._beats.join(timeout=2 * self._slice)
        if self.proc.leader and self.client is not None:
            self._await_disconnects(min(self.timeout_s, 5.0) if exc is not None else self.timeout_s)
        from jax._src import distributed as jax_distributed

        state = jax_distributed.global_state
        for part in ("client", "service"):
            obj = getattr(state, part)
            setattr(state, part, None)
            if obj is not None:
                with contextlib.suppress(Exception):
                    obj.shutdown()
        self.disarm()
        _session = None

    def _await_disconnects(self, limit_s: float) -> None:
        """Process 0: wait (at most ``limit_s``) until every other process has shut its client down, so that
        stopping the service does not pull it from under one (their error poll would abort them)."""
        done = threading.Thread(target=self._live_nodes, daemon=True)
        done.start()
        done.join(timeout=limit_s)

    def _live_nodes(self) -> None:
        with contextlib.suppress(Exception):  # returns once every other process has left (or is declared dead)
            self.client.get_live_nodes(list(range(self.proc.count)))

    # ------------------------------------------------------------------ JAX's fatal paths
    def arm(self) -> None:
        """Catch JAX's abort (SIGABRT) in a C-level handler that reports through ``on_fatal``."""
        if self.on_fatal is None:
            return
        try:
            libc = ctypes.CDLL(None)
            libc.signal.restype = ctypes.c_void_p
            libc.signal.argtypes = (ctypes.c_int, ctypes.c_void_p)
        except (OSError, AttributeError):
            return  # no C signal(): JAX's abort stays as it is
        self._handler, self._libc = _HANDLER(self._on_abort), libc
        self._previous = libc.signal(signal.SIGABRT, ctypes.cast(self._handler, ctypes.c_void_p))

    def disarm(self) -> None:
        if self._handler is not None:
            self._libc.signal(signal.SIGABRT, self._previous)
            self._handler = None

    @property
    def armed(self) -> bool:
        return self._handler is not None

    def _on_abort(self, signum: int) -> None:
        if self.held_stderr is not None:
            os.dup2(self.held_stderr, 2)
        try:  # leaving after a failure: that failure is the message
            message = self._verdict or self._fatal_message()
        except BaseException:  # the handler must reach on_fatal whatever happens
            message = str(self.error("JAX's distributed runtime stopped this process (see its log above)"))
        self.on_fatal(message)

    def _fatal_message(self) -> str | None:
        reason = self._fatal_reason()
        return None if reason is None else str(self.error(reason))

    def _fatal_reason(self) -> str | None:
        """Why JAX's client aborted, from what this process was doing (the C++ log above has JAX's words).
        No call to the coordination service here: with the coordinator gone, one waits forever."""
        if self.phase == "closing":
            return None  # the bake is complete: the coordinator went away while this process shut down
        address, n = self.coordinator or "the detected coordinator", self.proc.count
        if self.phase == "joining":
            if self.proc.leader:
                missing = "process 1" if n == 2 else f"one or more of processes 1 to {n - 1}"
                return (
                    f"{missing} did not join the coordinator at {address} within {self.timeout_s:g} s "
                    f"(--timeout): start every process with --coordinator {address} --num-processes {n} and "
                    "its own --process-id"
                )
            if not _answers(address):
                return f"the coordinator at {address} (process 0) went away while this process joined"
            if time.monotonic() - self.started < self.timeout_s / 2:
                return (
                    f"the coordinator at {address} refused this process: does process 0 run with "
                    f"--num-processes {n}? Every process needs the same"
                )
            return f"not every process joined the coordinator at {address} within {self.timeout_s:g} s (--timeout)"
        if not self.proc.leader and not _answers(address):
            return (
                f"lost the coordinator: process 0 at {address} is gone (it failed, exited or was killed; see "
                "its own message). Finished parts are kept: run every process again to resume"
            )
        return "JAX's distributed runtime stopped this process (see its log above)"


def _difference(name: str, mine, theirs, peer: int, recipe: dict | None, other: dict | None) -> str:
    """One line for a field on which this process and ``peer`` differ."""
    if theirs is None:
        return f"process {peer} does not say its {name}: is it another hairlut version?"
    keys = _leaf_differences(recipe, other) if recipe is not None and other is not None else []
    if keys:
        shown = "; ".join(
            f"{k} = {json.dumps(a, default=str)} here, {json.dumps(b, default=str)} at process {peer}" for k, a, b in keys[:3]
        )
        more = f" (and {len(keys) - 3} more)" if len(keys) > 3 else ""
        return f"process {peer} bakes another recipe: {shown}{more}; every process needs the same recipe"
    return f"{name} is {mine} here and {theirs} at process {peer}: every process needs the same {name}"


def _leaf_differences(a, b, where: str = "") -> list[tuple[str, object, object]]:
    """(dotted key, value here, value there) of every leaf on which two recipes differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b), key=str):
            out += _leaf_differences(a.get(k), b.get(k), f"{where}{k}.")
        return out
    return [] if a == b else [(where.rstrip("."), a, b)]


def join(coordinator=None, num_processes=None, process_id=None, timeout_s: float = TIMEOUT_S, on_fatal=None) -> Session | None:
    """Join JAX's distributed runtime as one process of a bake (once per process); None where something else
    initialised ``jax.distributed`` already.  ``coordinator`` None: JAX detects the cluster (SLURM, Open MPI)."""
    global _session
    import jax

    if _session is not None:
        return _session
    if jax.distributed.is_initialized():
        return None
    if isinstance(timeout_s, bool) or not isinstance(timeout_s, int | float) or not 1 <= timeout_s < math.inf:
        raise errors.ValidationError("timeout", timeout_s, "seconds, a number ≥ 1")
    proc = Process(int(process_id or 0), int(num_processes or 1))
    session = Session(proc, coordinator, timeout_s, on_fatal)
    if coordinator is not None:
        session.check_port_free() if proc.leader else session.await_coordinator()
    jax.config.update("jax_enable_recoverability", True)
    jax.config.update("jax_enable_preemption_service", False)
    kwargs = (
        {}
        if coordinator is None
        else {"coordinator_address": str(coordinator), "num_processes": proc.count, "process_id": proc.index}
    )
    left = max(1, math.ceil(session.timeout_s - (time.monotonic() - session.started)))
    whole = max(1, math.ceil(session.timeout_s))
    session.arm()
    try:
        with _held_stderr(session) if session.armed else contextlib.nullcontext():
            jax.distributed.initialize(
                **kwargs, initialization_timeout=left, heartbeat_timeout_seconds=whole, shutdown_timeout_seconds=whole
            )
    except (RuntimeError, ValueError, TypeError) as exc:
        session.disarm()
        raise errors.ValidationError(
            "distributed", coordinator or "auto-detect", f"jax.distributed.initialize failed: {_first_line(exc)}"
        ) from None
    from jax._src import distributed as jax_distributed

    state = jax_distributed.global_state
    session.proc = Process(int(state.process_id), int(state.num_processes))
    session.coordinator, session.client = state.coordinator_address, state.client
    _session = session
    atexit.register(session.leave)  # runs before JAX's own shutdown (registered earlier, called later)
    try:
        session.claim()
        session.agree({"--num-processes": session.proc.count})
        try:
            jax.local_devices()  # the backends' start-up exchanges each process's devices through the service
        except RuntimeError as exc:
            raise session.error(f"JAX's backend did not start: {_first_line(exc)}") from None
    except BaseException as exc:
        session.leave(exc)
        raise
    session.phase = "running"
    return session
