"""A Python agent of a TDL distributed system.

An agent joins a system (a name shared by an executive and its agents) over zenoh and offers tasks
by name; the executive (the Rust crate ``tcm-zenoh``) places remote nodes of its task tree on it.
This module speaks the wire of ``crates/tcm-zenoh`` (docs/distributed.md): the liveliness tokens
``tdl/<system>/agents/<agent>`` and ``tdl/<system>/offers/<task>/<agent>``, the ``start``,
``cancel``, ``started``, ``done`` and ``cancelled`` messages with their task ids and sequence
numbers, JSON payloads, and typed failures.

    import tdl_agent

    class NoVoice(tdl_agent.TaskFailure):
        '''The speaker is off (a handler of ``NoVoice`` or ``HardwareFailure`` takes it).'''
        def __init__(self, text: str) -> None:
            super().__init__(f"cannot say {text!r}")
            self.text = text

    agent = tdl_agent.Agent("robot", "voice")

    @agent.command("speak")
    async def speak(ctx: tdl_agent.TaskContext, text: str) -> int:
        await asyncio.sleep(0.1)
        return len(text)

    agent.start(tdl_agent.loopback_config(7447))
    agent.run()          # until close(), SIGINT or SIGTERM

What a Python agent offers:

* **commands** and **goals that only run** (no children: a goal's calls to the tree are not
  supported here), with a body ``body(ctx, args)``: ``args`` is the JSON the executive sent,
  decoded; the returned value travels back as JSON (the node's value).
* A body is a coroutine function (run on the agent's asyncio loop, one thread; cancelling it
  raises :class:`asyncio.CancelledError` at its current ``await``) or a plain function (run in a
  worker thread; it cannot be interrupted, so it should look at ``ctx.cancelled`` when it runs
  long; its result is ignored once it was cancelled).
* **Typed failures**: raising a :class:`TaskFailure` subclass fails the node with an exception of
  the class's name, the names of its :class:`TaskFailure` base classes as ancestry (nearest
  first), and its public attributes as its value, so a handler in the tree catches it by name and
  reads its value (``tcm_zenoh::caught::<E>``). Any other exception fails the node with
  ``RemoteError``.
* **Cleanup**: ``on_terminate`` gives a task a cleanup ``cleanup(args)`` (sync or async), run when
  the node is terminated while its body runs (after the body is cancelled, before the
  cancellation is confirmed), and when the executive that started it goes away.

Messages are applied once, in order: a task's message is applied only when it is numbered one more
than the last one applied of that task (its start is number 1; zenoh delivers one publisher's
messages in order). A duplicated, late or out-of-order message, or one of a kind the agent does
not know, is counted (:class:`AgentStats`) and logged (logger ``tdl_agent``), never applied, and
does not change what the agent expects next.

A program that drives a serving executive (``tdl serve``) rather than offering tasks to one uses
:class:`Client` (module :mod:`tdl_agent.client`): load programs, start, stop and raise events in
runs, and ask for their status.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import functools
import inspect
import logging
import signal
import threading
from dataclasses import dataclass, field
from typing import Any, Awaitable, Callable, Dict, List, Optional, Sequence, Tuple, Union

import zenoh

from . import wire
from .client import Client, ClientError, NoAnswer, ProtocolError, Refused
from .wire import Failure, Json

__all__ = [
    "Agent",
    "AgentStats",
    "TaskContext",
    "TaskFailure",
    "Failure",
    "loopback_config",
    "peer_config",
    "client_config",
    "with_mtls",
    "loopback_tls_config",
    "Client",
    "ClientError",
    "Refused",
    "NoAnswer",
    "ProtocolError",
]

log = logging.getLogger("tdl_agent")

#: How many ended tasks an agent remembers, to tell a duplicate message from a late one.
ENDED_KEPT = 65_536

Body = Callable[["TaskContext", Json], Union[Json, Awaitable[Json]]]
Cleanup = Callable[[Json], Union[None, Awaitable[None]]]


class TaskFailure(Exception):
    """The base of the typed exceptions a body raises to fail its node.

    A subclass ``E`` fails the node with the exception named ``E`` (or ``E.tdl_name`` when the
    class sets it), whose ancestry is the names of ``E``'s base classes up to
    :class:`TaskFailure` (nearest first), so a handler of any of them takes it, and whose value
    is :meth:`data`: by default the instance's public attributes, as a JSON object.
    """

    #: The exception's name in the tree, when it is not the class's name.
    tdl_name: Optional[str] = None

    @classmethod
    def exception_name(cls) -> str:
        """The exception's name in the tree."""
        return cls.__dict__.get("tdl_name") or cls.__name__

    @classmethod
    def ancestry(cls) -> List[str]:
        """The names of the exception's ancestors, nearest first (not :class:`TaskFailure`)."""
        names: List[str] = []
        for c in cls.__mro__[1:]:
            if c is TaskFailure:
                break
            if isinstance(c, type) and issubclass(c, TaskFailure):
                names.append(c.exception_name())
        return names

    def data(self) -> Json:
        """The exception's value: its public attributes (``None`` when it has none)."""
        fields = {k: v for k, v in vars(self).items() if not k.startswith("_")}
        return fields or None

    def to_failure(self) -> Failure:
        """The failure as it travels."""
        return Failure(type(self).exception_name(), str(self), type(self).ancestry(), self.data())


def loopback_config(port: int) -> zenoh.Config:
    """The configuration of an agent on the executive's machine: peer mode, multicast scouting
    off, connecting to ``tcp/127.0.0.1:<port>``, listening nowhere."""
    return peer_config([], [f"tcp/127.0.0.1:{port}"])


def peer_config(listen: Sequence[str], connect: Sequence[str]) -> zenoh.Config:
    """A peer-mode configuration with multicast scouting off, listening on ``listen`` and
    connecting to ``connect`` (endpoints such as ``tcp/127.0.0.1:7447``)."""
    return _config("peer", listen, connect)


def client_config(routers: Sequence[str]) -> zenoh.Config:
    """A client-mode configuration with multicast scouting off, connecting to the ``zenohd``
    routers ``routers`` (docs/distributed.md, "Several machines")."""
    return _config("client", [], routers)


def with_mtls(config: zenoh.Config, authority: str, certificate: str, key: str) -> zenoh.Config:
    """``config`` with mutual TLS on its ``tls/...`` endpoints (docs/distributed.md, "Mutual
    TLS"), as ``tcm_zenoh::config::with_mtls``: ``authority`` is the PEM certificate of the
    system's authority, ``certificate`` and ``key`` this agent's, signed by it; a peer is
    accepted only with a certificate the authority signed."""
    import json

    tls = "transport/link/tls"
    for k, v in (
        ("root_ca_certificate", authority),
        ("listen_certificate", certificate),
        ("listen_private_key", key),
        ("connect_certificate", certificate),
        ("connect_private_key", key),
    ):
        config.insert_json5(f"{tls}/{k}", json.dumps(str(v)))
    config.insert_json5(f"{tls}/enable_mtls", "true")
    config.insert_json5(f"{tls}/verify_name_on_connect", "true")
    return config


def loopback_tls_config(port: int, authority: str, certificate: str, key: str) -> zenoh.Config:
    """As :func:`loopback_config`, over mutual TLS: connecting to ``tls/127.0.0.1:<port>``."""
    return with_mtls(peer_config([], [f"tls/127.0.0.1:{port}"]), authority, certificate, key)


def _config(mode: str, listen: Sequence[str], connect: Sequence[str]) -> zenoh.Config:
    import json

    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("listen/endpoints", json.dumps(list(listen)))
    c.insert_json5("connect/endpoints", json.dumps(list(connect)))
    return c


@dataclass
class AgentStats:
    """The counters of an agent (as Rust's ``AgentStats``)."""

    started: int = 0
    ended: int = 0
    cancelled: int = 0
    orphaned: int = 0
    duplicates: int = 0
    #: Messages numbered past the next one expected, and starts not numbered 1: refused.
    refused: int = 0
    late: int = 0
    malformed: int = 0
    #: Starts refused because a bound was reached (the node fails with ``RemoteRefused``).
    over_limit: int = 0
    #: Starts refused because the executive the key names is not live: not answered.
    strangers: int = 0
    #: ``reattach`` questions answered ``attached`` (the task runs here).
    reattached: int = 0


@dataclass
class _Offer:
    kind: str
    body: Body
    cleanup: Optional[Cleanup] = None


class TaskContext:
    """What a body sees: its task, its node, whether it was cancelled, and a heartbeat."""

    def __init__(self, agent: "Agent", executive: str, task_id: int, node: int, name: str) -> None:
        self._agent = agent
        self._key = (executive, task_id)
        #: The node's display number in the executive's tree (for logs).
        self.node = node
        #: The offered task's name.
        self.task = name
        #: Set when the node is terminated (or its executive went): a plain-function body that
        #: runs long should look at it and return.
        self.cancelled = threading.Event()

    def heartbeat(self) -> None:
        """Tells the executive the body is alive (resets its heartbeat timeout). Safe from any
        thread."""
        self._agent._from_any_thread(self._agent._heartbeat, self._key)

    def set_state(self, var: str, value: Json) -> None:
        """Sets the state variable ``var`` of the executive's run (docs/semantics.md, "State and
        conditions"): ``True``/``False``, an ``int``, a ``float``, a ``str``, or ``None`` for
        unknown. The executive's conditions that read it answer; a value of another type than
        the variable's is refused there, with a warning in its trace. Safe from any thread."""
        if isinstance(value, float) and value != value:
            raise ValueError("a state value is finite: use None for unknown")
        self._agent._from_any_thread(self._agent._set_state, self._key, var, value)


@dataclass
class _Running:
    offer: _Offer
    args: Json
    ctx: TaskContext
    last_seq: int
    out_seq: int = 0
    task: Optional["asyncio.Task[None]"] = None
    #: Its executive's token went, and the agent holds it: aborted when the hold ends, unless
    #: the executive re-attaches first.
    orphaned: bool = False


#: How many ended bodies' ends an agent with a hold keeps (the oldest dropped first).
OUTCOMES_KEPT = 4096

#: How long the first messages to an executive wait for its inbox to be known (seconds).
REACH = 3.0

#: How long a start from an executive whose token was not seen waits for it (seconds), and how
#: many such starts wait at once (the others are refused at once).
PARK_WAIT = 2.0
PARKED = 64


class _Outlet:
    """The publisher to an executive's inbox, and what waits for a subscriber of it to be known:
    zenoh drops a publication no known subscriber matches, and an executive's token can come
    before its inbox's declaration (docs/distributed.md, "Messages")."""

    def __init__(self, publisher: Any) -> None:
        self.publisher = publisher
        self.matched = False
        self.waiting: List[bytes] = []
        self.listener: Any = None

    def put(self, data: bytes) -> None:
        if self.matched:
            self.publisher.put(data)
        else:
            self.waiting.append(data)

    def open(self) -> None:
        """Sends what waited, in order; later messages go at once."""
        self.matched = True
        waiting, self.waiting = self.waiting, []
        for data in waiting:
            self.publisher.put(data)
        listener, self.listener = self.listener, None
        if listener is not None:
            try:
                listener.undeclare()
            except Exception as e:
                log.debug("undeclaring a matching listener: %s", e)

    def undeclare(self) -> None:
        if self.listener is not None:
            self.listener.undeclare()
        self.publisher.undeclare()


class Agent:
    """An agent named ``name`` of system ``system``; offer tasks, then :meth:`start` it.

    Its bounds (docs/distributed.md, "Bounds"): at most ``max_bodies_per_executive`` bodies
    running for one executive and ``max_bodies`` in all; at most ``max_threads`` plain-function
    bodies running in worker threads (a thread counts until its function returns, cancelled or
    not); a publisher kept for at most ``max_executives`` executives, each live (its token seen)
    and released when its token goes. A start past a bound is refused: the body does not run and
    the executive's node fails at once with ``RemoteRefused``.

    With ``hold`` (seconds; docs/distributed.md, "An executive that comes back"), the bodies of an
    executive whose token went keep running that long, and the ends of bodies are kept (the last
    4,096), so that the executive, resumed from its journal under the same id, re-attaches to
    them: ``reattach`` is answered ``attached`` with the body's end if it ended meanwhile. A body
    not re-attached when the hold ends is aborted and cleaned up (``orphaned``). With no hold (the
    default), the bodies are aborted when the token goes.
    """

    def __init__(
        self,
        system: str,
        name: str,
        *,
        max_bodies_per_executive: int = 256,
        max_bodies: int = 1024,
        max_threads: int = 16,
        max_executives: int = 16,
        hold: float = 0.0,
    ) -> None:
        for n in (system, name):
            if not wire.valid_name(n):
                raise ValueError(f"bad name {n!r}: use ASCII letters, digits, `_`, `-` and `.`")
        self.system = system
        self.name = name
        self.stats = AgentStats()
        self._offers: Dict[str, _Offer] = {}
        self._running: Dict[Tuple[str, int], _Running] = {}
        self._ended: "collections.OrderedDict[Tuple[str, int], int]" = collections.OrderedDict()
        self._publishers: Dict[str, _Outlet] = {}
        # The executives whose token is live.
        self._live: "set[str]" = set()
        # Starts from executives whose token was not seen yet, by executive.
        self._parked: Dict[str, List[Any]] = {}
        self.max_bodies_per_executive = max_bodies_per_executive
        self.max_bodies = max_bodies
        self.max_threads = max_threads
        self.max_executives = max_executives
        self.hold = hold
        # With a hold: the ends of bodies, by executive and task, for an executive that
        # re-attaches: (last number applied, last sent, the end's ``result``).
        self._outcomes: "collections.OrderedDict[Tuple[str, int], Tuple[int, int, Json]]" = (
            collections.OrderedDict()
        )
        # How often each executive's token went: a hold ends only the absence it began with.
        self._absences: Dict[str, int] = {}
        # Worker threads running a body's function now (cancelled ones included).
        self._threads = 0
        # Bodies' functions and cleanups; a few more threads than bodies, for the cleanups.
        self._executor = concurrent.futures.ThreadPoolExecutor(
            max_workers=max_threads + 2, thread_name_prefix=f"tdl-agent-{name}"
        )
        self._keep: List[Any] = []
        self._tasks: "set[asyncio.Task[None]]" = set()
        self._session: Optional[zenoh.Session] = None
        self._loop: Optional[asyncio.AbstractEventLoop] = None
        self._thread: Optional[threading.Thread] = None
        self._closed = threading.Event()

    # --- offering -----------------------------------------------------------------------------

    def command(
        self, name: str, body: Optional[Body] = None, *, on_terminate: Optional[Cleanup] = None
    ) -> Any:
        """Offers the command ``name`` with ``body(ctx, args)``; usable as a decorator
        (``@agent.command("speak")``)."""
        return self._offer(wire.COMMAND, name, body, on_terminate)

    def goal(
        self, name: str, body: Optional[Body] = None, *, on_terminate: Optional[Cleanup] = None
    ) -> Any:
        """Offers the goal ``name``: as :meth:`command`, for a node the tree treats as a goal
        (its body spawns no children from Python)."""
        return self._offer(wire.GOAL, name, body, on_terminate)

    def on_terminate(self, name: str, cleanup: Cleanup) -> None:
        """Sets the cleanup of the offered task ``name``: ``cleanup(args)`` runs when a body of it
        is cancelled, before the cancellation is confirmed."""
        self._offers[name].cleanup = cleanup

    def _offer(self, kind: str, name: str, body: Optional[Body], cleanup: Optional[Cleanup]) -> Any:
        if not wire.valid_name(name):
            raise ValueError(f"bad task name {name!r}: use ASCII letters, digits, `_`, `-` and `.`")
        if self._session is not None:
            raise RuntimeError("offer tasks before the agent starts")

        def register(f: Body) -> Body:
            self._offers[name] = _Offer(kind, f, cleanup)
            return f

        return register if body is None else register(body)

    # --- life ---------------------------------------------------------------------------------

    def start(self, config: zenoh.Config) -> None:
        """Joins the system with a zenoh session opened from ``config``
        (:func:`loopback_config`, :func:`client_config`) and starts serving, on a thread of its
        own: offer tokens first, then the agent's token, so an executive that sees the agent sees
        what it offers."""
        if self._session is not None:
            raise RuntimeError("the agent already started")
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(
            target=self._loop.run_forever, name=f"tdl-agent-{self.name}", daemon=True
        )
        self._thread.start()
        session = zenoh.open(config)
        self._session = session
        self._keep.append(
            session.declare_subscriber(
                wire.agent_inboxes(self.system, self.name), self._on_message
            )
        )
        self._keep.append(
            session.liveliness().declare_subscriber(
                wire.executives(self.system), self._on_executive, history=True
            )
        )
        for task in self._offers:
            self._keep.append(
                session.liveliness().declare_token(wire.offer_token(self.system, task, self.name))
            )
        self._keep.append(session.liveliness().declare_token(wire.agent_token(self.system, self.name)))

    def run(self) -> None:
        """Blocks until :meth:`close` is called, or (from the main thread) until SIGINT or
        SIGTERM, which close the agent."""
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda *_: self._closed.set())
        while not self._closed.wait(0.2):
            pass
        self.close()

    def close(self) -> None:
        """Withdraws the agent: its tokens go (executives fail the tasks it ran with
        ``AgentLost``), its bodies are cancelled without cleanup, its session closes."""
        self._closed.set()
        loop, session = self._loop, self._session
        if loop is None or session is None:
            return
        self._session = None

        def stop() -> None:
            for r in self._running.values():
                r.ctx.cancelled.set()
                if r.task is not None:
                    r.task.cancel()
            self._running.clear()
            loop.stop()

        loop.call_soon_threadsafe(stop)
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._executor.shutdown(wait=False)
        for k in reversed(self._keep):
            try:
                k.undeclare()
            except Exception as e:  # the session may be closing under it
                log.debug("undeclaring: %s", e)
        self._keep.clear()
        session.close()

    @property
    def session(self) -> Optional[zenoh.Session]:
        """The agent's zenoh session (``None`` before :meth:`start` and after :meth:`close`),
        for a program's own traffic: a body's queries, say."""
        return self._session

    def running(self) -> int:
        """How many bodies run now."""
        return len(self._running)

    # --- zenoh callbacks (zenoh's threads) ----------------------------------------------------

    def _from_any_thread(self, f: Callable[..., None], *args: Any) -> None:
        loop = self._loop
        try:
            running: Optional[asyncio.AbstractEventLoop] = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is not None and running is loop:
            # Already on the loop (an async body): at once, so that what the body sends keeps
            # its order with the body's end.
            f(*args)
            return
        if loop is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(f, *args)
            except RuntimeError:  # the loop closed meanwhile
                pass

    def _on_message(self, sample: zenoh.Sample) -> None:
        executive = str(sample.key_expr).rsplit("/", 1)[-1]
        self._from_any_thread(self._receive, executive, sample.payload.to_bytes())

    def _on_executive(self, sample: zenoh.Sample) -> None:
        executive = str(sample.key_expr).rsplit("/", 1)[-1]
        if sample.kind == zenoh.SampleKind.DELETE:
            self._from_any_thread(self._executive_gone, executive)
        else:
            self._from_any_thread(self._executive_up, executive)

    # --- the agent's loop ---------------------------------------------------------------------

    def _executive_up(self, executive: str) -> None:
        self._live.add(executive)
        self._publisher(executive)
        self._unpark(executive)

    def _publisher(self, executive: str) -> Optional[_Outlet]:
        """The outlet to a live executive's inbox, declared on first use; ``None`` for an
        executive whose token is not live, or past ``max_executives`` (its messages then go
        out as puts of the session, keeping nothing)."""
        p = self._publishers.get(executive)
        if (
            p is None
            and self._session is not None
            and executive in self._live
            and len(self._publishers) < self.max_executives
        ):
            p = _Outlet(
                self._session.declare_publisher(
                    wire.executive_inbox(self.system, executive, self.name),
                    congestion_control=zenoh.CongestionControl.BLOCK,
                )
            )
            self._publishers[executive] = p
            if p.publisher.matching_status.matching:
                p.open()
            else:
                outlet = p

                def on_matching(status: Any) -> None:
                    if status.matching:
                        self._from_any_thread(self._reached, executive, outlet)

                p.listener = p.publisher.declare_matching_listener(on_matching)
                # A declaration may have come between the first look and the listener; after
                # a while, what waits is sent anyway.
                if p.publisher.matching_status.matching:
                    p.open()
                elif self._loop is not None:
                    self._loop.call_later(REACH, self._reached, executive, p)
        return p

    def _reached(self, executive: str, p: _Outlet) -> None:
        if self._publishers.get(executive) is p and not p.matched:
            if not p.publisher.matching_status.matching:
                log.warning(
                    "agent %s: no subscriber of %s's inbox is known: sending anyway",
                    self.name,
                    executive,
                )
            p.open()

    def _send(self, key: Tuple[str, int], r: _Running, body: Dict[str, Json]) -> None:
        r.out_seq += 1
        try:
            data = wire.encode(key[1], r.out_seq, body)
        except (TypeError, ValueError) as e:
            data = wire.encode(
                key[1],
                r.out_seq,
                wire.failed(wire.remote_error(f"the value of {r.ctx.task} is not JSON: {e}")),
            )
        self._put(key, data)

    def _answer_reattach(self, key: Tuple[str, int]) -> None:
        """Answers an executive's ``reattach`` for ``key``, numbered 0: ``attached`` with where the
        task's two sequences stand when it runs here (no longer orphaned), or, with a hold, when
        it ended here with its end; else ``unattached``, saying whether this agent had it (an
        ended task whose end is not kept is lost for the executive: its node fails with
        ``AgentLost``)."""
        executive, task = key
        r = self._running.get(key)
        outcome = self._outcomes.get(key)
        if r is not None:
            r.orphaned = False
            self.stats.reattached += 1
            body = wire.attached(r.last_seq, r.out_seq)
        elif outcome is not None:
            self.stats.reattached += 1
            body = wire.attached(outcome[0], outcome[1], outcome[2])
        elif key in self._ended:
            kept = "aborted when its hold ended" if self.hold > 0 else "this agent keeps no ends"
            body = wire.unattached(
                f"agent {self.name} no longer has task {task} of executive {executive} "
                f"(it ended or was cancelled, and {kept})",
                True,
            )
        else:
            body = wire.unattached(
                f"agent {self.name} never had task {task} of executive {executive}: "
                "its start did not reach it",
                False,
            )
        self._put(key, wire.encode(task, 0, body))

    def _put(self, key: Tuple[str, int], data: bytes) -> None:
        try:
            p = self._publisher(key[0])
            if p is not None:
                p.put(data)
            elif self._session is not None:
                self._session.put(
                    wire.executive_inbox(self.system, key[0], self.name),
                    data,
                    congestion_control=zenoh.CongestionControl.BLOCK,
                )
        except Exception as e:
            log.warning("agent %s cannot reach executive %s: %s", self.name, key[0], e)

    def _receive(self, executive: str, data: bytes) -> None:
        try:
            msg = wire.decode(data)
        except wire.MalformedMessage as e:
            self.stats.malformed += 1
            log.warning("agent %s: malformed message ignored: %s", self.name, e)
            return
        key = (executive, msg.task)
        if msg.kind not in wire.TO_AGENT:
            # Not a message an executive sends: it says nothing about the task's sequence.
            self.stats.malformed += 1
            log.warning("agent %s: message of unknown kind %r ignored", self.name, msg.kind)
            return
        if msg.kind == "start":
            try:
                node, name, kind, args = wire.start_fields(msg)
            except wire.MalformedMessage as e:
                self.stats.malformed += 1
                log.warning("agent %s: malformed start ignored: %s", self.name, e)
                return
            self._start(key, msg.seq, node, name, kind, args)
            return
        if msg.kind == "reattach":
            # Numbered 0, outside the task's sequence: answered, and nothing else changes.
            self._answer_reattach(key)
            return
        r = self._running.get(key)
        if r is None:
            last = self._ended.get(key)
            if last is not None and msg.seq <= last:
                self.stats.duplicates += 1
                log.warning("agent %s: duplicate %s of task %d ignored", self.name, msg.kind, msg.task)
            else:
                self.stats.late += 1
                log.warning("agent %s: late %s of task %d ignored", self.name, msg.kind, msg.task)
            return
        if msg.seq <= r.last_seq:
            self.stats.duplicates += 1
            log.warning("agent %s: duplicate %s of task %d ignored", self.name, msg.kind, msg.task)
            return
        if msg.seq != r.last_seq + 1:
            # A gap, or a forged huge number that would make the executive's cancel a duplicate.
            self.stats.refused += 1
            log.warning(
                "agent %s: out-of-order %s %d of task %d refused (expected %d)",
                self.name, msg.kind, msg.seq, msg.task, r.last_seq + 1,
            )
            return
        r.last_seq = msg.seq
        if msg.kind == "cancel":
            self.stats.cancelled += 1
            self._stop(key, r, confirm=True)
        # A `reply` answers a call; a Python body makes none.

    def _start(
        self, key: Tuple[str, int], seq: int, node: int, name: str, kind: str, args: Json
    ) -> None:
        if key in self._running or key in self._ended:
            self.stats.duplicates += 1
            log.warning("agent %s: duplicate start of task %d ignored", self.name, key[1])
            return
        if key[0] not in self._live:
            # Only a live executive of the system starts tasks. The start waits a little for the
            # executive's token (its notice and the start can come by different paths), at most
            # PARKED starts at once; then it is refused, unanswered (nobody would read it).
            if sum(len(v) for v in self._parked.values()) < PARKED:
                first = key[0] not in self._parked
                self._parked.setdefault(key[0], []).append((key, seq, node, name, kind, args))
                if first and self._loop is not None:
                    self._loop.call_later(PARK_WAIT, self._unpark, key[0])
                return
            self._refuse_stranger(key, seq)
            return
        if seq != 1:
            # A task's first message is its start, number 1.
            self.stats.refused += 1
            log.warning("agent %s: start %d of task %d refused (a start is number 1)", self.name, seq, key[1])
            return
        ctx = TaskContext(self, key[0], key[1], node, name)
        offer = self._offers.get(name)
        if offer is None or offer.kind != kind:
            why = (
                f"agent {self.name} does not offer {name}"
                if offer is None
                else f"agent {self.name} offers {name} as another kind of task"
            )
            r = _Running(_Offer(kind, lambda c, a: None), args, ctx, seq)
            self._remember_ended(key, seq)
            self._send(key, r, wire.failed(wire.remote_error(why)))
            return
        why = self._over_limit(key[0], offer)
        if why is not None:
            self.stats.over_limit += 1
            log.warning("agent %s: start of %s (task %d) refused: %s", self.name, name, key[1], why)
            r = _Running(_Offer(kind, lambda c, a: None), args, ctx, seq)
            self._remember_ended(key, seq)
            self._send(key, r, wire.failed(wire.refused(self.name, name, why)))
            return
        r = _Running(offer, args, ctx, seq)
        self._running[key] = r
        self.stats.started += 1
        self._send(key, r, wire.started())
        r.task = self._spawn(self._run_body(key, r))

    def _refuse_stranger(self, key: Tuple[str, int], seq: int) -> None:
        self.stats.strangers += 1
        log.warning(
            "agent %s: start %d of task %d refused: no executive %s is live",
            self.name, seq, key[1], key[0],
        )

    def _unpark(self, executive: str) -> None:
        """Starts the starts of ``executive`` that waited for its token if it came, else refuses
        them."""
        for (key, seq, node, name, kind, args) in self._parked.pop(executive, []):
            if executive in self._live:
                self._start(key, seq, node, name, kind, args)
            else:
                self._refuse_stranger(key, seq)

    def _over_limit(self, executive: str, offer: _Offer) -> Optional[str]:
        """Why a start of ``offer`` from ``executive`` is refused, if a bound is reached."""
        if len(self._running) >= self.max_bodies:
            return f"{len(self._running)} bodies run already, the agent's bound"
        mine = sum(1 for k in self._running if k[0] == executive)
        if mine >= self.max_bodies_per_executive:
            return f"{mine} bodies run already for this executive, the agent's bound"
        if not inspect.iscoroutinefunction(offer.body) and self._threads >= self.max_threads:
            return f"{self._threads} worker threads are busy, the agent's bound"
        return None

    def _spawn(self, coro: Awaitable[None]) -> "asyncio.Task[None]":
        assert self._loop is not None
        task = self._loop.create_task(coro)  # type: ignore[arg-type]
        # The loop keeps only a weak reference to its tasks.
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    async def _run_body(self, key: Tuple[str, int], r: _Running) -> None:
        body = r.offer.body
        try:
            if inspect.iscoroutinefunction(body):
                value = await body(r.ctx, r.args)
            else:
                value = await self._in_thread(functools.partial(body, r.ctx, r.args))
                if inspect.isawaitable(value):
                    value = await value
            result = wire.done(value)
        except asyncio.CancelledError:
            raise
        except TaskFailure as e:
            result = wire.failed(e.to_failure())
        except Exception as e:
            result = wire.failed(wire.remote_error(f"{r.ctx.task} raised {type(e).__name__}: {e}"))
        if self._running.get(key) is r:
            self._end(key)
            self.stats.ended += 1
            self._send(key, r, result)
            if self.hold > 0:
                # Its `done` may be lost with an executive that went: kept for a reattach.
                self._outcomes[key] = (r.last_seq, r.out_seq, result["result"])
                while len(self._outcomes) > OUTCOMES_KEPT:
                    self._outcomes.popitem(last=False)

    async def _clean_up(self, key: Tuple[str, int], r: _Running, confirm: bool) -> None:
        cleanup = r.offer.cleanup
        if cleanup is not None:
            try:
                if inspect.iscoroutinefunction(cleanup):
                    await cleanup(r.args)
                else:
                    assert self._loop is not None
                    out = await self._loop.run_in_executor(self._executor, cleanup, r.args)
                    if inspect.isawaitable(out):
                        await out
            except Exception as e:
                log.warning("agent %s: the cleanup of %s raised %r", self.name, r.ctx.task, e)
        if confirm:
            self._send(key, r, wire.cancelled())

    async def _in_thread(self, f: Callable[[], Json]) -> Json:
        """Runs a body's function in a worker thread, counted until the function returns (a
        cancelled body's thread runs on: it still counts against ``max_threads``)."""
        self._threads += 1
        try:
            done = self._executor.submit(f)
        except RuntimeError:  # the executor was shut down: the agent closed
            self._threads -= 1
            raise
        done.add_done_callback(lambda _: self._from_any_thread(self._thread_done))
        return await asyncio.wrap_future(done)

    def _thread_done(self) -> None:
        self._threads -= 1

    def _heartbeat(self, key: Tuple[str, int]) -> None:
        r = self._running.get(key)
        if r is not None:
            self._send(key, r, wire.heartbeat())

    def _set_state(self, key: Tuple[str, int], var: str, value: Json) -> None:
        r = self._running.get(key)
        if r is not None:
            self._send(key, r, wire.set_state(var, value))

    def _end(self, key: Tuple[str, int]) -> None:
        r = self._running.pop(key, None)
        if r is not None:
            self._remember_ended(key, r.last_seq)

    def _remember_ended(self, key: Tuple[str, int], last_seq: int) -> None:
        self._ended[key] = last_seq
        while len(self._ended) > ENDED_KEPT:
            self._ended.popitem(last=False)

    def _executive_gone(self, executive: str) -> None:
        """``executive``'s token went: its bodies are aborted and cleaned up, at once or, with a
        hold, when the hold ends unless the executive re-attaches first (or goes again
        meanwhile: that absence ends them)."""
        if self.hold > 0 and self._loop is not None:
            for key, r in self._running.items():
                if key[0] == executive:
                    r.orphaned = True
            absence = self._absences.get(executive, 0) + 1
            self._absences[executive] = absence
            self._loop.call_later(self.hold, self._hold_ended, executive, absence)
        else:
            self._abandon(executive)
        self._live.discard(executive)
        p = self._publishers.pop(executive, None)
        if p is not None:
            try:
                p.undeclare()
            except Exception as e:
                log.debug("undeclaring the publisher to %s: %s", executive, e)

    def _hold_ended(self, executive: str, absence: int) -> None:
        if self._absences.get(executive) == absence:
            self._abandon(executive, orphaned_only=True)

    def _abandon(self, executive: str, orphaned_only: bool = False) -> None:
        """Aborts and cleans up the bodies ``executive`` started (those still orphaned only)."""
        for key in [k for k, r in self._running.items()
                    if k[0] == executive and (r.orphaned or not orphaned_only)]:
            self.stats.orphaned += 1
            self._stop(key, self._running[key], confirm=False)

    def _stop(self, key: Tuple[str, int], r: _Running, confirm: bool) -> None:
        """Ends the body of ``key``: cancelled, its cleanup run (then, with ``confirm``, the
        executive told ``cancelled``)."""
        self._end(key)
        r.ctx.cancelled.set()
        if r.task is not None:
            r.task.cancel()
        self._spawn(self._clean_up(key, r, confirm=confirm))
