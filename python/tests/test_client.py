"""Unit tests of tdl_agent's client of a serving executive without a network: the requests as
serde reads them (crates/tdl-serve/src/proto.rs), the answers as serde writes them, and the
client's one query per request on its key, over a stand-in session that records the queries and
answers from a script (a refusal, no answer then an answer, no answer twice).

Run with the module's other unit tests: ``python -m unittest discover -s python/tests``.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import unittest
from typing import Any, List, Optional

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import tdl_agent  # noqa: E402
from tdl_agent import client  # noqa: E402


class Requests(unittest.TestCase):
    def test_each_request_is_tagged_by_op_as_serde_reads_it(self) -> None:
        self.assertEqual(client.list_request(), {"op": "list"})
        self.assertEqual(client.unload_request("w"), {"op": "unload", "name": "w"})
        self.assertEqual(client.stop_request(3), {"op": "stop", "run": 3})
        self.assertEqual(
            client.raise_request(3, "door_open"), {"op": "raise", "run": 3, "event": "door_open"}
        )
        self.assertEqual(client.status_request(), {"op": "status", "run": None})
        self.assertEqual(client.status_request(2), {"op": "status", "run": 2})
        self.assertEqual(
            client.start_request("patrol"),
            {"op": "start", "program": "patrol", "task": None, "args": None},
        )
        self.assertEqual(
            client.start_request("patrol", "walk", [3, {"x": 1.5}]),
            {"op": "start", "program": "patrol", "task": "walk", "args": [3, {"x": 1.5}]},
        )

    def test_swaps_are_tagged_by_at(self) -> None:
        self.assertEqual(client.swap_of("spawns"), {"at": "spawns"})
        self.assertEqual(client.swap_of("now"), {"at": "now"})
        self.assertEqual(client.swap_of(("after", "lap")), {"at": "after", "task": "lap"})
        self.assertEqual(client.swap_of("after:lap"), {"at": "after", "task": "lap"})
        for bad in ("later", "after:", ("after", ""), ("before", "lap")):
            with self.assertRaises(ValueError, msg=repr(bad)):
                client.swap_of(bad)  # type: ignore[arg-type]

    def test_a_load_reads_paths_and_takes_named_texts(self) -> None:
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "watch.tdl")
            with open(path, "w", encoding="utf-8") as f:
                f.write("pub goal watch() {}\n")
            one = client.load_request("watch", path)
            self.assertEqual(
                one,
                {
                    "op": "load",
                    "name": "watch",
                    "files": [{"name": path, "text": "pub goal watch() {}\n"}],
                    "swap": {"at": "spawns"},
                },
            )
            two = client.load_request("w", [path, ("extra.tdl", "command c() {}")], "now")
            self.assertEqual(
                two["files"],
                [
                    {"name": path, "text": "pub goal watch() {}\n"},
                    {"name": "extra.tdl", "text": "command c() {}"},
                ],
            )
            self.assertEqual(two["swap"], {"at": "now"})
            # A pair alone is one file.
            self.assertEqual(
                client.files_of(("a.tdl", "text")), [{"name": "a.tdl", "text": "text"}]
            )
        with self.assertRaises(ValueError):
            client.files_of([])


class Responses(unittest.TestCase):
    def test_replies_read_as_their_kind_and_value(self) -> None:
        self.assertEqual(client.decode_response(b'{"ok":"done"}'), ("done", None))
        self.assertEqual(client.decode_response(b'{"ok":"unloaded"}'), ("unloaded", None))
        self.assertEqual(
            client.decode_response(b'{"ok":{"started":{"run":4,"trace":"tdl-runs/run-4.jsonl"}}}'),
            ("started", {"run": 4, "trace": "tdl-runs/run-4.jsonl"}),
        )
        self.assertEqual(
            client.decode_response(
                b'{"ok":{"loaded":{"version":"w@ab12","unchanged":false,"swapped":[1,2]}}}'
            ),
            ("loaded", {"version": "w@ab12", "unchanged": False, "swapped": [1, 2]}),
        )
        self.assertEqual(client.decode_response('{"ok":{"runs":[]}}'), ("runs", []))

    def test_a_refusal_raises_refused_with_the_reason(self) -> None:
        reason = "error: `dig` is not a task of the program\n --> broken.tdl:3:11"
        with self.assertRaises(tdl_agent.Refused) as caught:
            client.decode_response(json.dumps({"refused": reason}).encode())
        self.assertEqual(caught.exception.reason, reason)
        self.assertIn("broken.tdl:3:11", str(caught.exception))
        self.assertIsInstance(caught.exception, tdl_agent.ClientError)

    def test_what_is_not_an_answer_is_a_protocol_error(self) -> None:
        for bad in (b"", b"not json", b"[]", b'{"ok":{"a":1,"b":2}}', b'{"ok":1}', b'{"refused":3}',
                    b'{"ok":"done","refused":"x"}'):
            with self.assertRaises(tdl_agent.ProtocolError, msg=repr(bad)):
                client.decode_response(bad)


class _Payload:
    def __init__(self, data: bytes) -> None:
        self._data = data

    def to_bytes(self) -> bytes:
        return self._data

    def to_string(self) -> str:
        return self._data.decode()


class _Sample:
    def __init__(self, data: bytes) -> None:
        self.payload = _Payload(data)


class _Reply:
    def __init__(self, ok: Optional[bytes] = None, err: Optional[bytes] = None) -> None:
        self.ok = None if ok is None else _Sample(ok)
        self.err = None if err is None else _Sample(err)


class _Session:
    """Answers each query with the next of ``script``: a list of replies (empty: no one
    answered), recording the key, payload and timeout of each."""

    def __init__(self, script: List[List[_Reply]]) -> None:
        self.script = list(script)
        self.queries: List[Any] = []
        self.closed = False

    def get(self, key: str, payload: bytes, timeout: float) -> List[_Reply]:
        self.queries.append((key, json.loads(payload), timeout))
        return self.script.pop(0)

    def close(self) -> None:
        self.closed = True


class ClientOverASession(unittest.TestCase):
    def test_each_request_is_one_query_on_the_clients_key(self) -> None:
        s = _Session([
            [_Reply(ok=b'{"ok":{"started":{"run":7,"trace":"t/run-7.jsonl"}}}')],
            [_Reply(ok=b'{"ok":"done"}')],
            [_Reply(ok=b'{"ok":{"runs":[{"run":7,"running":true}]}}')],
        ])
        c = tdl_agent.Client("robot", "planner", executive="exec1", timeout=2.5, session=s)
        self.assertEqual(c.start("patrol", args=[1]), 7)
        c.raise_event(7, "door_open")
        self.assertEqual(c.status(7), [{"run": 7, "running": True}])
        self.assertEqual(
            s.queries,
            [
                ("tdl/robot/serve/exec1/planner",
                 {"op": "start", "program": "patrol", "task": None, "args": [1]}, 2.5),
                ("tdl/robot/serve/exec1/planner",
                 {"op": "raise", "run": 7, "event": "door_open"}, 2.5),
                ("tdl/robot/serve/exec1/planner", {"op": "status", "run": 7}, 2.5),
            ],
        )
        c.close()
        self.assertFalse(s.closed, "a session given is not the client's to close")

    def test_a_refusal_raises_refused_and_is_not_asked_again(self) -> None:
        s = _Session([[_Reply(ok=b'{"refused":"run 3 has ended"}')]])
        c = tdl_agent.Client("robot", "planner", session=s)
        with self.assertRaises(tdl_agent.Refused) as caught:
            c.stop(3)
        self.assertEqual(caught.exception.reason, "run 3 has ended")
        self.assertEqual(len(s.queries), 1)

    def test_an_unanswered_query_is_asked_once_more(self) -> None:
        s = _Session([[], [_Reply(ok=b'{"ok":{"programs":[]}}')]])
        c = tdl_agent.Client("robot", "planner", session=s)
        self.assertEqual(c.programs(), [])
        self.assertEqual([q[1] for q in s.queries], [{"op": "list"}, {"op": "list"}])

    def test_no_answer_twice_raises_no_answer_naming_the_executive(self) -> None:
        s = _Session([[], [], [_Reply(ok=b'{"ok":"done"}')]])
        c = tdl_agent.Client("robot", "planner", timeout=0.5, session=s)
        with self.assertRaises(tdl_agent.NoAnswer) as caught:
            c.status()
        self.assertEqual(len(s.queries), 2, "asked twice, no more")
        self.assertIn(
            "no executive `main` of system `robot` answered within 0.5 s", str(caught.exception)
        )

    def test_an_answer_of_another_kind_or_an_error_reply_is_a_protocol_error(self) -> None:
        s = _Session([[_Reply(ok=b'{"ok":"done"}')], [_Reply(err=b"boom")]])
        c = tdl_agent.Client("robot", "planner", session=s)
        with self.assertRaises(tdl_agent.ProtocolError):
            c.start("patrol")
        with self.assertRaises(tdl_agent.ProtocolError) as caught:
            c.unload("patrol")
        self.assertIn("boom", str(caught.exception))

    def test_bad_names_are_refused_before_any_query(self) -> None:
        for system, name, executive in (("robot", "a/b", "main"), ("robot", "*", "main"),
                                        ("", "planner", "main"), ("robot", "planner", "m#")):
            with self.assertRaises(ValueError):
                tdl_agent.Client(system, name, executive=executive, session=_Session([]))


if __name__ == "__main__":
    unittest.main()
