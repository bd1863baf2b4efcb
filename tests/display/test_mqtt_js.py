"""mqtt.js's packet parser in real Chromium: packets split across WebSocket messages, several packets in
one message, multi-byte remaining lengths, QoS 1 acknowledgements — byte streams mosquitto may send."""

from __future__ import annotations

from typing import Any

import pytest

from mav_motor_health.publish.web.server import static_text

pytestmark = pytest.mark.timeout(60)

# Build PUBLISH packets in the page and feed them to MmhMqttSubscriber.receive() in chosen chunks.
HARNESS = """
(chunking) => {
  const got = [];
  const sent = [];
  const client = new MmhMqttSubscriber("ws://unused", {onMessage: (t, p, r) => got.push([t, p, r])});
  client.send = (bytes) => sent.push(Array.from(bytes));
  const enc = new TextEncoder();
  function publish(topic, payload, qos, retain, id) {
    const t = enc.encode(topic), p = enc.encode(payload);
    const body = [t.length >> 8, t.length & 255, ...t];
    if (qos > 0) body.push(id >> 8, id & 255);
    body.push(...p);
    const len = [];
    let n = body.length;
    do { let d = n % 128; n = Math.floor(n / 128); if (n > 0) d |= 128; len.push(d); } while (n > 0);
    return [0x30 | (qos << 1) | (retain ? 1 : 0), ...len, ...body];
  }
  const big = "x".repeat(20000);  // 3-byte remaining length
  const stream = [
    ...publish("mmh/a/status", '{"online":true}', 1, true, 7),
    ...publish("mmh/a/motor/4/state", '{"state":"F3.1"}', 0, false, 0),
    ...publish("mmh/a/events", '{"big":"' + big + '"}', 1, false, 300),
    0xd0, 0x00,  // PINGRESP
  ];
  for (let at = 0; at < stream.length; ) {
    const size = chunking === "bytewise" ? 1 : chunking === "whole" ? stream.length : 1 + ((at * 7919) % 97);
    client.receive(new Uint8Array(stream.slice(at, at + size)));
    at += size;
  }
  return {got: got.map(([t, p, r]) => [t, p.length, r]), sent: sent, buffered: client.buffer.length};
}
"""


@pytest.mark.parametrize("chunking", ["whole", "bytewise", "ragged"])
def test_parser_reassembles_the_byte_stream(page: Any, chunking: str) -> None:
    page.set_content("<!doctype html><html><body></body></html>")
    page.add_script_tag(content=static_text("mqtt.js"))
    out = page.evaluate(HARNESS, chunking)
    assert out["got"] == [
        ["mmh/a/status", len('{"online":true}'), True],
        ["mmh/a/motor/4/state", len('{"state":"F3.1"}'), False],
        ["mmh/a/events", len('{"big":""}') + 20000, False],
    ]
    # QoS 1 deliveries acknowledged with their packet ids (PUBACK), nothing else sent (never a PUBLISH)
    assert out["sent"] == [[0x40, 2, 0, 7], [0x40, 2, 1, 44]]
    assert out["buffered"] == 0


def test_event_dedupe_in_the_page_follows_the_python_rules(page: Any) -> None:
    """MmhEventDedupe (the display's) decides as EventDedupe (the package's) on the same stream: repeats,
    a restarted agent's new run_id, late events within and beyond the window, events without a seq."""
    from mav_motor_health.publish.mqtt import EventDedupe

    stream: list[dict[str, Any]] = [{"run_id": "a", "seq": s} for s in (1, 2, 2, 5, 3, 3, 1, 9, 4, 5, 10)]
    stream += [{"run_id": "b", "seq": 1}, {"run_id": "a", "seq": 10}, {"run_id": "b", "seq": 1}]
    stream += [{"motor": 1}, {"motor": 1}, {"run_id": "a", "seq": 2.5}, {"run_id": "", "seq": 1}]
    stream += [{"run_id": "c", "seq": 1}, {"run_id": "a", "seq": 10}, {"run_id": "b", "seq": 2}]
    stream += [{"run_id": "d", "seq": s} for s in (*range(1, 30), 20, 21, 22, 28)]
    python = EventDedupe(window=4, runs=2)
    expected = [python.accept(e) for e in stream]
    page.set_content("<!doctype html><html><body></body></html>")
    page.add_script_tag(content=static_text("mqtt.js"))
    got = page.evaluate(
        "(stream) => { const d = new MmhEventDedupe(4, 2); return stream.map((e) => d.accept(e)); }", stream
    )
    assert got == expected
    assert expected.count(False) >= 8  # the stream does exercise the drops
