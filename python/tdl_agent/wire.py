"""The wire of a TDL system on zenoh, as the Python agent speaks it.

This module mirrors ``crates/tcm-zenoh/src/wire.rs`` (see docs/distributed.md, "Keys" and
"Messages"). It does not import zenoh, so its encoding can be tested on its own.

Every message is a JSON object ``{"task": id, "seq": n, "body": {...}}``: the remote task it is
about (an id unique per executive), and its number among the messages of that task in that
direction, from 1. ``body["kind"]`` says what it is.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

#: What arguments and values are: anything :func:`json.dumps` takes.
Json = Any

#: The kinds of task an agent offers (``task_kind`` of a start).
COMMAND = "command"
GOAL = "goal"

_NAME = re.compile(r"^[A-Za-z0-9_.\-]+$")


def valid_name(name: str) -> bool:
    """Whether ``name`` can be one chunk of a key expression: ASCII letters, digits, ``_``,
    ``-`` and ``.``, not empty. System, agent and task names must be."""
    return bool(_NAME.match(name)) and name.isascii()


def agent_token(system: str, agent: str) -> str:
    """The liveliness token of an agent: the agent is up."""
    return f"tdl/{system}/agents/{agent}"


def offer_token(system: str, task: str, agent: str) -> str:
    """The liveliness token an agent holds for each task it offers."""
    return f"tdl/{system}/offers/{task}/{agent}"


def executives(system: str) -> str:
    """The liveliness tokens of the system's executives (a pattern)."""
    return f"tdl/{system}/executives/*"


def agent_inboxes(system: str, agent: str) -> str:
    """Where an agent receives the messages of every executive; the last chunk of a message's key
    names the executive that sent it."""
    return f"tdl/{system}/to-agent/{agent}/*"


def executive_inbox(system: str, executive: str, agent: str) -> str:
    """Where executive ``executive`` receives the messages of agent ``agent``: the key names the
    sender, and the executive accepts a task's messages only from the agent it placed it on."""
    return f"tdl/{system}/to-exec/{executive}/{agent}"


#: The kinds of message an executive sends to an agent.
TO_AGENT = ("start", "cancel", "reply", "reattach")


class MalformedMessage(ValueError):
    """A message that does not read as the wire says."""


@dataclass(frozen=True)
class Message:
    """One message: the remote task it is about, its sequence number, and its body."""

    task: int
    seq: int
    body: Dict[str, Json]

    @property
    def kind(self) -> str:
        """What the message says: ``start``, ``cancel`` or ``reply`` (from an executive)."""
        return str(self.body["kind"])


@dataclass
class Failure:
    """A typed failure as it travels (Rust's ``RemoteFailure``): the exception's type name, its
    message, its ancestors' names (nearest first), and its value as JSON."""

    exception: str
    message: str
    ancestry: List[str] = field(default_factory=list)
    data: Json = None

    def to_json(self) -> Dict[str, Json]:
        """The failure as the wire carries it."""
        return {
            "exception": self.exception,
            "message": self.message,
            "ancestry": list(self.ancestry),
            "data": self.data,
        }


def remote_error(message: str) -> Failure:
    """A failure of the distribution layer's own exception ``RemoteError``, whose value is
    ``{"message": ...}``, as the Rust side makes it."""
    return Failure("RemoteError", message, [], {"message": message})


def refused(agent: str, task: str, reason: str) -> Failure:
    """The failure of a start an agent refused because one of its bounds was reached: the
    exception ``RemoteRefused`` (a ``RemoteError``), whose value is ``{"agent", "task",
    "reason"}``, as the Rust side makes it."""
    return Failure(
        "RemoteRefused",
        f"agent {agent} refused to start {task}: {reason}",
        ["RemoteError"],
        {"agent": agent, "task": task, "reason": reason},
    )


def encode(task: int, seq: int, body: Dict[str, Json]) -> bytes:
    """A message as bytes (compact JSON). Raises :class:`TypeError` or :class:`ValueError` when
    the body holds something JSON cannot say (``NaN`` included)."""
    return json.dumps(
        {"task": task, "seq": seq, "body": body},
        separators=(",", ":"),
        allow_nan=False,
    ).encode("utf-8")


def decode(data: bytes) -> Message:
    """A message read from bytes; raises :class:`MalformedMessage` when it does not read."""
    try:
        obj = json.loads(data)
    except (ValueError, UnicodeDecodeError) as e:
        raise MalformedMessage(f"not JSON: {e}") from e
    except RecursionError as e:
        # Nested deeper than the interpreter's recursion limit (a forged payload).
        raise MalformedMessage("nested too deep") from e
    if not isinstance(obj, dict):
        raise MalformedMessage("not a JSON object")
    task, seq, body = obj.get("task"), obj.get("seq"), obj.get("body")
    for what, n in (("task", task), ("seq", seq)):
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            raise MalformedMessage(f"{what} is not a non-negative integer: {n!r}")
    if not isinstance(body, dict) or not isinstance(body.get("kind"), str):
        raise MalformedMessage("body is not an object with a kind")
    return Message(task, seq, body)


def start(node: int, name: str, task_kind: str, args: Json) -> Dict[str, Json]:
    """Executive to agent: run the offered task ``name`` for the node numbered ``node``."""
    return {"kind": "start", "node": node, "name": name, "task_kind": task_kind, "args": args}


def cancel() -> Dict[str, Json]:
    """Executive to agent: the node was terminated; abort, clean up, confirm."""
    return {"kind": "cancel"}


def reattach() -> Dict[str, Json]:
    """Executive to agent, numbered 0 outside the task's sequence: where does the task stand?
    (An executive resumed from its journal, or one that saw a gap in the task's messages.)"""
    return {"kind": "reattach"}


def attached(received: int, sent: int, done: Optional[Json] = None) -> Dict[str, Json]:
    """Agent to executive, numbered 0: the agent has the task; it applied the executive's
    messages up to ``received`` and sent its own up to ``sent``; ``done``, the ``result`` of the
    body's end (``{"Ok": value}`` or ``{"Err": failure}``) if it ended while the executive was
    away (its ``done`` may have been lost), else ``None``: the body runs."""
    return {"kind": "attached", "received": received, "sent": sent, "done": done}


def unattached(reason: str, started: bool) -> Dict[str, Json]:
    """Agent to executive, numbered 0: the agent does not run the task; ``started`` says whether
    it had it (it ended or was aborted) or never got its start."""
    return {"kind": "unattached", "reason": reason, "started": started}


def started() -> Dict[str, Json]:
    """Agent to executive: the body is running."""
    return {"kind": "started"}


def heartbeat() -> Dict[str, Json]:
    """Agent to executive: the body is alive."""
    return {"kind": "heartbeat"}


def set_state(var: str, value: Json) -> Dict[str, Json]:
    """Agent to executive: the body sets the state variable ``var`` of the executive's run to
    ``value`` (``None`` for unknown; a ``float`` for a ``float`` variable, an ``int`` for an
    ``int`` one)."""
    return {"kind": "set_state", "var": var, "value": value}


def done(value: Json) -> Dict[str, Json]:
    """Agent to executive: the body ended with ``value``."""
    return {"kind": "done", "result": {"Ok": value}}


def failed(failure: Failure) -> Dict[str, Json]:
    """Agent to executive: the body failed with a typed failure."""
    return {"kind": "done", "result": {"Err": failure.to_json()}}


def cancelled() -> Dict[str, Json]:
    """Agent to executive: the body was aborted after a cancel, and its cleanup ran."""
    return {"kind": "cancelled"}


def start_fields(msg: Message) -> "tuple[int, str, str, Json]":
    """The node, task name, task kind and arguments of a ``start``; raises
    :class:`MalformedMessage` when one is missing."""
    b = msg.body
    node, name, kind = b.get("node"), b.get("name"), b.get("task_kind")
    if not isinstance(node, int) or not isinstance(name, str) or kind not in (COMMAND, GOAL):
        raise MalformedMessage(f"a start without node, name or task kind: {b!r}")
    args: Optional[Json] = b.get("args")
    return node, name, kind, args
