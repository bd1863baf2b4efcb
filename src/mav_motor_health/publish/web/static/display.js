/* The live display: subscribes to the agent's MQTT topics (docs/display.md) and draws them.
 * Read-only: it never publishes. Configuration comes from config.json, served next to this file.
 */
(function () {
  "use strict";
  const VEHICLE_ID = /^[A-Za-z0-9_-]+$/;
  const KIND_RANK = {fault: 4, sensor: 3, nodata: 2, ok: 1, waiting: 0};
  const $ = (id) => document.getElementById(id);

  function fmt(value, digits) {
    return typeof value === "number" && isFinite(value) ? value.toFixed(digits) : "–";
  }

  function utcClock(iso) {
    const d = new Date(iso);
    return isNaN(d) ? "" : d.toISOString().slice(11, 19) + "Z";
  }

  function newVehicle(id) {
    // dedupe: QoS 1 may deliver an event twice (after a broker restart); the log shows it once
    return {id: id, status: null, info: null, lastLiveMs: null, events: [], dedupe: new MmhEventDedupe(), motors: new Map()};
  }

  function newMotor() {
    return {state: null, lastLiveMs: null, lastTelemetryMs: null, samples: [], last: null};
  }

  class Display {
    constructor(cfg) {
      this.cfg = cfg;
      this.prefix = cfg.topic_prefix;
      this.staleMs = cfg.stale_after_s * 1000;
      this.vehicles = new Map();
      this.selected = new URLSearchParams(location.search).get("vehicle");
      this.connectedAtMs = null;
      this.dirty = true;
      $("chart-window").textContent = String(cfg.chart_window_s);
      this.frame = null;
      this.setFrame(cfg.default_frame);
    }

    /* The frame a vehicle announces in its info topic, if this page can draw it. */
    frameOf(v) {
      const announced = v && v.info && v.info.frame;
      return announced && this.cfg.layouts[announced] ? announced : this.cfg.default_frame;
    }

    /* (Re)build the top view and the motor cards for a frame. */
    setFrame(frame) {
      if (frame === this.frame) {
        return;
      }
      this.frame = frame;
      this.layout = this.cfg.layouts[frame];
      $("hexaview").textContent = "";
      $("hexaview").dataset.frame = frame;
      this.view = MmhHexaView.create($("hexaview"), {layout: this.layout, states: this.cfg.states, title: frame + " top view, nose up"});
      for (const old of $("motor-cards").querySelectorAll(".motor-card")) {
        old.remove();
      }
      this.cards = new Map();
      for (const m of [...this.layout].sort((a, b) => a.motor - b.motor)) {
        this.cards.set(m.motor, this.makeCard(m));
      }
    }

    brokerUrl() {
      if (this.cfg.broker_ws_url) {
        return this.cfg.broker_ws_url;
      }
      const scheme = location.protocol === "https:" ? "wss" : "ws";
      return `${scheme}://${location.hostname || "127.0.0.1"}:${this.cfg.default_ws_port}`;
    }

    start() {
      this.client = new MmhMqttSubscriber(this.brokerUrl(), {
        topics: [this.prefix + "/#"],
        keepaliveS: this.cfg.keepalive_s,
        onMessage: (topic, payload, retained) => this.onMessage(topic, payload, retained),
        onStatus: (state, detail) => this.onStatus(state, detail),
      });
      $("login").addEventListener("submit", (ev) => {
        ev.preventDefault();
        this.client.setCredentials($("login-user").value, $("login-password").value);
        $("login-password").value = "";
        $("login").hidden = true;
      });
      $("login-toggle").addEventListener("click", () => {
        $("login").hidden = !$("login").hidden;
      });
      if (this.cfg.ask_credentials) {
        $("login").hidden = false;
        $("login-reason").textContent = "This display needs a broker user name and password.";
      } else {
        this.client.start();
      }
      this.client.stopped = false;
      setInterval(() => this.render(), 1000);
      // Redraw when something changed, at most five times a second: telemetry of many vehicles
      // must not keep a field laptop's CPU busy.
      let lastRenderMs = 0;
      const frame = (nowMs) => {
        if (this.dirty && nowMs - lastRenderMs >= 200) {
          lastRenderMs = nowMs;
          this.render();
        }
        requestAnimationFrame(frame);
      };
      requestAnimationFrame(frame);
    }

    onStatus(state, detail) {
      const el = $("broker-status");
      el.dataset.state = state;
      el.textContent = state === "connected" ? "broker: connected" : `broker: ${state}${detail ? " — " + detail : ""}`;
      el.title = this.brokerUrl();
      if (state === "connected" && this.connectedAtMs === null) {
        this.connectedAtMs = Date.now();
      }
      if (state === "unauthorised") {
        $("login").hidden = false;
        $("login-reason").textContent = `The broker refused the connection (${detail}). Enter a user name and password.`;
      }
      this.dirty = true;
    }

    onMessage(topic, payload, retained) {
      if (!topic.startsWith(this.prefix + "/")) {
        return;
      }
      const parts = topic.slice(this.prefix.length + 1).split("/");
      const id = parts[0];
      if (!VEHICLE_ID.test(id)) {
        return;
      }
      let msg;
      try {
        msg = JSON.parse(payload);
      } catch (err) {
        console.warn(`${topic}: payload is not JSON`, payload);
        return;
      }
      if (msg === null || typeof msg !== "object") {
        return;
      }
      const now = Date.now();
      let v = this.vehicles.get(id);
      if (!v) {
        v = newVehicle(id);
        this.vehicles.set(id, v);
        if (!this.selected) {
          this.selected = id;
        }
      }
      // Retained messages are history the broker kept; only live ones prove the vehicle is talking now.
      if (!retained) {
        v.lastLiveMs = now;
      }
      const kind = parts.slice(1).join("/");
      if (kind === "status") {
        v.status = msg;
      } else if (kind === "info") {
        v.info = msg;
      } else if (kind === "events") {
        if (!v.dedupe.accept(msg)) {
          return;
        }
        v.events.unshift(msg);
        v.events.length = Math.min(v.events.length, 200);
      } else if (parts[1] === "motor" && parts.length === 4) {
        const n = Number(parts[2]);
        if (!Number.isInteger(n) || n < 1) {
          return;
        }
        if (!v.motors.has(n)) {
          v.motors.set(n, newMotor());
        }
        const m = v.motors.get(n);
        if (!retained) {
          m.lastLiveMs = now;
        }
        if (parts[3] === "state") {
          m.state = msg;
        } else if (parts[3] === "telemetry") {
          m.lastTelemetryMs = now;
          m.last = msg;
          if (typeof msg.t_s === "number") {
            const samples = m.samples;
            if (samples.length && msg.t_s < samples[samples.length - 1].t) {
              samples.length = 0; // vehicle clock restarted (agent restart or a new flight)
            }
            samples.push({t: msg.t_s, w: msg.omega_rad_s, wm: msg.omega_model_rad_s, i: msg.current_a, im: msg.current_model_a});
            const horizon = msg.t_s - this.cfg.chart_window_s;
            while (samples.length && samples[0].t < horizon) {
              samples.shift();
            }
          }
        }
      }
      this.dirty = true;
    }

    /* Why a vehicle shows "no data", or null when it is live. */
    vehicleNoData(v, now) {
      if (v.status && v.status.online === false) {
        return "vehicle offline (agent disconnected)";
      }
      if (v.lastLiveMs === null) {
        if (this.connectedAtMs !== null && now - this.connectedAtMs > this.staleMs) {
          return `nothing live for ${MmhHexaView.formatDuration((now - this.connectedAtMs) / 1000)} (last known state only)`;
        }
        return null;
      }
      if (now - v.lastLiveMs > this.staleMs) {
        return `vehicle silent for ${MmhHexaView.formatDuration((now - v.lastLiveMs) / 1000)}`;
      }
      return null;
    }

    /* What one motor shows: {state, kind, description, since, note}. */
    motorView(v, n, vehicleNoData, now) {
      const m = v.motors.get(n);
      const s = m && m.state;
      const label = s && typeof s.state === "string" ? s.state : "";
      const known = this.cfg.states[label];
      const out = {
        state: label,
        kind: label ? (known ? known.kind : "fault") : "waiting",
        description: (s && s.description) || (known && known.description) || "",
        since: "",
        note: "",
      };
      if (s && s.since_utc && label && label !== "NORMAL") {
        const since = Date.parse(s.since_utc);
        if (!isNaN(since)) {
          out.sinceDuration = MmhHexaView.formatDuration((now - since) / 1000);
          out.since = "for " + out.sinceDuration;
          out.sinceClock = utcClock(s.since_utc);
        }
      }
      if (vehicleNoData) {
        out.kind = "nodata"; // the view's overlay says why; each motor need not repeat it
        out.since = "";
      } else if (label === "NO_DATA") {
        out.note = "motor silent (agent)";
      } else if (m && m.lastTelemetryMs !== null && now - m.lastTelemetryMs > this.staleMs) {
        out.kind = "nodata";
        out.note = "silent " + MmhHexaView.formatDuration((now - m.lastTelemetryMs) / 1000);
      } else if (s && s.fresh === false) {
        out.kind = "nodata";
        out.note = "stale state";
      }
      return out;
    }

    worstKind(v, now) {
      const noData = this.vehicleNoData(v, now);
      if (noData) {
        return "nodata";
      }
      let worst = "waiting";
      for (const m of this.cfg.layouts[this.frameOf(v)]) {
        const k = this.motorView(v, m.motor, null, now).kind;
        if (KIND_RANK[k] > KIND_RANK[worst]) {
          worst = k;
        }
      }
      return worst;
    }

    makeCard(m) {
      const card = document.createElement("article");
      card.className = "motor-card kind-waiting";
      card.dataset.motor = m.motor;
      card.innerHTML =
        `<header><span class="num">M${m.motor}</span><span class="spin">${m.spin}</span>` +
        `<span class="state">—</span><span class="desc"></span><span class="since"></span></header>` +
        `<div class="charts"><figure><figcaption>speed, rad/s</figcaption><canvas class="chart-speed"></canvas></figure>` +
        `<figure><figcaption>current, A</figcaption><canvas class="chart-current"></canvas></figure></div>` +
        `<div class="values"></div>`;
      $("motor-cards").appendChild(card);
      return {
        root: card,
        state: card.querySelector(".state"),
        desc: card.querySelector(".desc"),
        since: card.querySelector(".since"),
        values: card.querySelector(".values"),
        speed: card.querySelector(".chart-speed"),
        current: card.querySelector(".chart-current"),
      };
    }

    renderPicker(now) {
      const picker = $("vehicle-picker");
      const ids = [...this.vehicles.keys()].sort();
      picker.hidden = ids.length < 2;
      const existing = new Map([...picker.querySelectorAll("button")].map((b) => [b.dataset.vehicle, b]));
      for (const id of ids) {
        let b = existing.get(id);
        if (!b) {
          b = document.createElement("button");
          b.type = "button";
          b.dataset.vehicle = id;
          b.addEventListener("click", () => {
            this.selected = id;
            this.dirty = true;
          });
          picker.appendChild(b);
        }
        const kind = this.worstKind(this.vehicles.get(id), now);
        b.className = "kind-" + kind + (id === this.selected ? " selected" : "");
        b.setAttribute("aria-pressed", String(id === this.selected));
        if (b.textContent !== id) b.textContent = id;
      }
      // Reorder only when a vehicle joined: moving a button on every render (five times a second per
      // vehicle) could take it from under a click between the press and the release.
      const shown = [...picker.querySelectorAll("button")].map((b) => b.dataset.vehicle);
      if (shown.join("\n") !== ids.join("\n")) {
        const order = ids.map((id) => existing.get(id) || picker.querySelector(`button[data-vehicle="${id}"]`));
        order.forEach((b) => picker.appendChild(b));
      }
    }

    render() {
      this.dirty = false;
      const now = Date.now();
      this.renderPicker(now);
      // The tab title tells of a fault on any vehicle, even while the window is in the background.
      const faulty = [...this.vehicles.values()].filter((veh) => this.worstKind(veh, now) === "fault").map((veh) => veh.id);
      document.title = faulty.length ? `FAULT ${faulty.sort().join(", ")} — Motor health` : "Motor health";
      const v = this.selected ? this.vehicles.get(this.selected) : null;
      this.setFrame(this.frameOf(v));
      $("vehicle-name").textContent = v ? v.id : "";
      if (!v) {
        this.view.setNoData("no vehicle on the broker yet");
        for (const m of this.layout) {
          this.view.setMotor(m.motor, {state: "", kind: "waiting"});
        }
        return;
      }
      const noData = this.vehicleNoData(v, now);
      this.view.setNoData(noData);
      const info = v.info || {};
      const bits = [v.id];
      if (info.frame) {
        bits.push(info.frame);
      }
      if (info.autopilot) {
        bits.push(info.autopilot);
      }
      if (info.profile) {
        bits.push("profile " + info.profile);
      }
      if (info.params) {
        bits.push("motor " + info.params);
      }
      bits.push(v.lastLiveMs === null ? "no live message yet" : "last message " + MmhHexaView.formatDuration((now - v.lastLiveMs) / 1000) + " ago");
      const summary = $("vehicle-summary");
      summary.textContent = bits.join(" · ");
      summary.dataset.nodata = noData ? "true" : "false";
      if (info.frame && !this.cfg.layouts[info.frame]) {
        summary.textContent += ` · frame "${info.frame}" not drawn: shown as ${this.cfg.default_frame}`;
      }
      for (const m of this.layout) {
        const mv = this.motorView(v, m.motor, noData, now);
        this.view.setMotor(m.motor, {state: mv.state, kind: mv.kind, description: mv.description, since: mv.since, note: mv.note});
        this.renderCard(this.cards.get(m.motor), v.motors.get(m.motor), mv);
      }
      this.renderEvents(v);
    }

    renderCard(card, m, mv) {
      card.root.className = "motor-card kind-" + mv.kind;
      card.root.dataset.state = mv.state;
      card.state.textContent = mv.kind === "nodata" && mv.state !== "NO_DATA" ? "NO DATA" : MmhHexaView.stateText(mv.state);
      card.desc.textContent =
        mv.kind === "nodata" ? `${mv.note || "no data"}${mv.state ? " · last: " + mv.state : ""}` : mv.state === "NORMAL" ? "" : mv.description;
      card.since.textContent = mv.since ? `since ${mv.sinceClock} (${mv.sinceDuration})` : "";
      const last = m && m.last;
      card.values.textContent = last
        ? `ω ${fmt(last.omega_rad_s, 0)} / ${fmt(last.omega_model_rad_s, 0)} rad/s · i ${fmt(last.current_a, 1)} / ${fmt(last.current_model_a, 1)} A · ${fmt(last.voltage_v, 1)} V`
        : "no telemetry";
      const samples = m ? m.samples : [];
      drawChart(card.speed, samples, "w", "wm", this.cfg.chart_window_s);
      drawChart(card.current, samples, "i", "im", this.cfg.chart_window_s);
    }

    renderEvents(v) {
      const body = $("event-log").querySelector("tbody");
      const key = v.id + ":" + v.events.length + ":" + (v.events[0] ? v.events[0].time_utc : "");
      if (body.dataset.key === key) {
        return;
      }
      body.dataset.key = key;
      body.textContent = "";
      if (!v.events.length) {
        const row = body.insertRow();
        const cell = row.insertCell();
        cell.colSpan = 6;
        cell.className = "empty";
        cell.textContent = "no state change since this page opened";
        return;
      }
      for (const e of v.events.slice(0, 50)) {
        const row = body.insertRow();
        const known = this.cfg.states[e.state];
        row.className = "kind-" + (known ? known.kind : "fault");
        const ev = e.evidence || {};
        const cells = [
          utcClock(e.time_utc),
          typeof e.t_s === "number" ? e.t_s.toFixed(1) + " s" : "",
          "M" + e.motor,
          `${e.previous || "?"} → ${e.state}${known && e.state !== "NORMAL" ? " " + known.description : ""}`,
          `${fmt(ev.omega_rad_s, 0)} / ${fmt(ev.omega_model_rad_s, 0)}`,
          `${fmt(ev.current_a, 2)} / ${fmt(ev.current_model_a, 2)}`,
        ];
        for (const c of cells) {
          row.insertCell().textContent = c;
        }
      }
    }
  }

  /* Measured (solid) against model (dashed) over the last window_s of vehicle time. */
  function drawChart(canvas, samples, measured, model, windowS) {
    const ratio = window.devicePixelRatio || 1;
    const w = canvas.clientWidth;
    const h = canvas.clientHeight;
    if (!w || !h) {
      return;
    }
    if (canvas.width !== Math.round(w * ratio) || canvas.height !== Math.round(h * ratio)) {
      canvas.width = Math.round(w * ratio);
      canvas.height = Math.round(h * ratio);
    }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.clearRect(0, 0, w, h);
    ctx.strokeStyle = "#cfd8dc";
    ctx.lineWidth = 1;
    ctx.strokeRect(0.5, 0.5, w - 1, h - 1);
    const values = [];
    for (const s of samples) {
      for (const k of [measured, model]) {
        if (typeof s[k] === "number" && isFinite(s[k])) {
          values.push(s[k]);
        }
      }
    }
    if (!values.length) {
      return;
    }
    let lo = Math.min(...values);
    let hi = Math.max(...values);
    if (hi - lo < 1e-9) {
      lo -= 1;
      hi += 1;
    }
    const pad = (hi - lo) * 0.08;
    lo -= pad;
    hi += pad;
    const tEnd = samples[samples.length - 1].t;
    const x = (t) => ((t - (tEnd - windowS)) / windowS) * (w - 2) + 1;
    const y = (val) => h - 2 - ((val - lo) / (hi - lo)) * (h - 4);
    const line = (key, colour, dash) => {
      ctx.beginPath();
      ctx.setLineDash(dash);
      ctx.strokeStyle = colour;
      ctx.lineWidth = 2;
      let pen = false;
      for (const s of samples) {
        const val = s[key];
        if (typeof val !== "number" || !isFinite(val)) {
          pen = false;
          continue;
        }
        if (pen) {
          ctx.lineTo(x(s.t), y(val));
        } else {
          ctx.moveTo(x(s.t), y(val));
          pen = true;
        }
      }
      ctx.stroke();
    };
    line(model, "#78909c", [5, 4]);
    line(measured, "#1565c0", []);
    ctx.setLineDash([]);
    ctx.font = "11px system-ui, sans-serif";
    const label = (textValue, baseline) => {
      const width = ctx.measureText(textValue).width;
      ctx.fillStyle = "rgba(255, 255, 255, 0.85)";
      ctx.fillRect(2, baseline - 10, width + 4, 13);
      ctx.fillStyle = "#546e7a";
      ctx.fillText(textValue, 4, baseline);
    };
    label(hi.toFixed(hi < 20 ? 1 : 0), 12);
    label(lo.toFixed(lo < 20 ? 1 : 0), h - 4);
  }

  async function main() {
    let cfg;
    try {
      const response = await fetch("config.json", {cache: "no-store"});
      cfg = await response.json();
    } catch (err) {
      $("broker-status").textContent = "cannot load config.json: " + err;
      return;
    }
    const display = new Display(cfg);
    window.mmhDisplay = display; // for the browser console (and the tests)
    display.start();
  }

  main();
})();
