"""The host process of an isolated FMU (sdl_fmu.vehicle.isolated): one instance at a time (an EgoInstance or a
ControllerInstance), driven by requests on a pipe, each answered on another.

A request is (kind, controls, friction, argument), pickled behind an 8-byte length: the controls and surfaces set
since the last request are applied first, then `kind`: open (argument-less; the request carries the pickled
EgoModel, the unpacked folder, start and parameter values), read, step (to the time `argument`), save, restore and
discard (a snapshot number), close; for a controller (vehicle/controller.py) open-controller (the pickled
ControllerModel, the folder, the instance name) and sample (`argument`: k and the input signals by name; the answer:
the Request as a tuple). The answer is ("ok", value) or ("error", the FmuError's text). The host ignores
Ctrl-C (sdl-fmu decides), dies with its parent (Linux: PR_SET_PDEATHSIG), and ends when the request pipe closes.
The FMU's own prints (its stdout) go to sdl-fmu's stderr; its log messages too (fmu_log)."""

from __future__ import annotations

import os
import pickle
import signal
import struct
import sys

_HEADER = struct.Struct("<Q")
_READ = 1 << 16  # bytes asked of the pipe per read


def _die_with_parent() -> None:
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() == 1:  # the parent is already gone
        os._exit(1)


def _requests(fd: int):
    """The requests' bodies as they come, until the pipe closes. A read takes what the pipe holds (a request's length
    and body, written at once, come in one read); only one request is outstanding at a time."""
    buffer = b""
    while True:
        end = None
        while end is None or len(buffer) < end:
            chunk = os.read(fd, _READ)
            if not chunk:
                return
            buffer += chunk
            if end is None and len(buffer) >= _HEADER.size:
                end = _HEADER.size + _HEADER.unpack_from(buffer)[0]
        yield buffer[_HEADER.size:end]
        buffer = buffer[end:]


def _write(fd: int, reply) -> None:
    data = pickle.dumps(reply, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view):]


def _first_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text.splitlines()[0]


def serve(requests: int, replies: int) -> None:
    """Answers each request on `requests` on `replies` (see the module) until the request pipe closes."""
    from .instance import EgoInstance, FmuError
    from .unpack import adopt

    instance, snapshots, count = None, {}, 0
    for body in _requests(requests):
        request = pickle.loads(body)
        kind = request[0]
        try:
            if kind == "open":
                _, model, folder, start, parameters, name = request
                model = pickle.loads(model)
                adopt(model.fmu_path, folder)
                instance, snapshots = EgoInstance(model, start, parameters, name), {}
                value = (instance.warnings, tuple(instance.read()))
            elif kind == "open-controller":
                from .controller import ControllerInstance

                _, model, folder, name = request
                model = pickle.loads(model)
                adopt(model.fmu_path, folder)
                instance, snapshots = ControllerInstance(model, name), {}
                value = None
            else:
                _, controls, friction, argument = request
                if instance is None:
                    raise FmuError("no instance")
                if controls is not None:
                    instance.set_controls(*controls)
                if friction is not None:
                    instance.set_friction(friction)
                value = None
                if kind == "sample":  # a controller's sample: (k, its input signals by name)
                    value = tuple(instance.sample(*argument))
                elif kind == "step":
                    instance.step_to(argument)
                    value = tuple(instance.read())
                elif kind == "read":
                    value = tuple(instance.read())
                elif kind == "save":
                    count += 1
                    snapshots[count] = instance.save()
                    value = count
                elif kind == "restore":
                    instance.restore(snapshots[argument])
                    value = tuple(instance.read())
                elif kind == "discard":
                    instance.discard(snapshots.pop(argument))
                elif kind == "close":
                    instance.close()
                    instance, snapshots = None, {}
                else:
                    raise FmuError(f"unknown request {kind!r}")
            reply = ("ok", value)
        except FmuError as error:
            reply = ("error", _first_line(error))
        except Exception as error:  # noqa: BLE001 - whatever the FMU's call raised is the answer
            reply = ("error", f"{type(error).__name__}: {_first_line(error)}")
        _write(replies, reply)


def main() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    requests, replies = int(sys.argv[1]), int(sys.argv[2])
    try:
        serve(requests, replies)
    except BrokenPipeError:
        pass
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)  # no exit handlers: an FMU's own (a Python interpreter inside it, say) cannot fail the exit
