"""Events carry ``run_id`` and ``seq`` because QoS 1 delivers at least once: :class:`EventDedupe`'s rules,
and the numbering as a real Mosquitto delivers it (two agent runs, a resent event)."""

from __future__ import annotations

import asyncio
import re

from agent_parts import MqttListener, until

from mav_motor_health.publish.mqtt import EventDedupe, MqttPublisher, MqttSettings, event_key, new_run_id


def ev(run_id: str, seq: int) -> dict[str, object]:
    return {"motor": 1, "state": "F3.1", "previous": "NORMAL", "run_id": run_id, "seq": seq}


def accepted(dedupe: EventDedupe, events: list[dict[str, object]]) -> list[tuple[object, object]]:
    return [(e.get("run_id"), e.get("seq")) for e in events if dedupe.accept(e)]


def test_dedupe_drops_repeats_of_one_run():
    dedupe = EventDedupe()
    stream = [ev("a", 1), ev("a", 2), ev("a", 2), ev("a", 3), ev("a", 1), ev("a", 3)]
    assert accepted(dedupe, stream) == [("a", 1), ("a", 2), ("a", 3)]
    assert dedupe.dropped == 3


def test_dedupe_takes_a_new_run_id_as_a_restarted_agent():
    dedupe = EventDedupe()
    # the agent restarts: seq begins at 1 again under a new run id; a late repeat of the old run still goes
    stream = [ev("a", 1), ev("a", 2), ev("b", 1), ev("a", 2), ev("b", 2), ev("b", 1)]
    assert accepted(dedupe, stream) == [("a", 1), ("a", 2), ("b", 1), ("b", 2)]


def test_dedupe_accepts_late_and_missing_seq_within_the_window_only():
    dedupe = EventDedupe(window=4)
    # a gap (events lost in a full outbox) is accepted; a late event within the window is news
    assert accepted(dedupe, [ev("a", 1), ev("a", 5), ev("a", 3), ev("a", 3)]) == [
        ("a", 1),
        ("a", 5),
        ("a", 3),
    ]
    # the window is the 4 numbers up to the highest (2..5); 1 lies further back: no record left, dropped
    assert accepted(dedupe, [ev("a", 2), ev("a", 1), ev("a", 4)]) == [("a", 2), ("a", 4)]
    # the window moves with the highest, and memory stays bounded
    accepted(dedupe, [ev("a", k) for k in range(6, 200)])
    assert accepted(dedupe, [ev("a", 195), ev("a", 196), ev("a", 200)]) == [("a", 200)]
    assert len(dedupe._seen["a"].seqs) <= 2 * dedupe.window + 1


def test_dedupe_passes_events_without_a_sequence_and_forgets_old_runs():
    dedupe = EventDedupe(runs=2)
    old = {"motor": 1, "state": "F3.1", "previous": "NORMAL"}  # an agent from before run_id/seq
    assert dedupe.accept(old) and dedupe.accept(old)
    assert event_key(old) is None
    assert event_key({"run_id": "a", "seq": True}) is None  # a bool is no sequence number
    assert event_key({"run_id": "a", "seq": 3}) == ("a", 3)
    assert accepted(dedupe, [ev("a", 1), ev("b", 1), ev("a", 1), ev("c", 1), ev("a", 1)]) == [
        ("a", 1),
        ("b", 1),
        ("c", 1),
    ]
    assert accepted(dedupe, [ev("b", 1)]) == [("b", 1)]  # b was the least recently heard: forgotten


def test_run_ids_differ_and_say_when_the_run_began():
    a, b = new_run_id(), new_run_id()
    assert a != b
    assert re.fullmatch(r"\d{8}T\d{6}Z-[0-9a-f]{8}", a), a


def test_events_over_mosquitto_carry_increasing_seq_per_run(broker):
    """Two publisher runs (an agent restarted) and one event sent twice, as the outbox does when a PUBACK
    was lost; the listener (real Mosquitto, QoS 1, persistent session) gets the repeat, the dedupe drops it."""
    listener = MqttListener(broker.port, "mmh/seqtest/#", client_id="listener-seq")
    settings = MqttSettings(host="127.0.0.1", port=broker.port, vehicle_id="seqtest", reconnect_min_s=0.1)

    async def run(events: list[tuple[int, str]], resend_second: bool = False) -> str:
        async with MqttPublisher(settings) as mqtt:
            for motor, state in events:
                mqtt.event({"t_s": 1.0, "motor": motor, "state": state, "previous": "NORMAL"})
            if resend_second:
                sent = [m for m in mqtt.outbox.events if b'"seq":2' in m.payload]
                mqtt.outbox.put_event(sent[0].topic, sent[0].payload)
            assert await mqtt.flush(10)
            return mqtt.run_id

    async def main() -> tuple[str, str]:
        first = await run([(4, "F3.1"), (2, "F2.1"), (4, "NORMAL")], resend_second=True)
        await until(lambda: len(listener.on("seqtest/events")) == 4, 10, "four deliveries of run 1")
        second = await run([(4, "F3.1"), (1, "F1.1")])
        await until(lambda: len(listener.on("seqtest/events")) == 6, 10, "two events of run 2")
        return first, second

    try:
        first, second = asyncio.run(main())
    finally:
        listener.close()
    raw = [(p["run_id"], p["seq"], p["motor"]) for _, p in listener.on("seqtest/events")]
    assert raw == [(first, 1, 4), (first, 2, 2), (first, 3, 4), (first, 2, 2), (second, 1, 4), (second, 2, 1)]
    kept = [(p["run_id"], p["seq"], p["motor"], p["state"]) for p in listener.event_payloads("seqtest")]
    assert kept == [
        (first, 1, 4, "F3.1"),
        (first, 2, 2, "F2.1"),
        (first, 3, 4, "NORMAL"),
        (second, 1, 4, "F3.1"),
        (second, 2, 1, "F1.1"),
    ]
    assert first != second
    # the status topic names the run: online while it runs, offline when it ended cleanly
    statuses = [(p["online"], p["run_id"]) for _, p in listener.on("seqtest/status")]
    assert (True, first) in statuses and (False, first) in statuses and statuses[-1] == (False, second)
