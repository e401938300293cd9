"""Foreign FMUs run in a child process, so that nothing they do takes sdl-fmu down silently.

An FMU is native code from anyone: in sdl-fmu's own process, a segmentation fault would kill it without a word, an
`exit(0)` would end the run with exit status 0 and nothing written, and a loop inside fmi2DoStep would hold it for
ever, deaf to Ctrl-C (the signal is handled only when the call returns). So an FMU that sdl-fmu did not build runs
in a host process (`sdl_fmu.vehicle.host`), and `IsolatedInstance` stands in for its EgoInstance here (a controller
FMU's IsolatedController, in controller.py, for its ControllerInstance, on the same `Hosted` machinery): the same
methods, each a request over a pipe (about 10 µs; the controls and surfaces set since the last request travel with
the next one). What the host reports or how it ends becomes one FmuError line naming the call and the instant:
"it crashed (SIGSEGV) in fmi2DoStep from t = 1.000000 s to 1.050000 s", "its process ended (exit status 0) ...".
While sdl-fmu waits for an answer, Ctrl-C and SIGTERM are handled at once and the host is killed; a wall-clock
`deadline()` (api.run's timeout) ends the wait too (FmuTimeout). The host ignores Ctrl-C itself and dies with its
parent (PR_SET_PDEATHSIG on Linux), so a hung FMU never outlives sdl-fmu.

Which FMUs: `runs_in_process(fmu)` is true only for an FMU whose bytes are those of an FMU sdl-fmu built into its
FMU cache (the shipped models and the example AEB, also as a sweep ships them to its workers); everything else is
isolated.
SDL_FMU_ISOLATION=always isolates every FMU (the benchmark of the cost, and the test that both ways give identical
results). The decision and the measured cost: docs/decisions.md. A host serves one instance at a time and is kept
for the next instance of the same FMU in the same thread (the vehicle test pack starts dozens), so its start (about
0.3 s: a Python interpreter and fmpy) is paid once per FMU and process."""

from __future__ import annotations

import atexit
import contextlib
import contextvars
import functools
import hashlib
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
import time as wall_clock
from pathlib import Path
from typing import Callable, Union

from .instance import EgoState, FmuError, _make_state

ISOLATION_VARIABLE = "SDL_FMU_ISOLATION"
Where = Union[str, Callable[[], str]]  # the call and instant a message names, or a function giving them
_READ = 1 << 16  # bytes asked of the pipe per read: an answer's length and body at once
CLOSE_GRACE = 10.0  # s: an FMU that does not terminate and free itself within this is killed
START_LIMIT = 120.0  # s for a host to start (an interpreter and fmpy): beyond it, it hangs
_HEADER = struct.Struct("<Q")
_deadline: contextvars.ContextVar[float | None] = contextvars.ContextVar("sdl_fmu_fmu_deadline", default=None)


class FmuTimeout(FmuError):
    """The wall-clock deadline passed while the FMU was working (its host was killed). `subject`: the FMU as the
    message names it (None: the ego FMU, which the caller names)."""

    subject: str | None = None


class HostEnded(FmuError):
    """The host process ended while the FMU was working: a crash (a signal) or an exit of the FMU's."""


@contextlib.contextmanager
def deadline(seconds: float | None):
    """Inside it, waiting for an isolated FMU ends `seconds` of wall clock after entering (FmuTimeout)."""
    token = _deadline.set(None if seconds is None else wall_clock.monotonic() + seconds)
    try:
        yield
    finally:
        _deadline.reset(token)


# ---- which FMUs run in sdl-fmu's process ----------------------------------------------------------------------


@functools.lru_cache(maxsize=64)
def _digest(path: str, mtime: int, size: int) -> str:
    hashed = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            hashed.update(block)
    return hashed.hexdigest()


def _file_digest(path: Path) -> str:
    status = path.stat()
    return _digest(str(path.resolve()), status.st_mtime_ns, status.st_size)


def built_digests(size: int | None = None) -> set[str]:
    """SHA-256 of every FMU sdl-fmu built into its FMU cache (<Model>-fmi<version>-<key>/fmi<version>/<Model>.fmu),
    of those `size` bytes long if given (only those are read)."""
    from ..paths import cache_directory

    digests = set()
    for path in cache_directory().glob("*-fmi*-*/fmi*/*.fmu"):
        try:
            if size is None or path.stat().st_size == size:
                digests.add(_file_digest(path))
        except OSError:
            continue
    return digests


def runs_in_process(fmu: str | os.PathLike) -> bool:
    """Whether this FMU may run in sdl-fmu's own process: one that sdl-fmu built (see the module)."""
    if os.environ.get(ISOLATION_VARIABLE, "auto") == "always":
        return False
    try:
        path = Path(fmu)
        return _file_digest(path) in built_digests(path.stat().st_size)
    except OSError:
        return False


# ---- the host, as seen from here --------------------------------------------------------------------------------


class _Host:
    """One host process and its two pipes."""

    def __init__(self):
        requests, self._requests = os.pipe()
        self._replies, replies = os.pipe()
        root = str(Path(__file__).resolve().parents[2])  # the folder holding this sdl_fmu
        code = f"import sys; sys.path.insert(0, {root!r}); from sdl_fmu.vehicle.host import main; main()"
        try:
            self.process = subprocess.Popen([sys.executable, "-c", code, str(requests), str(replies)],
                                            pass_fds=(requests, replies), stdin=subprocess.DEVNULL,
                                            stdout=_stderr_fd(), close_fds=True)
        finally:
            os.close(requests)
            os.close(replies)
        self.busy = False
        self.thread = threading.get_ident()

    def call(self, request: tuple, where: Where, limit: float | None = None):
        """Sends a request and waits for its answer; FmuError for the FMU's own refusal, for the host's end, and
        FmuTimeout past the deadline (`limit` s from now, or the context's deadline). `where` names the call and the
        instant in those messages (a function giving the text: formatted only for a message)."""
        self.busy = True
        data = pickle.dumps(request, protocol=pickle.HIGHEST_PROTOCOL)
        try:
            view = memoryview(_HEADER.pack(len(data)) + data)
            while view:
                view = view[os.write(self._requests, view):]
        except (BrokenPipeError, OSError):
            self._ended(where)
        end = _deadline.get()
        if limit is not None:
            end = wall_clock.monotonic() + limit if end is None else min(end, wall_clock.monotonic() + limit)
        status, value = pickle.loads(self._answer(where, end))
        self.busy = False
        if status == "error":
            raise FmuError(value)
        return value

    def _answer(self, where: Where, end: float | None) -> bytes:
        """The answer's body. Its length and body come in one read where the pipe holds both (the host writes them
        at once), so an answer usually costs one wait and one read; only one request is ever outstanding, so a read
        never takes part of the next answer."""
        buffer, size = b"", None
        while size is None or len(buffer) < _HEADER.size + size:
            if end is not None:
                remaining = end - wall_clock.monotonic()
                if remaining <= 0 or not select.select([self._replies], [], [], remaining)[0]:
                    if wall_clock.monotonic() >= end:
                        self.kill()
                        raise FmuTimeout(f"did not answer {_text(where)} before the wall-clock limit (its process "
                                         "was ended)")
                    continue
            chunk = os.read(self._replies, _READ)
            if not chunk:
                self._ended(where)
            buffer += chunk
            if size is None and len(buffer) >= _HEADER.size:
                size, = _HEADER.unpack_from(buffer)
        return buffer[_HEADER.size:]

    def _ended(self, where: Where):
        """The host is gone: how it ended, as one FmuError."""
        where = _text(where)
        try:
            code = self.process.wait(timeout=CLOSE_GRACE)
        except subprocess.TimeoutExpired:
            self.kill()
            code = self.process.returncode
        self.kill()
        if code is not None and code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            raise HostEnded(f"it crashed ({name}) {where}")
        raise HostEnded(f"its process ended (exit status {code}) {where}; an FMU must not end the process it runs in")

    @property
    def alive(self) -> bool:
        return self.process.poll() is None and not self.busy

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        try:
            self.process.wait(timeout=CLOSE_GRACE)
        except subprocess.TimeoutExpired:
            pass
        for fd in (self._requests, self._replies):
            try:
                os.close(fd)
            except OSError:
                pass
        self._requests = self._replies = -1
        self.busy = False


def _text(where: Where) -> str:
    return where if isinstance(where, str) else where()


def _stderr_fd() -> int:
    """What the host's standard output goes to: sdl-fmu's stderr (an FMU's own prints never mix with the command's
    output on stdout)."""
    try:
        return sys.__stderr__.fileno()
    except (AttributeError, ValueError, OSError):
        return subprocess.DEVNULL


_idle: dict[tuple, list[_Host]] = {}  # (thread, FMU) -> hosts with no instance, kept for the next one
_idle_lock = threading.Lock()


def _host_for(key: tuple) -> _Host:
    with _idle_lock:
        hosts = _idle.get(key, [])
        while hosts:
            host = hosts.pop()
            if host.alive:
                return host
            host.kill()
    return _Host()


def _release(key: tuple, host: _Host) -> None:
    with _idle_lock:
        _idle.setdefault(key, []).append(host)


@atexit.register
def _end_hosts() -> None:
    with _idle_lock:
        for hosts in _idle.values():
            for host in hosts:
                host.kill()
        _idle.clear()


# ---- an instance in a host --------------------------------------------------------------------------------------


class Hosted:
    """What every instance in a host does (the vehicle's IsolatedInstance, the controller's IsolatedController in
    controller.py): take a host for its FMU (a kept one, or a new one), open the instance there, send requests, and
    close it, the host then kept for the next instance. `opened(value)` takes the open request's answer."""

    def _open(self, model, request: tuple) -> object:
        """Unpacks the FMU here (once per process; the host uses the folder) and sends the open request `request`
        (its kind, then its arguments; the model pickled and the folder are put first); returns the answer."""
        from .unpack import UnpackError

        self._prefix = "fmi3" if model.fmi_version == "3.0" else "fmi2"
        self._host = None
        try:
            folder = model.unzipped()
        except UnpackError as error:
            raise self._error(str(error)) from None
        self._key = (threading.get_ident(), str(Path(model.fmu_path).resolve()))
        try:
            self._host = _host_for(self._key)
        except OSError as error:
            raise self._error(f"its host process cannot be started: {error.strerror or error}") from None
        kind, *arguments = request
        try:
            return self._host.call((kind, pickle.dumps(model), str(folder), *arguments),
                                   "while it was instantiated and initialised", limit=START_LIMIT)
        except BaseException:
            self._host.kill()
            self._host = None
            raise

    def _error(self, text: str) -> FmuError:
        """The error of a failure before the FMU was opened (its unpack, its host's start)."""
        return FmuError(text)

    def _send(self, request: tuple, where: Where):
        if self._host is None:
            raise FmuError("the instance is closed")
        return self._host.call(request, where)

    def close(self) -> None:
        """Terminates and frees the FMU in its host (killed if it is stuck, crashed or was interrupted mid-call),
        which is then kept for the next instance."""
        host, self._host = getattr(self, "_host", None), None
        if host is None:
            return
        if not host.alive:
            host.kill()
            return
        try:
            host.call(("close", None, None, None), "while it was terminated and freed", limit=CLOSE_GRACE)
        except Exception:  # noqa: BLE001 - a close that fails must not hide what ended the run: the host goes
            host.kill()
            return
        except BaseException:
            host.kill()
            raise
        _release(self._key, host)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class IsolatedInstance(Hosted):
    """An EgoInstance in a host process (see the module): read, step_to, step, set_controls, set_friction, save,
    restore, discard, close, `time`, `warnings`."""

    def __init__(self, model, start: dict[str, float], parameters: dict[str, float], instance_name: str = "ego"):
        self.model = model
        self.time = 0.0
        self._controls = self._friction = None
        self.warnings, state = self._open(model, ("open", dict(start), dict(parameters), instance_name))
        self._state = _make_state(state)

    def _call(self, kind: str, where: Where, argument=None):
        request = (kind, self._controls, self._friction, argument)
        self._controls = self._friction = None
        return self._send(request, where)

    # ---- what the master and the test pack ask ----------------------------------------------------------------

    def read(self) -> EgoState:
        if self._controls is not None or self._friction is not None:
            self._state = _make_state(self._call("read", f"while its outputs were read at t = {self.time:.6f} s"))
        return self._state

    def step_to(self, end: float) -> None:
        start = self.time
        self._state = _make_state(self._call("step", lambda: f"in {self._prefix}DoStep from t = {start:.6f} s to "
                                                             f"{end:.6f} s", end))
        self.time = end

    def step(self, h: float) -> None:
        self.step_to(self.time + h)

    def set_controls(self, throttle: float, brake: float, steer: float) -> None:
        self._controls = (throttle, brake, steer)

    def set_friction(self, values) -> None:
        self._friction = tuple(values)

    def save(self):
        return self._call("save", f"in {self._prefix}GetFMUstate at t = {self.time:.6f} s"), self.time

    def restore(self, snapshot) -> None:
        number, time = snapshot
        self._state = _make_state(self._call("restore", f"in {self._prefix}SetFMUstate to t = {time:.6f} s",
                                             number))
        self.time = time

    def discard(self, snapshot) -> None:
        self._call("discard", f"in {self._prefix}FreeFMUstate at t = {self.time:.6f} s", snapshot[0])
