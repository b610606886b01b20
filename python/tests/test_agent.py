"""Unit tests of tdl_agent without a network: the messages' encoding as the Rust side writes and
reads them (crates/tcm-zenoh/src/wire.rs), typed failures, and the agent's exactly-once handling
of messages, driven on an asyncio loop with a publisher that records what it is given, and the
wait of the first messages to an executive until its inbox is known.

Run with ``python -m unittest discover -s python/tests`` (the package ``eclipse-zenoh`` must be
installed: ``tdl_agent`` imports it); crates/tcm-zenoh/tests/it/python.rs runs them in its venv.
"""

from __future__ import annotations

import asyncio
import json
import os
import sys
import types
import unittest
from typing import Any, List

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import tdl_agent  # noqa: E402
from tdl_agent import wire  # noqa: E402


class HardwareFailure(tdl_agent.TaskFailure):
    pass


class ArmFailure(HardwareFailure):
    pass


class NoGrasp(ArmFailure):
    def __init__(self, x: int) -> None:
        super().__init__(f"no grasp at {x}")
        self.x = x


class Renamed(tdl_agent.TaskFailure):
    tdl_name = "SpeechFailed"


class Encoding(unittest.TestCase):
    def test_bodies_are_encoded_as_serde_writes_them(self) -> None:
        # As serde_json writes Msg<ToExec> (internally tagged `kind`, Result as {"Ok"}/{"Err"}).
        self.assertEqual(wire.encode(7, 1, wire.started()), b'{"task":7,"seq":1,"body":{"kind":"started"}}')
        self.assertEqual(
            wire.encode(7, 2, wire.done({"a": [1, 2.5, None]})),
            b'{"task":7,"seq":2,"body":{"kind":"done","result":{"Ok":{"a":[1,2.5,null]}}}}',
        )
        self.assertEqual(
            wire.encode(7, 3, wire.failed(NoGrasp(3).to_failure())),
            b'{"task":7,"seq":3,"body":{"kind":"done","result":{"Err":{"exception":"NoGrasp",'
            b'"message":"no grasp at 3","ancestry":["ArmFailure","HardwareFailure"],"data":{"x":3}}}}}',
        )
        self.assertEqual(wire.encode(1, 4, wire.cancelled()), b'{"task":1,"seq":4,"body":{"kind":"cancelled"}}')
        self.assertEqual(wire.encode(1, 5, wire.heartbeat()), b'{"task":1,"seq":5,"body":{"kind":"heartbeat"}}')
        # As serde writes ToExec::SetState: the value itself (null for unknown).
        self.assertEqual(
            wire.encode(1, 6, wire.set_state("battery", 90.5)),
            b'{"task":1,"seq":6,"body":{"kind":"set_state","var":"battery","value":90.5}}',
        )
        self.assertEqual(
            wire.encode(1, 7, wire.set_state("range", None)),
            b'{"task":1,"seq":7,"body":{"kind":"set_state","var":"range","value":null}}',
        )

    def test_values_json_cannot_say_are_refused(self) -> None:
        with self.assertRaises(ValueError):
            wire.encode(1, 1, wire.done(float("nan")))
        with self.assertRaises(TypeError):
            wire.encode(1, 1, wire.done(object()))

    def test_a_start_written_by_the_executive_reads(self) -> None:
        m = wire.decode(
            b'{"task":3,"seq":1,"body":{"kind":"start","node":12,"name":"speak",'
            b'"task_kind":"command","args":"hello"}}'
        )
        self.assertEqual((m.task, m.seq, m.kind), (3, 1, "start"))
        self.assertEqual(wire.start_fields(m), (12, "speak", "command", "hello"))
        self.assertEqual(wire.decode(b'{"task":3,"seq":2,"body":{"kind":"cancel"}}').kind, "cancel")

    def test_json_nested_past_the_recursion_limit_is_malformed(self) -> None:
        deep = b'{"task":1,"seq":1,"body":' + b"[" * 200_000 + b"]" * 200_000 + b"}"
        with self.assertRaises(wire.MalformedMessage):
            wire.decode(deep)

    def test_a_refusal_has_the_rust_shape(self) -> None:
        self.assertEqual(
            wire.refused("py", "slow", "too many").to_json(),
            {"exception": "RemoteRefused", "message": "agent py refused to start slow: too many",
             "ancestry": ["RemoteError"], "data": {"agent": "py", "task": "slow", "reason": "too many"}},
        )

    def test_malformed_messages_are_refused(self) -> None:
        for bad in [b"", b"[]", b"{", b'{"task":-1,"seq":1,"body":{"kind":"cancel"}}',
                    b'{"task":1,"seq":true,"body":{"kind":"cancel"}}', b'{"task":1,"seq":1,"body":{}}',
                    b"\xff"]:
            with self.assertRaises(wire.MalformedMessage, msg=repr(bad)):
                wire.decode(bad)
        with self.assertRaises(wire.MalformedMessage):
            wire.start_fields(wire.decode(b'{"task":1,"seq":1,"body":{"kind":"start","name":"x"}}'))

    def test_a_tls_config_names_the_certificates_and_asks_for_the_peers(self) -> None:
        text = str(tdl_agent.loopback_tls_config(7447, "/c/ca.pem", "/c/me.pem", "/c/me.key"))
        for part in ("tls/127.0.0.1:7447", "/c/ca.pem", "/c/me.pem", "/c/me.key"):
            self.assertIn(part, text)

    def test_keys_and_names(self) -> None:
        self.assertEqual(wire.agent_token("robot", "voice"), "tdl/robot/agents/voice")
        self.assertEqual(wire.offer_token("robot", "speak", "voice"), "tdl/robot/offers/speak/voice")
        self.assertEqual(wire.agent_inboxes("robot", "voice"), "tdl/robot/to-agent/voice/*")
        self.assertEqual(wire.executive_inbox("robot", "abc", "py"), "tdl/robot/to-exec/abc/py")
        self.assertTrue(wire.valid_name("arm-1.left_2"))
        for bad in ["", "a/b", "a*", "$x", "a b", "a?", "a#", "é"]:
            self.assertFalse(wire.valid_name(bad), bad)


class Failures(unittest.TestCase):
    def test_a_task_failure_keeps_its_name_ancestry_and_value(self) -> None:
        f = NoGrasp(4).to_failure()
        self.assertEqual((f.exception, f.message, f.ancestry, f.data),
                         ("NoGrasp", "no grasp at 4", ["ArmFailure", "HardwareFailure"], {"x": 4}))
        r = Renamed("mute").to_failure()
        self.assertEqual((r.exception, r.ancestry, r.data), ("SpeechFailed", [], None))

    def test_a_remote_error_has_the_rust_shape(self) -> None:
        self.assertEqual(wire.remote_error("oops").to_json(),
                         {"exception": "RemoteError", "message": "oops", "ancestry": [], "data": {"message": "oops"}})


class Recorder:
    """A publisher that keeps what it is given, decoded."""

    def __init__(self) -> None:
        self.sent: List[Any] = []

    def put(self, data: bytes) -> None:
        m = json.loads(data)
        self.sent.append((m["task"], m["seq"], m["body"]))


class ExactlyOnce(unittest.TestCase):
    def setUp(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.agent = tdl_agent.Agent("sys", "py")
        self.out = Recorder()
        self.cleanups: List[Any] = []
        self.runs = 0

        async def slow(ctx: tdl_agent.TaskContext, ms: int) -> int:
            self.runs += 1
            await asyncio.sleep(ms / 1000)
            return ms

        async def cleanup(ms: int) -> None:
            self.cleanups.append(ms)

        self.agent.command("slow", slow, on_terminate=cleanup)
        self.agent.goal("fail", lambda ctx, x: (_ for _ in ()).throw(NoGrasp(x)))
        self.agent._loop = self.loop
        self.agent._live.add("exec1")
        self.agent._publisher = lambda executive: self.out  # type: ignore[method-assign]

    def tearDown(self) -> None:
        self.loop.close()

    def deliver(self, task: int, seq: int, body: Any) -> None:
        self.agent._receive("exec1", wire.encode(task, seq, body))

    def settle(self) -> None:
        self.loop.run_until_complete(asyncio.sleep(0.05))

    def test_a_body_sets_state_in_order_with_its_other_messages(self) -> None:
        async def sense(ctx: tdl_agent.TaskContext, _: Any) -> None:
            ctx.set_state("battery", 20.0)
            ctx.set_state("battery", 90.0)
            with self.assertRaises(ValueError):
                ctx.set_state("battery", float("nan"))

        self.agent.command("sense", sense)
        self.deliver(2, 1, wire.start(6, "sense", "command", None))
        self.settle()
        self.assertEqual(self.out.sent, [
            (2, 1, {"kind": "started"}),
            (2, 2, {"kind": "set_state", "var": "battery", "value": 20.0}),
            (2, 3, {"kind": "set_state", "var": "battery", "value": 90.0}),
            (2, 4, {"kind": "done", "result": {"Ok": None}}),
        ])

    def test_a_duplicated_start_runs_the_body_once(self) -> None:
        self.deliver(1, 1, wire.start(5, "slow", "command", 1))
        self.deliver(1, 1, wire.start(5, "slow", "command", 1))
        self.settle()
        self.assertEqual(self.runs, 1)
        self.assertEqual(self.out.sent, [(1, 1, {"kind": "started"}),
                                         (1, 2, {"kind": "done", "result": {"Ok": 1}})])
        self.assertEqual(self.agent.stats.duplicates, 1)
        # A cancel after the end is late (its number is above the last one applied).
        self.deliver(1, 2, wire.cancel())
        self.assertEqual((self.agent.stats.late, self.cleanups), (1, []))

    def test_a_cancel_aborts_runs_the_cleanup_and_confirms_once(self) -> None:
        self.deliver(2, 1, wire.start(6, "slow", "command", 10_000))
        self.settle()
        self.deliver(2, 2, wire.cancel())
        self.deliver(2, 2, wire.cancel())
        self.settle()
        self.assertEqual(self.cleanups, [10_000])
        self.assertEqual(self.out.sent, [(2, 1, {"kind": "started"}), (2, 2, {"kind": "cancelled"})])
        self.assertEqual((self.agent.stats.cancelled, self.agent.stats.duplicates), (1, 1))
        self.assertEqual(self.agent.running(), 0)

    def test_a_typed_failure_an_unknown_task_and_a_wrong_kind_come_back_as_failures(self) -> None:
        self.deliver(3, 1, wire.start(7, "fail", "goal", 9))
        self.deliver(4, 1, wire.start(8, "nothing", "command", None))
        self.deliver(5, 1, wire.start(9, "slow", "goal", 1))
        self.settle()
        errs = {t: b["result"]["Err"] for (t, _, b) in self.out.sent if b["kind"] == "done"}
        self.assertEqual((errs[3]["exception"], errs[3]["data"]), ("NoGrasp", {"x": 9}))
        self.assertEqual(errs[4]["exception"], "RemoteError")
        self.assertIn("does not offer nothing", errs[4]["message"])
        self.assertIn("another kind", errs[5]["message"])

    def test_a_huge_sequence_number_cannot_hide_the_executives_cancel(self) -> None:
        # A forged reply numbered 2^64-1 would make every later message a duplicate.
        self.deliver(7, 1, wire.start(11, "slow", "command", 30_000))
        self.settle()
        self.deliver(7, 2**64 - 1, {"kind": "reply", "call": 1, "result": {"Ok": {"answer": "done"}}})
        self.assertEqual((self.agent.stats.refused, self.agent.running()), (1, 1))
        self.deliver(7, 2, wire.cancel())
        self.settle()
        self.assertEqual(self.cleanups, [30_000])
        self.assertEqual(self.out.sent, [(7, 1, {"kind": "started"}), (7, 2, {"kind": "cancelled"})])
        self.assertEqual((self.agent.stats.cancelled, self.agent.stats.duplicates), (1, 0))

    def test_a_gap_in_the_numbers_is_refused_and_changes_nothing(self) -> None:
        self.deliver(8, 1, wire.start(12, "slow", "command", 30_000))
        self.settle()
        self.deliver(8, 3, wire.cancel())
        self.settle()
        self.assertEqual((self.agent.stats.refused, self.agent.running(), self.cleanups), (1, 1, []))
        self.deliver(8, 2, wire.cancel())
        self.settle()
        self.assertEqual((self.agent.stats.cancelled, self.cleanups), (1, [30_000]))

    def test_reattach_is_answered_outside_the_sequence_with_where_the_task_stands(self) -> None:
        # Running: `attached`, numbered 0, with the executive's last message applied and ours.
        self.deliver(10, 1, wire.start(14, "slow", "command", 30_000))
        self.settle()
        self.deliver(10, 0, wire.reattach())
        self.assertEqual(self.out.sent[-1], (10, 0, wire.attached(1, 1)))
        self.assertEqual(self.agent.stats.reattached, 1)
        # Nothing else moved: the executive's cancel, number 2, is still the next one.
        self.deliver(10, 2, wire.cancel())
        self.settle()
        self.assertEqual((self.agent.stats.cancelled, self.agent.stats.refused), (1, 0))
        # Ended (this agent keeps no ends): `unattached`, had it.
        self.deliver(10, 0, wire.reattach())
        task, seq, body = self.out.sent[-1]
        self.assertEqual((task, seq, body["kind"], body["started"]), (10, 0, "unattached", True))
        # Never started here: `unattached`, never had it, so the executive sends its start.
        self.deliver(11, 0, wire.reattach())
        task, seq, body = self.out.sent[-1]
        self.assertEqual((task, seq, body["kind"], body["started"]), (11, 0, "unattached", False))
        self.assertIn("never had task 11", body["reason"])
        self.assertEqual(self.agent.stats.malformed, 0)

    def test_a_message_of_unknown_kind_does_not_advance_the_sequence(self) -> None:
        self.deliver(9, 1, wire.start(13, "slow", "command", 30_000))
        self.settle()
        self.deliver(9, 2, {"kind": "bogus"})
        self.assertEqual((self.agent.stats.malformed, self.agent.running()), (1, 1))
        # The executive's cancel, number 2, is still the next one.
        self.deliver(9, 2, wire.cancel())
        self.settle()
        self.assertEqual((self.agent.stats.cancelled, self.agent.stats.duplicates), (1, 0))
        self.assertEqual(self.cleanups, [30_000])

    def test_a_start_from_an_executive_that_is_not_live_waits_for_its_token_or_is_refused(self) -> None:
        self.agent._receive("made-up", wire.encode(1, 1, wire.start(1, "slow", "command", 1)))
        self.settle()
        # Waiting for the token; when the wait ends without it, refused, unanswered.
        self.assertEqual((self.agent.stats.strangers, self.runs, self.out.sent), (0, 0, []))
        self.agent._unpark("made-up")
        self.assertEqual((self.agent.stats.strangers, self.runs, self.out.sent), (1, 0, []))
        # A start whose executive's token comes while it waits runs.
        self.agent._receive("late", wire.encode(1, 1, wire.start(1, "slow", "command", 1)))
        self.agent._executive_up("late")
        self.settle()
        self.assertEqual((self.agent.stats.strangers, self.runs), (1, 1))
        # Past so many waiting at once, refused at once.
        for task in range(tdl_agent.PARKED + 1):
            self.agent._receive("flood", wire.encode(task, 1, wire.start(1, "slow", "command", 1)))
        self.assertEqual(self.agent.stats.strangers, 2)

    def test_json_nested_too_deep_is_counted_as_malformed(self) -> None:
        self.agent._receive("exec1", b"[" * 200_000 + b"]" * 200_000)
        self.assertEqual((self.agent.stats.malformed, self.out.sent), (1, []))

    def test_a_start_not_numbered_1_is_refused_and_the_task_stays_unknown(self) -> None:
        self.deliver(10, 2**64 - 1, wire.start(14, "slow", "command", 1))
        self.settle()
        self.assertEqual((self.agent.stats.refused, self.runs, self.out.sent), (1, 0, []))
        self.deliver(10, 1, wire.start(14, "slow", "command", 1))
        self.settle()
        self.assertEqual(self.runs, 1)
        self.assertEqual(self.out.sent, [(10, 1, {"kind": "started"}), (10, 2, {"kind": "done", "result": {"Ok": 1}})])

    def test_an_executive_that_goes_orphans_its_bodies_with_cleanup(self) -> None:
        self.deliver(6, 1, wire.start(10, "slow", "command", 20_000))
        self.settle()
        self.agent._executive_gone("exec1")
        self.settle()
        self.assertEqual((self.agent.stats.orphaned, self.cleanups), (1, [20_000]))
        self.assertEqual(self.out.sent, [(6, 1, {"kind": "started"})])


class Hold(unittest.TestCase):
    """With a hold, an executive's bodies outlive its token for a while: one re-attached in time
    runs on, one that ended meanwhile gives its kept end, one not re-attached is aborted and
    cleaned up when the hold ends (docs/distributed.md, "An executive that comes back")."""

    def setUp(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.agent = tdl_agent.Agent("sys", "py", hold=0.3)
        self.out = Recorder()
        self.cleanups: List[Any] = []

        async def slow(ctx: tdl_agent.TaskContext, ms: int) -> int:
            await asyncio.sleep(ms / 1000)
            return ms

        async def cleanup(ms: int) -> None:
            self.cleanups.append(ms)

        self.agent.command("slow", slow, on_terminate=cleanup)
        self.agent._loop = self.loop
        self.agent._live.add("exec1")
        self.agent._publisher = lambda executive: self.out  # type: ignore[method-assign]

    def tearDown(self) -> None:
        for r in self.agent._running.values():
            if r.task is not None:
                r.task.cancel()
        self.loop.run_until_complete(asyncio.sleep(0.01))
        self.loop.close()

    def deliver(self, task: int, seq: int, body: Any) -> None:
        self.agent._receive("exec1", wire.encode(task, seq, body))

    def wait(self, seconds: float) -> None:
        self.loop.run_until_complete(asyncio.sleep(seconds))

    def test_bodies_outlive_their_executive_for_the_hold_and_reattach_with_their_ends(self) -> None:
        self.deliver(1, 1, wire.start(11, "slow", "command", 20_000))  # re-attached while running
        self.deliver(2, 1, wire.start(12, "slow", "command", 50))  # ends while the executive is away
        self.deliver(3, 1, wire.start(13, "slow", "command", 20_000))  # never re-attached
        self.wait(0.02)
        self.agent._executive_gone("exec1")
        self.wait(0.1)
        # Nothing was aborted; the short body ended, and its `done` went out (to be lost).
        self.assertEqual((self.agent.stats.orphaned, self.cleanups), (0, []))
        self.assertIn((2, 2, wire.done(50)), self.out.sent)
        # The executive comes back under the same id and re-attaches to tasks 1 and 2.
        self.agent._executive_up("exec1")
        self.deliver(1, 0, wire.reattach())
        self.assertEqual(self.out.sent[-1], (1, 0, wire.attached(1, 1)))
        self.deliver(2, 0, wire.reattach())
        self.assertEqual(self.out.sent[-1], (2, 0, wire.attached(1, 2, {"Ok": 50})))
        self.assertEqual(self.agent.stats.reattached, 2)
        # The hold ends: task 3, never re-attached, is aborted and cleaned up; task 1 runs on.
        self.wait(0.3)
        self.assertEqual((self.agent.stats.orphaned, self.cleanups), (1, [20_000]))
        self.assertIn((1, "exec1"), [(k[1], k[0]) for k in self.agent._running])
        self.assertNotIn(("exec1", 3), self.agent._running)
        self.deliver(3, 0, wire.reattach())
        task, seq, body = self.out.sent[-1]
        self.assertEqual((task, seq, body["kind"], body["started"]), (3, 0, "unattached", True))
        self.assertIn("aborted when its hold ended", body["reason"])
        # Task 1 follows its sequence on: the executive's cancel, number 2, applies.
        self.deliver(1, 2, wire.cancel())
        self.wait(0.05)
        self.assertEqual(self.agent.stats.cancelled, 1)
        self.assertEqual(self.out.sent[-1], (1, 2, wire.cancelled()))

    def test_an_executive_that_goes_again_ends_the_first_absence_only_with_the_second(self) -> None:
        self.deliver(1, 1, wire.start(11, "slow", "command", 20_000))
        self.wait(0.02)
        self.agent._executive_gone("exec1")
        self.wait(0.2)
        # Back, re-attached, and gone again before the first hold would have ended.
        self.agent._executive_up("exec1")
        self.deliver(1, 0, wire.reattach())
        self.agent._executive_gone("exec1")
        self.wait(0.15)
        # The first absence's hold has ended: it ends nothing, the second one's has not.
        self.assertEqual(self.agent.stats.orphaned, 0)
        self.wait(0.2)
        self.assertEqual((self.agent.stats.orphaned, self.cleanups), (1, [20_000]))

    def test_the_attached_answer_with_an_end_is_encoded_as_serde_writes_it(self) -> None:
        self.assertEqual(
            wire.encode(4, 0, wire.attached(1, 2, {"Ok": 50})),
            b'{"task":4,"seq":0,"body":{"kind":"attached","received":1,"sent":2,"done":{"Ok":50}}}',
        )


class Bounds(unittest.TestCase):
    """Starts past a bound are refused with ``RemoteRefused``; publishers are kept only for live
    executives, at most so many, and released when their token goes."""

    def setUp(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.agent = tdl_agent.Agent(
            "sys", "py", max_bodies_per_executive=2, max_bodies=3, max_threads=1, max_executives=1
        )
        self.gate = __import__("threading").Event()

        async def slow(ctx: tdl_agent.TaskContext, ms: int) -> int:
            await asyncio.sleep(ms / 1000)
            return ms

        def blocking(ctx: tdl_agent.TaskContext, _: Any) -> str:
            self.gate.wait(10)
            return "unblocked"

        self.agent.command("slow", slow)
        self.agent.command("blocking", blocking)
        self.agent._loop = self.loop
        # Live executives (their tokens seen), whose publishers are declared on first use.
        self.agent._live.update({"e1", "e2", "e3"})
        # What leaves, by executive: through a publisher (`out`) or a put of the session (`put`).
        self.sent: List[Any] = []
        self.declared: List[str] = []
        test = self

        class Pub(FakePublisher):
            def __init__(self, key: str) -> None:
                super().__init__(True)
                self.key = key

            def put(self, data: bytes) -> None:
                test.sent.append(("out", self.key, json.loads(data)))

            def undeclare(self) -> None:
                test.declared.remove(self.key)

        def declare(key: str, congestion_control: Any) -> Any:
            self.declared.append(key)
            return Pub(key)

        def put(key: str, data: bytes, congestion_control: Any) -> None:
            self.sent.append(("put", key, json.loads(data)))

        self.agent._session = types.SimpleNamespace(declare_publisher=declare, put=put)  # type: ignore[assignment]

    def tearDown(self) -> None:
        self.gate.set()
        for r in self.agent._running.values():
            if r.task is not None:
                r.task.cancel()
        self.loop.run_until_complete(asyncio.sleep(0.01))
        self.agent._session = None
        self.agent._executor.shutdown(wait=True)
        self.loop.close()

    def deliver(self, executive: str, task: int, body: Any) -> None:
        self.agent._receive(executive, wire.encode(task, 1, body))

    def settle(self) -> None:
        self.loop.run_until_complete(asyncio.sleep(0.05))

    def refusals(self) -> List[Any]:
        return [(k.split("/")[3], m["task"], m["body"]["result"]["Err"]["data"]["reason"])
                for (_, k, m) in self.sent
                if m["body"]["kind"] == "done" and "Err" in m["body"]["result"]
                and m["body"]["result"]["Err"]["exception"] == "RemoteRefused"]

    def test_starts_past_the_bounds_on_bodies_are_refused_with_remote_refused(self) -> None:
        for task in (1, 2, 3):
            self.deliver("e1", task, wire.start(task, "slow", "command", 60_000))
        self.settle()
        self.assertEqual(self.agent.running(), 2)
        self.assertEqual([(e, t) for (e, t, _) in self.refusals()], [("e1", 3)])
        self.assertIn("for this executive", self.refusals()[0][2])
        # Another executive may still start one; then the agent's total bound is reached.
        self.deliver("e2", 1, wire.start(1, "slow", "command", 60_000))
        self.deliver("e3", 1, wire.start(1, "slow", "command", 60_000))
        self.settle()
        self.assertEqual(self.agent.running(), 3)
        self.assertEqual([(e, t) for (e, t, _) in self.refusals()], [("e1", 3), ("e3", 1)])
        self.assertEqual(self.agent.stats.over_limit, 2)
        # A refused start is remembered: sent again, it is a duplicate, not a second refusal.
        self.deliver("e3", 1, wire.start(1, "slow", "command", 60_000))
        self.assertEqual((self.agent.stats.duplicates, self.agent.stats.over_limit), (1, 2))

    def test_threads_are_bounded_and_a_cancelled_threads_body_counts_until_it_returns(self) -> None:
        self.deliver("e1", 1, wire.start(1, "blocking", "command", None))
        self.settle()
        self.agent._receive("e1", wire.encode(1, 2, wire.cancel()))
        self.settle()
        # Cancelled, but its function still runs in its thread: no thread for another.
        self.assertEqual(self.agent.running(), 0)
        self.deliver("e1", 2, wire.start(2, "blocking", "command", None))
        self.settle()
        self.assertEqual([(e, t) for (e, t, _) in self.refusals()], [("e1", 2)])
        self.assertIn("worker threads", self.refusals()[0][2])
        # A coroutine body needs no thread.
        self.deliver("e1", 3, wire.start(3, "slow", "command", 1))
        self.gate.set()
        for _ in range(40):
            self.settle()
            if self.agent._threads == 0:
                break
        self.assertEqual(self.agent._threads, 0)
        self.deliver("e1", 4, wire.start(4, "blocking", "command", None))
        self.settle()
        self.settle()
        done = [m["body"] for (_, _, m) in self.sent if m["task"] == 4 and m["body"]["kind"] == "done"]
        self.assertEqual(done, [{"kind": "done", "result": {"Ok": "unblocked"}}])

    def test_publishers_are_kept_for_live_executives_only_at_most_so_many_and_released(self) -> None:
        self.agent._executive_up("e1")
        self.agent._executive_up("e2")
        # One publisher at most.
        self.assertEqual(self.declared, ["tdl/sys/to-exec/e1/py"])
        self.assertIsNone(self.agent._publisher("e2"))
        self.sent.clear()
        self.deliver("e1", 1, wire.start(1, "slow", "command", 1))
        self.deliver("e2", 1, wire.start(1, "slow", "command", 1))
        self.settle()
        self.assertEqual({(how, k.split("/")[3]) for (how, k, _) in self.sent},
                         {("out", "e1"), ("put", "e2")})
        self.agent._executive_gone("e1")
        self.assertEqual(self.declared, [])
        self.assertEqual(self.agent._publishers, {})


class FakePublisher:
    """A publisher whose matching status the test sets, keeping what is put."""

    def __init__(self, matching: bool) -> None:
        self.sent: List[bytes] = []
        self.matching = matching
        self.handler: Any = None

    @property
    def matching_status(self) -> Any:
        return types.SimpleNamespace(matching=self.matching)

    def declare_matching_listener(self, handler: Any) -> Any:
        self.handler = handler
        return types.SimpleNamespace(undeclare=lambda: None)

    def put(self, data: bytes) -> None:
        self.sent.append(data)


class Reach(unittest.TestCase):
    def setUp(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.agent = tdl_agent.Agent("sys", "py")
        self.agent._loop = self.loop
        self.publishers: List[FakePublisher] = []
        # Whether a subscriber of the inbox is known when the publisher is declared.
        self.known = False

        def declare(key: str, congestion_control: Any) -> FakePublisher:
            self.assertEqual(key, "tdl/sys/to-exec/exec1/py")
            p = FakePublisher(self.known)
            self.publishers.append(p)
            return p

        self.agent._session = types.SimpleNamespace(declare_publisher=declare)  # type: ignore[assignment]

    def tearDown(self) -> None:
        self.agent._session = None
        self.loop.close()

    def test_messages_wait_until_the_executives_inbox_is_known_then_go_in_order(self) -> None:
        self.agent._executive_up("exec1")
        out = self.agent._publisher("exec1")
        assert out is not None
        out.put(b"1")
        out.put(b"2")
        pub = self.publishers[0]
        self.assertEqual(pub.sent, [])
        pub.matching = True
        pub.handler(types.SimpleNamespace(matching=True))
        self.loop.run_until_complete(asyncio.sleep(0.01))
        out.put(b"3")
        self.assertEqual(pub.sent, [b"1", b"2", b"3"])
        self.assertIs(self.agent._publisher("exec1"), out)
        self.assertEqual(len(self.publishers), 1)

    def test_an_inbox_known_at_once_sends_at_once(self) -> None:
        self.known = True
        self.agent._executive_up("exec1")
        out = self.agent._publisher("exec1")
        assert out is not None
        out.put(b"1")
        self.assertEqual(self.publishers[0].sent, [b"1"])
        self.assertIsNone(self.publishers[0].handler)


if __name__ == "__main__":
    unittest.main()
