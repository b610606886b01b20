"""A client of a serving executive (``tdl serve``; docs/distributed.md, "A serving executive").

It does what ``tdl load``, ``tdl start``, ``tdl stop``, ``tdl raise``, ``tdl status``, ``tdl
programs`` and ``tdl unload`` do, from Python, with the protocol of
``crates/tdl-serve/src/proto.rs``: each request is one zenoh query on
``tdl/<system>/serve/<executive>/<client>`` whose payload is the request as JSON, answered by one
reply whose payload is ``{"ok": <reply>}`` or ``{"refused": "<why>"}``. The last key segment is
the client's name, which the executive records as who asked (the ``by`` of the run's ``control``
records).

    import tdl_agent

    with tdl_agent.Client("tdl", "planner", port=7447) as c:
        try:
            c.load("watch", ["watch.tdl"])
        except tdl_agent.Refused as e:
            print(e.reason)              # the located diagnostics, as `tdl check` prints them
            raise
        run = c.start("watch")
        c.raise_event(run, "door_open")
        c.stop(run)
        print(c.status(run))             # [{"run": 1, "running": False, "outcome": ..., ...}]

A refused request raises :class:`Refused` (nothing changed at the executive); no answer within
the timeout raises :class:`NoAnswer`; an answer that does not read raises
:class:`ProtocolError`. All three derive from :class:`ClientError`.

The functions :func:`load_request` (and the other ``*_request``) and :func:`decode_response`
build and read the messages without a network.
"""

from __future__ import annotations

import json
import os
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from . import wire

__all__ = [
    "Client",
    "ClientError",
    "Refused",
    "NoAnswer",
    "ProtocolError",
    "serve_key",
    "swap_of",
    "files_of",
    "load_request",
    "unload_request",
    "list_request",
    "start_request",
    "stop_request",
    "raise_request",
    "status_request",
    "decode_response",
]

#: How long a client waits for an answer by default, in seconds (as ``tdl_serve::DEFAULT_TIMEOUT``).
DEFAULT_TIMEOUT = 10.0

#: A program's files as :meth:`Client.load` takes them: a path, or a ``(name, text)`` pair (a
#: tuple), or a list of these.
File = Union[str, "os.PathLike[str]", Tuple[str, str]]
Files = Union[File, Sequence[File]]

#: When runs take a new version: ``"spawns"``, ``"now"``, ``("after", task)`` or ``"after:TASK"``.
SwapSpec = Union[str, Tuple[str, str]]


class ClientError(Exception):
    """What a request to a serving executive can fail with."""


class Refused(ClientError):
    """The executive refused the request; nothing changed there. ``reason`` is its reason, with a
    program's located diagnostics (``file:line:column``) when it was refused for them."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class NoAnswer(ClientError):
    """No executive answered within the timeout (asked twice, as the Rust client does)."""

    def __init__(self, executive: str, system: str, waited: float) -> None:
        super().__init__(
            f"no executive `{executive}` of system `{system}` answered within {waited:g} s: "
            "is `tdl serve` running there, and may this client speak to it?"
        )
        self.executive = executive
        self.system = system
        self.waited = waited


class ProtocolError(ClientError):
    """An answer that does not read, or not the kind of answer the request asks for."""


# --- the messages (no network) ------------------------------------------------------------------


def serve_key(system: str, executive: str, client: str) -> str:
    """The key a request of ``client`` to ``executive`` is a query on (``proto::key``)."""
    return f"tdl/{system}/serve/{executive}/{client}"


def swap_of(swap: SwapSpec) -> Dict[str, str]:
    """The JSON of a swap (``proto::Swap``): ``"spawns"``, ``"now"``, ``("after", task)`` or
    ``"after:TASK"``."""
    if swap in ("spawns", "now"):
        return {"at": str(swap)}
    if isinstance(swap, str) and swap.startswith("after:") and len(swap) > len("after:"):
        return {"at": "after", "task": swap[len("after:"):]}
    if isinstance(swap, tuple) and len(swap) == 2 and swap[0] == "after" and swap[1]:
        return {"at": "after", "task": str(swap[1])}
    raise ValueError(f"swap {swap!r}: give 'spawns', 'now' or ('after', task)")


def files_of(files: Files) -> List[Dict[str, str]]:
    """The files of a load (``proto::File``): one path or ``(name, text)`` pair, or a list of
    them. Each path is read (its name is the path as given, for diagnostics); a pair (a tuple) is
    taken as it is."""
    items: Sequence[Any]
    if isinstance(files, (str, os.PathLike, tuple)):
        items = [files]
    else:
        items = list(files)
    out = []
    for f in items:
        if isinstance(f, tuple):
            name, text = f
            out.append({"name": str(name), "text": str(text)})
        else:
            path = os.fspath(f)
            with open(path, encoding="utf-8") as fh:
                out.append({"name": path, "text": fh.read()})
    if not out:
        raise ValueError("a program has at least one file")
    return out


def load_request(name: str, files: Files, swap: SwapSpec = "spawns") -> Dict[str, Any]:
    """Loads a program (or a new version of it) under ``name``."""
    return {"op": "load", "name": name, "files": files_of(files), "swap": swap_of(swap)}


def unload_request(name: str) -> Dict[str, Any]:
    """Removes the program ``name``."""
    return {"op": "unload", "name": name}


def list_request() -> Dict[str, Any]:
    """The loaded programs."""
    return {"op": "list"}


def start_request(program: str, task: Optional[str] = None, args: Any = None) -> Dict[str, Any]:
    """Starts ``task`` of ``program`` (its default task when ``None``) with ``args`` (any JSON,
    as ``tdl run --args`` takes it)."""
    return {"op": "start", "program": program, "task": task, "args": args}


def stop_request(run: int) -> Dict[str, Any]:
    """Stops a run."""
    return {"op": "stop", "run": int(run)}


def raise_request(run: int, event: str) -> Dict[str, Any]:
    """Raises the external event ``event`` in a run."""
    return {"op": "raise", "run": int(run), "event": event}


def status_request(run: Optional[int] = None) -> Dict[str, Any]:
    """The runs, or one run."""
    return {"op": "status", "run": None if run is None else int(run)}


def decode_response(payload: Union[bytes, str]) -> Tuple[str, Any]:
    """Reads an answer: ``(kind, value)`` of its reply (``("done", None)``,
    ``("started", {"run": 1, "trace": ...})``, ``("runs", [...])``, ...), or raises
    :class:`Refused` with the executive's reason, or :class:`ProtocolError`."""
    try:
        response = json.loads(payload)
    except (ValueError, UnicodeDecodeError) as e:
        raise ProtocolError(f"the answer is not JSON: {e}") from None
    if isinstance(response, dict) and len(response) == 1:
        if "refused" in response and isinstance(response["refused"], str):
            raise Refused(response["refused"])
        reply = response.get("ok")
        if isinstance(reply, str):
            return reply, None
        if isinstance(reply, dict) and len(reply) == 1:
            ((kind, value),) = reply.items()
            return kind, value
    raise ProtocolError(f"not an answer: {str(payload)[:200]}")


# --- the client -------------------------------------------------------------------------------


class Client:
    """A client named ``name`` of the serving executive ``executive`` of ``system``.

    By default it opens a zenoh session of its own on this machine, as the agents do
    (:func:`tdl_agent.loopback_config`: peer mode, multicast scouting off, connecting to
    ``tcp/127.0.0.1:<port>``); give ``config`` for another (TLS, routers), or ``session`` to use
    an open one (an agent's ``agent.session``), which :meth:`close` then leaves open. Each request
    waits at most ``timeout`` seconds for the answer. Usable as a context manager.
    """

    def __init__(
        self,
        system: str,
        name: str,
        port: int = 7447,
        executive: str = "main",
        timeout: float = DEFAULT_TIMEOUT,
        *,
        config: Any = None,
        session: Any = None,
    ) -> None:
        for what, n in (("system", system), ("client", name), ("executive", executive)):
            if not wire.valid_name(n):
                raise ValueError(
                    f"bad {what} name {n!r}: use ASCII letters, digits, `_`, `-` and `.`"
                )
        if timeout <= 0:
            raise ValueError("the timeout is a positive number of seconds")
        self.system = system
        self.name = name
        self.executive = executive
        self.timeout = float(timeout)
        self._owned = session is None
        if session is None:
            import zenoh

            from . import loopback_config

            session = zenoh.open(config if config is not None else loopback_config(port))
        self._session: Any = session

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Closes the client's session (not one it was given)."""
        session, self._session = self._session, None
        if session is not None and self._owned:
            session.close()

    def request(self, request: Dict[str, Any]) -> Tuple[str, Any]:
        """Sends ``request`` (a dict from :func:`load_request` and the others): the reply's
        ``(kind, value)``. The link to the executive comes up a moment after the session opens,
        and a query sent before finds no one: a request unanswered is sent once more."""
        if self._session is None:
            raise ClientError("the client is closed")
        key = serve_key(self.system, self.executive, self.name)
        payload = json.dumps(request).encode()
        for attempt in (1, 2):
            answer = self._query(key, payload)
            if answer is not None:
                return decode_response(answer)
        raise NoAnswer(self.executive, self.system, self.timeout)

    def _query(self, key: str, payload: bytes) -> Optional[bytes]:
        """One query: the first reply's payload, or ``None`` when none came in time."""
        replies = self._session.get(key, payload=payload, timeout=self.timeout)
        for reply in replies:
            if reply.ok is not None:
                return bytes(reply.ok.payload.to_bytes())
            raise ProtocolError(
                f"the executive answered with an error: {reply.err.payload.to_string()!r}"
            )
        return None

    def _expect(self, request: Dict[str, Any], kind: str) -> Any:
        got, value = self.request(request)
        if got != kind:
            raise ProtocolError(f"asked {request['op']!r}, answered {got!r}")
        return value

    # --- the requests -------------------------------------------------------------------------

    def load(self, name: str, files: Files, swap: SwapSpec = "spawns") -> Dict[str, Any]:
        """Loads a program (or a new version of it) under ``name`` from ``files`` (paths, or
        ``(name, text)`` pairs), checked there as one program: a program with errors raises
        :class:`Refused` with its located diagnostics. ``swap`` says how runs of an older version
        take it (``"spawns"``, ``"now"``, ``("after", task)``). Returns ``{"version":
        "name@hash", "unchanged": bool, "swapped": [runs]}``."""
        return self._expect(load_request(name, files, swap), "loaded")

    def unload(self, name: str) -> None:
        """Removes a program (refused while a run runs it); its handlers leave every run."""
        self._expect(unload_request(name), "unloaded")

    def programs(self) -> List[Dict[str, Any]]:
        """The loaded programs: dicts with ``name``, ``version``, ``tasks``, ``attaches_to`` and
        ``loaded_by``."""
        return self._expect(list_request(), "programs")

    def start(self, program: str, task: Optional[str] = None, args: Any = None) -> int:
        """Starts ``task`` of ``program`` (default: its only goal or command no task of it
        spawns) with ``args`` in a run of its own: the run's number."""
        return int(self._expect(start_request(program, task, args), "started")["run"])

    def stop(self, run: int) -> None:
        """Stops a run: its top-level task is terminated, its cleanup runs; it ends
        ``terminated``. Refused for a run that ended."""
        self._expect(stop_request(run), "done")

    def raise_event(self, run: int, event: str) -> None:
        """Raises the external event ``event`` in a run."""
        self._expect(raise_request(run, event), "done")

    #: The same as :meth:`raise_event`.
    raise_ = raise_event

    def status(self, run: Optional[int] = None) -> List[Dict[str, Any]]:
        """The runs (or only ``run``): dicts with ``run``, ``version``, ``task``, ``running``,
        ``outcome`` (how it ended, once it did), ``live_nodes`` and ``trace`` (its file)."""
        return self._expect(status_request(run), "runs")

    def wait_ended(self, run: int, timeout: float = 30.0, poll: float = 0.1) -> Dict[str, Any]:
        """Asks for ``run``'s status until it has ended (``outcome`` set): that status. Raises
        :class:`TimeoutError` when it still runs after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            (info,) = self.status(run)
            if not info["running"] and info["outcome"] is not None:
                return info
            if time.monotonic() >= deadline:
                raise TimeoutError(f"run {run} has not ended after {timeout:g} s: {info}")
            time.sleep(poll)
