/* A small MQTT 3.1.1 subscriber over WebSocket (subprotocol "mqtt"), no dependencies.
 *
 * Enough for a read-only display: CONNECT (optional username/password), SUBSCRIBE, receive PUBLISH at
 * QoS 0/1/2 (retained included), PINGREQ keep-alive, reconnect with back-off. It never publishes.
 *
 *   const client = new MmhMqttSubscriber(url, {topics: ["mmh/#"], onMessage, onStatus});
 *   client.start();           // connects, and reconnects until stop()
 *   client.setCredentials("viewer", "secret");   // reconnects with them
 *
 * And MmhEventDedupe, which drops an event seen already: QoS 1 delivers at least once.
 *
 *   const dedupe = new MmhEventDedupe();
 *   if (dedupe.accept(event)) { ... }   // false for a repeat of the same (run_id, seq)
 */
(function (global) {
  "use strict";
  if (global.MmhMqttSubscriber) {
    return;
  }
  const CONNACK_REASONS = {
    1: "unacceptable protocol version",
    2: "client identifier rejected",
    3: "broker unavailable",
    4: "bad user name or password",
    5: "not authorised",
  };
  const encoder = new TextEncoder();
  const decoder = new TextDecoder("utf-8");

  function utf8Field(str) {
    const bytes = encoder.encode(str);
    const out = new Uint8Array(2 + bytes.length);
    out[0] = bytes.length >> 8;
    out[1] = bytes.length & 0xff;
    out.set(bytes, 2);
    return out;
  }

  function remainingLength(n) {
    const out = [];
    do {
      let digit = n % 128;
      n = Math.floor(n / 128);
      if (n > 0) {
        digit |= 0x80;
      }
      out.push(digit);
    } while (n > 0);
    return out;
  }

  function packet(firstByte, parts) {
    const body = parts.reduce((len, p) => len + p.length, 0);
    const head = [firstByte].concat(remainingLength(body));
    const out = new Uint8Array(head.length + body);
    out.set(head, 0);
    let at = head.length;
    for (const p of parts) {
      out.set(p, at);
      at += p.length;
    }
    return out;
  }

  function u16(n) {
    return new Uint8Array([n >> 8, n & 0xff]);
  }

  class MmhMqttSubscriber {
    constructor(url, options) {
      const opts = options || {};
      this.url = url;
      this.topics = opts.topics || ["#"];
      this.keepaliveS = opts.keepaliveS || 20;
      this.onMessage = opts.onMessage || function () {};
      this.onStatus = opts.onStatus || function () {};
      this.clientId = opts.clientId || "mmh-display-" + Math.random().toString(36).slice(2, 10);
      this.username = null;
      this.password = null;
      this.ws = null;
      this.buffer = new Uint8Array(0);
      this.nextPacketId = 1;
      this.retryS = 1;
      this.stopped = true;
      this.pingTimer = null;
      this.lastPongMs = 0;
      this.retryTimer = null;
      this.holdReconnect = false;
    }

    start() {
      this.stopped = false;
      this.connect();
    }

    stop() {
      this.stopped = true;
      clearTimeout(this.retryTimer);
      this.teardown(true);
    }

    setCredentials(username, password) {
      this.username = username || null;
      this.password = password || null;
      this.holdReconnect = false;
      this.retryS = 1;
      clearTimeout(this.retryTimer);
      this.teardown(true);
      if (!this.stopped) {
        this.connect();
      }
    }

    status(state, detail) {
      try {
        this.onStatus(state, detail || "");
      } catch (err) {
        console.error(err);
      }
    }

    connect() {
      let ws;
      this.status("connecting", this.url);
      try {
        ws = new WebSocket(this.url, ["mqtt"]);
      } catch (err) {
        this.status("error", String(err));
        this.scheduleReconnect();
        return;
      }
      ws.binaryType = "arraybuffer";
      this.ws = ws;
      this.buffer = new Uint8Array(0);
      ws.onopen = () => this.sendConnect();
      ws.onmessage = (ev) => this.receive(new Uint8Array(ev.data));
      ws.onerror = () => this.status("error", "cannot reach the broker at " + this.url);
      ws.onclose = () => {
        if (this.ws !== ws) {
          return;
        }
        this.teardown(false);
        if (!this.stopped && !this.holdReconnect) {
          this.status("disconnected", "reconnecting in " + this.retryS + " s");
          this.scheduleReconnect();
        }
      };
    }

    scheduleReconnect() {
      clearTimeout(this.retryTimer);
      this.retryTimer = setTimeout(() => {
        if (!this.stopped) {
          this.connect();
        }
      }, this.retryS * 1000);
      this.retryS = Math.min(this.retryS * 2, 15);
    }

    teardown(closeSocket) {
      clearInterval(this.pingTimer);
      this.pingTimer = null;
      const ws = this.ws;
      this.ws = null;
      if (ws && closeSocket) {
        try {
          if (ws.readyState === WebSocket.OPEN) {
            ws.send(new Uint8Array([0xe0, 0x00])); // DISCONNECT
          }
          ws.close();
        } catch (err) {
          /* already closed */
        }
      }
    }

    send(bytes) {
      if (this.ws && this.ws.readyState === WebSocket.OPEN) {
        this.ws.send(bytes);
      }
    }

    sendConnect() {
      let flags = 0x02; // clean session: a display needs no stored session
      const payload = [utf8Field(this.clientId)];
      if (this.username !== null) {
        flags |= 0x80;
        payload.push(utf8Field(this.username));
        if (this.password !== null) {
          flags |= 0x40;
          payload.push(utf8Field(this.password));
        }
      }
      const header = new Uint8Array([0x00, 0x04, 0x4d, 0x51, 0x54, 0x54, 0x04, flags, this.keepaliveS >> 8, this.keepaliveS & 0xff]);
      this.send(packet(0x10, [header].concat(payload)));
    }

    sendSubscribe() {
      const id = this.nextPacketId;
      this.nextPacketId = (this.nextPacketId % 65535) + 1;
      const parts = [u16(id)];
      for (const topic of this.topics) {
        parts.push(utf8Field(topic), new Uint8Array([1]));
      }
      this.send(packet(0x82, parts));
    }

    startKeepalive() {
      this.lastPongMs = Date.now();
      clearInterval(this.pingTimer);
      this.pingTimer = setInterval(() => {
        if (Date.now() - this.lastPongMs > this.keepaliveS * 1500) {
          this.status("disconnected", "broker stopped answering");
          const ws = this.ws;
          this.teardown(false);
          if (ws) {
            ws.close();
          }
          if (!this.stopped) {
            this.scheduleReconnect();
          }
          return;
        }
        this.send(new Uint8Array([0xc0, 0x00])); // PINGREQ
      }, (this.keepaliveS * 1000) / 2);
    }

    receive(chunk) {
      // A WebSocket message may hold part of a packet or several packets: parse a byte stream.
      this.lastPongMs = Date.now(); // any traffic shows the broker is alive
      const joined = new Uint8Array(this.buffer.length + chunk.length);
      joined.set(this.buffer, 0);
      joined.set(chunk, this.buffer.length);
      let at = 0;
      while (joined.length - at >= 2) {
        let multiplier = 1;
        let length = 0;
        let i = at + 1;
        let complete = false;
        for (; i < joined.length && i < at + 5; i++) {
          length += (joined[i] & 0x7f) * multiplier;
          multiplier *= 128;
          if ((joined[i] & 0x80) === 0) {
            complete = true;
            i++;
            break;
          }
        }
        if (!complete || joined.length - i < length) {
          break;
        }
        this.handle(joined[at], joined.subarray(i, i + length));
        at = i + length;
      }
      this.buffer = joined.slice(at);
    }

    handle(first, body) {
      const type = first >> 4;
      if (type === 2) {
        // CONNACK
        const code = body[1];
        if (code === 0) {
          this.retryS = 1;
          this.status("subscribing", this.url);
          this.sendSubscribe();
          this.startKeepalive();
        } else {
          const reason = CONNACK_REASONS[code] || "refused (" + code + ")";
          // Bad credentials will not improve by retrying: wait for new ones.
          this.holdReconnect = code === 4 || code === 5;
          this.status(this.holdReconnect ? "unauthorised" : "error", reason);
          const ws = this.ws;
          this.teardown(false);
          if (ws) {
            ws.close();
          }
          if (!this.holdReconnect && !this.stopped) {
            this.scheduleReconnect();
          }
        }
      } else if (type === 3) {
        // PUBLISH
        const qos = (first >> 1) & 0x03;
        const retained = (first & 0x01) === 1;
        const topicLength = (body[0] << 8) | body[1];
        const topic = decoder.decode(body.subarray(2, 2 + topicLength));
        let at = 2 + topicLength;
        if (qos > 0) {
          const id = (body[at] << 8) | body[at + 1];
          at += 2;
          this.send(packet(qos === 1 ? 0x40 : 0x50, [u16(id)])); // PUBACK / PUBREC
        }
        const payload = decoder.decode(body.subarray(at));
        try {
          this.onMessage(topic, payload, retained);
        } catch (err) {
          console.error("message on " + topic + " not handled:", err);
        }
      } else if (type === 6) {
        // PUBREL (QoS 2) → PUBCOMP
        this.send(packet(0x70, [body.subarray(0, 2)]));
      } else if (type === 9) {
        // SUBACK: 0x80 means the broker (its ACL) refused a filter. Only now is nothing missed.
        const refused = [];
        for (let k = 2; k < body.length; k++) {
          if (body[k] === 0x80) {
            refused.push(this.topics[k - 2]);
          }
        }
        if (refused.length) {
          this.status("error", "subscription refused: " + refused.join(", "));
        } else {
          this.status("connected", this.url);
        }
      } else if (type === 13) {
        this.lastPongMs = Date.now(); // PINGRESP
      }
    }
  }

  /* Drops events seen already, by (run_id, seq). The agent publishes events at QoS 1, delivered at least
   * once: after a broker restart the same event can come twice. A new run_id is a restarted agent whose
   * seq starts at 1 again. The rules are mav_motor_health.publish.mqtt.EventDedupe's (read its docstring):
   * a seq not seen is accepted even below the highest, within `window` of it; further back it is dropped;
   * an event without run_id/seq is always accepted; the `runs` most recently heard runs are remembered. */
  class MmhEventDedupe {
    constructor(windowSize, runs) {
      this.window = windowSize || 1024;
      this.runs = runs || 64;
      this.dropped = 0;
      this.seen = new Map(); // run_id → {highest, seqs}, least recently heard first
    }

    /* True the first time an event is seen (show it), false for a repeat (drop it). */
    accept(event) {
      const runId = event ? event.run_id : undefined;
      const seq = event ? event.seq : undefined;
      if (typeof runId !== "string" || !runId || !Number.isInteger(seq)) {
        return true;
      }
      const run = this.run(runId);
      if (run.seqs.has(seq) || seq <= run.highest - this.window) {
        this.dropped += 1;
        return false;
      }
      run.seqs.add(seq);
      if (seq > run.highest) {
        run.highest = seq;
        if (run.seqs.size > 2 * this.window) {
          run.seqs = new Set([...run.seqs].filter((s) => s > seq - this.window));
        }
      }
      return true;
    }

    /* The run's record, now the most recently heard; the least recent one forgotten past `runs`. */
    run(runId) {
      const run = this.seen.get(runId) || {highest: 0, seqs: new Set()};
      this.seen.delete(runId);
      this.seen.set(runId, run);
      if (this.seen.size > this.runs) {
        this.seen.delete(this.seen.keys().next().value);
      }
      return run;
    }
  }

  global.MmhMqttSubscriber = MmhMqttSubscriber;
  global.MmhEventDedupe = MmhEventDedupe;
})(window);
